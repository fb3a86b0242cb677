// The simulated device (rt/user_model.hpp behind the HapticDevice interface) and the template.
#include "drivers/simulated_device.hpp"
#include "drivers/template_device.hpp"
#include "tests/support/alloc_counter.hpp"

#include <chrono>
#include <cmath>
#include <thread>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
SimulatedDeviceConfig reach_config() {
  SimulatedDeviceConfig c;
  c.script = haptic::rt::GoalScript(haptic::rt::Vec3::Zero());
  c.script.add(0.5, haptic::rt::Vec3(0.03, 0.0, 0.0));
  return c;
}
constexpr double kT = 0.002;
}  // namespace

TEST_GROUP(SimulatedDevice) {};

TEST(SimulatedDevice, OwnerSteppedRunIsDeterministicAndFollowsTheHand) {
  SimulatedDevice a(reach_config()), b(reach_config());
  a.start();
  b.start();
  DeviceSample sa{}, sb{};
  const double zero[3] = {0, 0, 0};
  for (int k = 0; k < 1000; ++k) {  // 2 s
    CHECK(a.read_newest(sa));
    CHECK(b.read_newest(sb));
    a.command_force(zero);
    b.command_force(zero);
    a.service(k * kT, kT);
    b.service(k * kT, kT);
  }
  CHECK(a.read_newest(sa));
  CHECK(b.read_newest(sb));
  DOUBLES_EQUAL(sa.position_m[0], sb.position_m[0], 0.0);  // bit-identical
  DOUBLES_EQUAL(0.03, sa.position_m[0], 1e-3);              // the hand brought it to the goal
  DOUBLES_EQUAL(2.0, sa.time_s, 1e-9);
  LONGS_EQUAL(1001, sa.sequence);
  DOUBLES_EQUAL(a.user().device().damping_Ns_per_m, a.capabilities().min_damping_Ns_per_m, 0.0);
}

TEST(SimulatedDevice, CommandedForceReachesThePlantAndDisplacesIt) {
  SimulatedDeviceConfig c;  // hand holds the origin (300 N/m)
  SimulatedDevice d(c);
  d.start();
  DeviceSample s{};
  const double push[3] = {0.0, 0.0, 1.5};
  for (int k = 0; k < 1500; ++k) {
    d.read_newest(s);
    d.command_force(push);
    d.service(k * kT, kT);
  }
  double out[3];
  d.last_output_force(out);
  DOUBLES_EQUAL(1.5, out[2], 0.0);
  CHECK(d.read_newest(s));
  DOUBLES_EQUAL(1.5 / 300.0, s.position_m[2], 2e-4);  // static balance against the hand spring
}

TEST(SimulatedDevice, UnplugGivesSafeStateWithinOneTick) {
  SimulatedDevice d(SimulatedDeviceConfig{});
  d.start();
  DeviceSample s{};
  const double push[3] = {1.0, 0.0, 0.0};
  for (int k = 0; k < 10; ++k) {
    CHECK(d.read_newest(s));
    d.command_force(push);
    d.service(k * kT, kT);
  }
  d.simulate_unplug();
  // Tick 10: the station reads first and learns the fault in this tick...
  CHECK_FALSE(d.read_newest(s));
  CHECK(d.fault() == DeviceFault::kUnplugged);
  d.command_force(push);
  d.service(10 * kT, kT);
  double out[3];
  d.last_output_force(out);
  // ...and the force that leaves in the same tick is zero.
  DOUBLES_EQUAL(0.0, out[0], 0.0);
}

TEST(SimulatedDevice, OwnerSteppedTickDoesNotAllocate) {
  SimulatedDevice d(reach_config());
  d.start();
  DeviceSample s{};
  const double f[3] = {0.1, 0.0, 0.0};
  haptic::test::AllocationCounter counter;
  for (int k = 0; k < 500; ++k) {
    d.read_newest(s);
    d.command_force(f);
    d.service(k * kT, kT);
  }
  LONGS_EQUAL(0, counter.allocations());
}

TEST(SimulatedDevice, OwnThreadModeProducesSamplesAtItsServoRate) {
  SimulatedDeviceConfig c = reach_config();
  c.mode = SimulatedDeviceMode::kOwnThread;
  c.servo_rate_hz = 1000.0;
  SafetyLimits lenient;  // this machine is shared: a descheduled servo thread must not trip staleness here
  lenient.max_stale_reads = 100000;
  SimulatedDevice d(c, lenient);
  d.start();
  DeviceSample s{};
  std::uint64_t last_seq = 0;
  int fresh = 0;
  // Bounded wait (not a timing assertion): up to 5 s for 20 new samples.
  for (int i = 0; i < 5000 && fresh < 20; ++i) {
    if (d.read_newest(s) && s.sequence > last_seq) {
      ++fresh;
      last_seq = s.sequence;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  d.stop();
  CHECK(fresh >= 20);
  CHECK(d.fault() == DeviceFault::kNotStarted);
}

TEST(SimulatedDevice, BadServoRateNamesTheKey) {
  SimulatedDeviceConfig c;
  c.servo_rate_hz = 5.0;
  try {
    SimulatedDevice d(c);
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("drivers.simulated.servo_rate_hz") != std::string::npos);
  }
}

TEST_GROUP(TemplateDevice) {};

TEST(TemplateDevice, CopyMeDriverWorksThroughTheInterface) {
  TemplateDevice d;
  d.start();
  d.service(0.0);
  DeviceSample s{};
  CHECK(d.read_newest(s));
  const double f[3] = {5.0, 0.0, 0.0};
  d.command_force(f);
  d.service(0.001);
  double out[3];
  d.last_output_force(out);
  DOUBLES_EQUAL(1.0, out[0], 1e-12);  // its 1 N capability
}
