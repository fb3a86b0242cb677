// Workspace mapping and ramp-in: the virtual proxy starts at the mapped device
// position (outside the object), and the force sent to the device ramps in, so the first coupled
// tick cannot jolt the hand. Stated bound: with device.ramp_in_s = R the force sent at the n-th
// coupled tick (n = 0 first) is at most F_max (n + 1) T / R (F_max: the device's force limit).
// The same start without placement and ramp (the behaviour before) is measured for comparison.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "drivers/phantom_device.hpp"
#include "firmware/station/probe.hpp"
#include "firmware/station/tick.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;
using namespace haptic::firmware;

namespace {

struct FirstTicks {
  double first_N = 0;    // |force sent to the device| at the first coupled tick
  double max_over_bound = 0;  // max_n |F_n| / (F_max (n + 1) T / R) over the ramp (<= 1: the bound holds)
  bool projected = false;
};

// Station 2 of the default scenario (neighbour 1) with these [device] lines, planned as `run` plans it.
PlanResult plan_station_2(const std::string& device_lines) {
  test::StationText s;
  s.id = 2;
  s.peers = {1};
  s.out_dir = "/tmp";
  s.device = device_lines;
  return plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
}

// One station's core built as the station builds it, with the device held still at `device_m`
// (device frame), `ticks` coupled ticks; returns the forces the device would get.
FirstTicks first_ticks(const std::string& device_lines, const double device_m[3], bool place, int ticks) {
  const PlanResult pr = plan_station_2(device_lines);
  CHECK_TEXT(pr.status == PhaseStatus::kOk, pr.error.c_str());
  ProbeResult probe;
  probe.status = PhaseStatus::kOk;
  probe.rtt_bound_ticks = {3};
  probe.loss_allowance_ticks = {1};
  const drivers::DeviceCapabilities caps = drivers::touch_default_capabilities();
  BuildResult b = build_station_core(*pr.plan, probe, caps, place ? device_m : nullptr);
  CHECK_TEXT(b.status == PhaseStatus::kOk, b.message.c_str());
  TickInputs in;
  in.map = &b.map;
  in.ramp_ticks = pr.plan->ramp_in_ticks;
  TickCounters cnt;
  FirstTicks r;
  r.projected = b.proxy_projected;
  const double T = pr.plan->built->spec.period_s;
  for (int k = 0; k < ticks; ++k) {
    const auto out = b.core->tick(k, b.map.to_object(device_m, nullptr));  // no neighbour data: the edge is a damper
    double f[3];
    device_force_out(in, cnt, out.device_force_N, f);
    const double n = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    if (k == 0) r.first_N = n;
    if (in.ramp_ticks > 0 && k < in.ramp_ticks)
      r.max_over_bound = std::max(r.max_over_bound, n / (caps.max_force_N * (k + 1) * T / (static_cast<double>(in.ramp_ticks) * T)));
    ++cnt.ticks_run;
  }
  return r;
}

// 12 mm inside the object below user 2's contact face, 20 mm sideways: where a person might hold
// the stylus when the station starts.
void inside_point(double out[3]) {
  const PlanResult pr = plan_station_2("kind = \"touch\"\ndamping_Ns_per_m = 0.5\n");
  const auto& b = *pr.plan->built;
  const Eigen::Vector3d inward = b.push_direction[1];
  Eigen::Vector3d side = inward.unitOrthogonal();
  const Eigen::Vector3d p = b.vp_start[1] + 0.012 * inward + 0.020 * side;
  for (int a = 0; a < 3; ++a) out[a] = p[a];
}
}  // namespace

TEST_GROUP(DeviceMapping){};

TEST(DeviceMapping, FirstTickForceIsBelowTheRampBoundAndFarBelowTheUnmappedUnrampedStart) {
  double q[3];
  inside_point(q);
  const std::string touch = "kind = \"touch\"\ndamping_Ns_per_m = 0.5\n";
  const FirstTicks before = first_ticks(touch + "ramp_in_s = 0\n", q, false, 1);   // proxy at the scenario's start, no ramp
  const FirstTicks placed = first_ticks(touch + "ramp_in_s = 0\n", q, true, 1);    // placement only
  const FirstTicks ramped = first_ticks(touch + "ramp_in_s = 0.5\n", q, true, 250); // placement + ramp over 0.5 s
  const double F_max = drivers::touch_default_capabilities().max_force_N, T = 0.002;
  std::printf("\n  first-tick device force: without placement and ramp %.4f N, placement only %.4f N, placement + 0.5 s ramp %.6f N "
              "(bound F_max T / ramp_in_s = %.6f N)\n",
              before.first_N, placed.first_N, ramped.first_N, F_max * T / 0.5);
  CHECK(placed.projected && ramped.projected);  // the mapped point was inside the object
  CHECK(before.first_N > 1.0);                  // the jolt the ramp removes (K_vc x 20+ mm, clamped at F_max)
  CHECK(ramped.first_N <= F_max * T / 0.5 * (1 + 1e-12));
  CHECK(ramped.max_over_bound <= 1.0 + 1e-12);  // and at every tick of the ramp
}

