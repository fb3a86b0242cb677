// The device interface: limits on the way out, the safe state within one tick.
#include "drivers/device.hpp"
#include "tests/support/alloc_counter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
// Test subclass exposing "spin one device period" (libfranka habit).
class BenchDevice final : public HapticDevice {
 public:
  explicit BenchDevice(const SafetyLimits& limits = {}, bool actuate_z = true)
      : HapticDevice(caps(actuate_z), limits) {}
  static DeviceCapabilities caps(bool actuate_z) {
    DeviceCapabilities c{};
    c.max_force_N = 2.0;
    c.max_stiffness_N_per_m = 1000.0;
    c.servo_rate_hz = 1000.0;
    c.workspace_radius_m = 0.1;
    c.min_damping_Ns_per_m = 0.5;
    for (int i = 0; i < 3; ++i) c.sensed_axes[i] = c.actuated_axes[i] = true;
    c.actuated_axes[2] = actuate_z;
    c.name = "bench";
    return c;
  }
  void start() override { arm(); }
  void stop() override { disarm(); }
  // One device period: publish a sample at (p, v), then take the force to output.
  void spin(double px, double vx, double f_out[3]) {
    DeviceSample s{};
    s.position_m[0] = px;
    s.velocity_m_per_s[0] = vx;
    s.time_s = 1e-3 * static_cast<double>(seq_);
    s.sequence = ++seq_;
    publish_sample(s);
    take_force(f_out);
  }
  void publish_raw(const DeviceSample& s) { publish_sample(s); }
  void output(double f_out[3]) { take_force(f_out); }
  std::uint64_t seq_ = 0;
};

double norm(const double f[3]) { return std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]); }
}  // namespace

TEST_GROUP(DeviceInterface) {};

TEST(DeviceInterface, NotStartedDeviceOutputsZeroAndReportsIt) {
  BenchDevice d;
  double f_out[3];
  const double f[3] = {1.0, 0.0, 0.0};
  d.command_force(f);
  d.spin(0.0, 0.0, f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);
  CHECK(d.fault() == DeviceFault::kNotStarted);
  DeviceSample s;
  CHECK_FALSE(d.read_newest(s));
}

TEST(DeviceInterface, ForceIsClampedToMaxForceOnTheWayOut) {
  BenchDevice d;
  d.start();
  double f_out[3];
  d.spin(0.0, 0.0, f_out);
  DeviceSample s;
  CHECK(d.read_newest(s));
  const double f[3] = {3.0, 4.0, 0.0};  // 5 N, limit 2 N
  d.command_force(f);
  d.spin(0.0, 0.0, f_out);
  DOUBLES_EQUAL(2.0, norm(f_out), 1e-12);
  DOUBLES_EQUAL(0.6, f_out[0] / 2.0, 1e-12);  // direction kept
  LONGS_EQUAL(1, d.counters().force_clamps);
}

TEST(DeviceInterface, SafetyConfigLowersTheClampBelowTheCapability) {
  SafetyLimits l;
  l.max_force_N = 0.5;
  BenchDevice d(l);
  d.start();
  DOUBLES_EQUAL(0.5, d.force_limit_N(), 0.0);
  const double f[3] = {0.0, 1.0, 0.0};
  double f_out[3];
  d.command_force(f);
  d.output(f_out);
  DOUBLES_EQUAL(0.5, f_out[1], 1e-12);
}

TEST(DeviceInterface, NonActuatedAxisGetsNoForce) {
  BenchDevice d({}, /*actuate_z=*/false);
  d.start();
  const double f[3] = {0.1, 0.2, 0.3};
  double f_out[3];
  d.command_force(f);
  d.output(f_out);
  DOUBLES_EQUAL(0.1, f_out[0], 0.0);
  DOUBLES_EQUAL(0.0, f_out[2], 0.0);
}

TEST(DeviceInterface, PowerIntoTheHandIsCapped) {
  SafetyLimits l;
  l.max_power_W = 0.5;
  BenchDevice d(l);
  d.start();
  double f_out[3];
  d.spin(0.0, 1.0, f_out);  // moving at 1 m/s along x
  DeviceSample s;
  CHECK(d.read_newest(s));
  const double push[3] = {1.5, 0.0, 0.0};  // 1.5 W into the hand
  d.command_force(push);
  d.output(f_out);
  DOUBLES_EQUAL(0.5, f_out[0] * 1.0, 1e-12);
  LONGS_EQUAL(1, d.counters().power_limits);
  const double brake[3] = {-1.5, 0.0, 0.0};  // absorbing power is never limited
  d.command_force(brake);
  d.output(f_out);
  DOUBLES_EQUAL(-1.5, f_out[0], 1e-12);
}

TEST(DeviceInterface, StaleSampleEntersSafeStateAfterTheConfiguredTicks) {
  SafetyLimits l;
  l.max_stale_reads = 3;
  BenchDevice d(l);
  d.start();
  double f_out[3];
  d.spin(0.0, 0.0, f_out);
  DeviceSample s;
  CHECK(d.read_newest(s));                 // fresh
  for (int i = 0; i < 3; ++i) CHECK(d.read_newest(s));  // held, within the limit
  CHECK_FALSE(d.read_newest(s));           // 4th tick without a new sample: fault, this tick
  CHECK(d.fault() == DeviceFault::kStaleSample);
  const double f[3] = {1.0, 1.0, 1.0};
  d.command_force(f);
  d.output(f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);
}