TEST(DeviceMapping, AProxyPlacedAtAnOutsideDevicePositionFeelsNoForceAtAll) {
  double q[3];
  inside_point(q);
  const PlanResult pr = plan_station_2("kind = \"touch\"\ndamping_Ns_per_m = 0.5\n");
  const Eigen::Vector3d out_pt = pr.plan->built->vp_start[1] - 0.03 * pr.plan->built->push_direction[1];  // 30 mm outside
  const double p[3] = {out_pt.x(), out_pt.y(), out_pt.z()};
  const FirstTicks r = first_ticks("kind = \"touch\"\ndamping_Ns_per_m = 0.5\nramp_in_s = 0\n", p, true, 1);
  CHECK_FALSE(r.projected);
  DOUBLES_EQUAL(0.0, r.first_N, 1e-12);
}

TEST(DeviceMapping, TheMapMovesTheDeviceIntoTheObjectFrameAndScalesEq26AndTheLimit) {
  // A device whose origin is 2 cm off the object, at scale 2 (1 mm of stylus = 2 mm in the scene): the
  // proxy still starts at the mapped position, eq. (26) uses b_d / scale^2, the core's limit is F_max / scale.
  const PlanResult pr = plan_station_2("kind = \"touch\"\ndamping_Ns_per_m = 1.6\nmap_scale = 2.0\nmap_offset_m = [0.02, 0.0, 0.0]\nramp_in_s = 0\n");
  CHECK_TEXT(pr.status == PhaseStatus::kOk, pr.error.c_str());  // 1.6 / 4 = 0.4 >= K_vc T = 0.4
  ProbeResult probe;
  probe.status = PhaseStatus::kOk;
  probe.rtt_bound_ticks = {3};
  probe.loss_allowance_ticks = {1};
  // 30 mm outside user 2's face in the object frame, expressed in the device frame: (o - offset) / scale
  const Eigen::Vector3d target = pr.plan->built->vp_start[1] - 0.03 * pr.plan->built->push_direction[1];
  const double dev[3] = {(target.x() - 0.02) / 2.0, target.y() / 2.0, target.z() / 2.0};
  const BuildResult b = build_station_core(*pr.plan, probe, drivers::touch_default_capabilities(), dev);
  CHECK_TEXT(b.status == PhaseStatus::kOk, b.message.c_str());
  CHECK_FALSE(b.proxy_projected);
  CHECK((b.proxy_start_m - target).norm() < 1e-12);
  DOUBLES_EQUAL(0.4, b.core->config().device_damping_Ns_per_m, 1e-12);
  DOUBLES_EQUAL(3.3 / 2.0, b.core->config().max_device_force_N, 1e-12);
  CHECK(plan_station_2("kind = \"touch\"\ndamping_Ns_per_m = 1.5\nmap_scale = 2.0\n").status == PhaseStatus::kConfigError);  // 1.5 / 4 < 0.4: refused
}

namespace {
// A device whose samples the test sets (one servo period per publish).
class HeldDevice final : public drivers::HapticDevice {
 public:
  HeldDevice() : HapticDevice(caps(), drivers::SafetyLimits{}) {}
  static drivers::DeviceCapabilities caps() {
    drivers::DeviceCapabilities c = drivers::touch_default_capabilities();
    c.workspace_radius_m = 0.1;
    return c;
  }
  void start() override { arm(); }
  void stop() override { disarm(); }
  void hold_at(double x) {
    drivers::DeviceSample s{};
    s.position_m[0] = x;
    s.sequence = ++seq_;
    s.time_s = 1e-3 * static_cast<double>(seq_);
    publish_sample(s);
  }
  void output(double f[3]) { take_force(f); }
  std::uint64_t seq_ = 0;
};
}  // namespace

// Positions outside the mapped workspace, handled explicitly at the station's device read: within
// the device's workspace radius the map applies; beyond it (up to device.workspace_margin x the
// radius) the position is clamped radially onto the radius and the tick is counted
// (lifecycle.device.outside_workspace_ticks); beyond the margin the sample is out of range: the device
// enters its safe state in that tick (no position, every later force exactly zero).
TEST(DeviceMapping, APositionBeyondTheWorkspaceIsClampedAndCountedAndBeyondTheMarginIsTheSafeState) {
  HeldDevice dev;
  dev.start();
  drivers::WorkspaceMapConfig mc;
  mc.offset_m[0] = 0.5;
  mc.workspace_radius_m = HeldDevice::caps().workspace_radius_m;
  const drivers::WorkspaceMap map(mc);
  TickInputs in;
  in.device = &dev;
  in.map = &map;
  TickCounters cnt;
  dev.hold_at(0.05);  // inside: mapped as it is
  DOUBLES_EQUAL(0.55, read_device(in, cnt).x(), 1e-12);
  LONGS_EQUAL(0, cnt.outside_workspace_ticks);
  dev.hold_at(0.12);  // beyond the 0.1 m radius, within the 1.5 margin: clamped onto the radius, counted
  DOUBLES_EQUAL(0.6, read_device(in, cnt).x(), 1e-12);
  LONGS_EQUAL(1, cnt.outside_workspace_ticks);
  dev.hold_at(0.2);  // beyond 1.5 x 0.1 m: out of range, the safe state in this tick
  CHECK(std::isnan(read_device(in, cnt).x()));
  CHECK(dev.fault() == drivers::DeviceFault::kOutOfRange);
  LONGS_EQUAL(1, cnt.device_fault_ticks);
  const double f[3] = {1.0, 0.0, 0.0};
  dev.command_force(f);
  double out[3] = {9, 9, 9};
  dev.output(out);
  DOUBLES_EQUAL(0.0, out[0], 0.0);
}