TEST(DeviceInterface, OutOfWorkspaceSampleFaultsInTheSameTickAndZeroesForce) {
  BenchDevice d;  // radius 0.1 m, margin 1.5 -> 0.15 m
  d.start();
  double f_out[3];
  d.spin(0.0, 0.0, f_out);
  DeviceSample s;
  CHECK(d.read_newest(s));
  const double f[3] = {1.0, 0.0, 0.0};
  d.command_force(f);
  d.spin(0.2, 0.0, f_out);  // the device reports 0.2 m: beyond the margin
  DOUBLES_EQUAL(1.0, f_out[0], 0.0);  // the output taken before the sample was judged
  CHECK_FALSE(d.read_newest(s));
  CHECK(d.fault() == DeviceFault::kOutOfRange);
  d.command_force(f);
  d.output(f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);  // the very next output is zero
}

TEST(DeviceInterface, NonFiniteAndBackwardsSamplesAreOutOfRange) {
  BenchDevice d;
  d.start();
  double f_out[3];
  d.spin(0.0, 0.0, f_out);
  DeviceSample s;
  CHECK(d.read_newest(s));
  d.spin(std::nan(""), 0.0, f_out);
  CHECK_FALSE(d.read_newest(s));
  CHECK(d.fault() == DeviceFault::kOutOfRange);

  BenchDevice d2;
  d2.start();
  d2.spin(0.0, 0.0, f_out);
  d2.spin(0.0, 0.0, f_out);
  CHECK(d2.read_newest(s));
  DeviceSample back = s;
  back.sequence = s.sequence - 1;  // sequence going backwards
  d2.publish_raw(back);
  CHECK_FALSE(d2.read_newest(s));
  CHECK(d2.fault() == DeviceFault::kOutOfRange);
}

TEST(DeviceInterface, NonFiniteCommandIsRefusedAndLatched) {
  BenchDevice d;
  d.start();
  const double bad[3] = {0.0, std::nan(""), 0.0};
  double f_out[3];
  d.command_force(bad);
  d.output(f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);
  CHECK(d.fault() == DeviceFault::kBadCommand);
}

TEST(DeviceInterface, FaultFromAnotherThreadZeroesTheNextOutputEvenWithAForceQueued) {
  BenchDevice d;
  d.start();
  double f_out[3];
  d.spin(0.0, 0.0, f_out);
  DeviceSample s;
  CHECK(d.read_newest(s));
  const double f[3] = {1.0, 0.0, 0.0};
  d.command_force(f);  // queued before the unplug
  std::thread([&d] { d.notify_unplugged(); }).join();
  d.output(f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);
  CHECK_FALSE(d.read_newest(s));
  CHECK(d.fault() == DeviceFault::kUnplugged);
  STRCMP_EQUAL("unplugged", fault_name(d.fault()));
}

TEST(DeviceInterface, SafeStateIsLatchedAndAPreFaultForceDoesNotSurviveReArm) {
  BenchDevice d;
  d.start();
  const double f[3] = {1.0, 0.0, 0.0};
  d.command_force(f);
  d.notify_unplugged();
  d.notify_unplugged();
  CHECK(d.fault() == DeviceFault::kUnplugged);
  double f_out[3];
  d.output(f_out);  // drains the queued pre-fault force
  d.clear_fault();
  d.output(f_out);
  DOUBLES_EQUAL(0.0, norm(f_out), 0.0);
}

TEST(DeviceInterface, FaultComesWithTheHistoryOfTheLastSamples) {
  BenchDevice d;
  d.start();
  double f_out[3];
  DeviceSample s;
  for (int k = 0; k < 100; ++k) {
    d.spin(0.001 * k, 0.0, f_out);
    d.read_newest(s);
  }
  d.notify_unplugged();
  DeviceSample h[BenchDevice::kHistory];
  LONGS_EQUAL(BenchDevice::kHistory, d.history(h, BenchDevice::kHistory));
  LONGS_EQUAL(100 - BenchDevice::kHistory + 1, h[0].sequence);
  LONGS_EQUAL(100, h[BenchDevice::kHistory - 1].sequence);
  DOUBLES_EQUAL(0.099, h[BenchDevice::kHistory - 1].position_m[0], 1e-15);
}

TEST(DeviceInterface, TickSideCallsDoNotAllocate) {
  CHECK(haptic::test::allocation_counter_works());
  BenchDevice d;
  d.start();
  double f_out[3];
  DeviceSample s;
  const double f[3] = {0.5, 0.0, 0.0};
  haptic::test::AllocationCounter counter;
  for (int k = 0; k < 1000; ++k) {
    d.spin(0.0, 0.01, f_out);
    d.read_newest(s);
    d.command_force(f);
  }
  LONGS_EQUAL(0, counter.allocations());
}

TEST(DeviceInterface, BadSafetyConfigNamesTheKeyAndRange) {
  SafetyLimits l;
  l.max_power_W = -1.0;
  try {
    validate_limits(l);
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    CHECK(what.find("device.max_power_W") != std::string::npos);
    CHECK(what.find("[0, 1000]") != std::string::npos);
  }
}
