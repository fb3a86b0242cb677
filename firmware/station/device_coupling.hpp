#pragma once
// What couples this station's device to its virtual proxy (Section III-C): the
// device damping b_d, the virtual-coupling gains K_vc, B_vc, b_v and the force limit, from the
// device's published capabilities and the [device] keys of the station file, and eq. (26) on them.
// Checked twice: by the plan (`run --check-config`, with the figures the device kind publishes)
// and at start-up with the opened device's own capabilities. Start-up only (not RT-safe).
#include <string>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "drivers/device.hpp"
#include "drivers/workspace_map.hpp"
#include "rt/scene.hpp"
#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "rt/gains.hpp"

namespace haptic::firmware {

struct DeviceCoupling {
  rt::VirtualCouplingGains gains{};  // K_vc, B_vc, b_v
  double b_d_Ns_per_m = 0.0;         // device damping used by eq. (26)
  std::string b_d_source;            // where b_d came from (the key, or the device's figure)
  double force_limit_N = 0.0;        // the one force limit: min(device capability, device.max_force_N)
  bool force_feedback = true;        // false: position input only (no actuated axis): eq. (26) does not apply
  double map_scale = 1.0;            // device.map_scale: eq. (26) and the limit act in the object frame
  double object_b_d_Ns_per_m() const { return drivers::object_frame_damping(b_d_Ns_per_m, map_scale); }  // b_d / scale^2
  double object_force_limit_N() const { return drivers::object_frame_force_limit(force_limit_N, map_scale); }  // F_max / scale
};

// The coupling for a device with capabilities `caps` and the file's [device] keys (-1 = from the
// device / the scenario). Throws std::invalid_argument naming device.damping_Ns_per_m when the
// device has force feedback but publishes no b_d (the Touch) and the file does not state one.
DeviceCoupling device_coupling(const StationFile& file, const ScenarioSpec& spec, const drivers::DeviceCapabilities& caps);

// Eq. (26) for this coupling with the steps T_k the core will integrate with (rt::check_eq26 at its
// worst: T_k = T^max, T_k/T_{k-1} = T^max/T^min; the core's StationConfig::validate checks the same
// at start-up; T^min = T^max = the period for a fixed step). Throws std::invalid_argument naming the
// keys as written in the station file (station.period_min_s/period_max_s when they decide it), and
// proposing the largest device.coupling_stiffness_N_per_m (K_vc) that satisfies it for the given b_d
// (rt::max_K_vc_eq26). Start-up only.
void check_device_coupling(const DeviceCoupling& coupling, double t_min_s, double t_max_s);
// The largest margin m <= max_margin_s for which eq. (26) holds at T^min = T - m, T^max = T + m
// (check_device_coupling; 0 when it holds only at the period, or not even there). Start-up only.
double eq26_largest_step_margin_s(const DeviceCoupling& coupling, double period_s, double max_margin_s);

// The device -> object transform of this station ([device] map_* keys; clamp radius = the
// device's workspace radius). Throws std::invalid_argument naming the key.
drivers::WorkspaceMapConfig workspace_map_config(const StationFile& file, const drivers::DeviceCapabilities& caps);

// device.ramp_in_s in ticks (-1: 1 s for a real device, 0 for a simulated user).
std::int64_t ramp_in_ticks(const StationFile& file, double period_s);

// The force factor of the ramp-in at the n-th coupled tick (n = 0 first): min(1, (n + 1) / ramp_ticks),
// 1 without a ramp. RT-safe.
inline double ramp_in_factor(std::int64_t n, std::int64_t ramp_ticks) {
  return ramp_ticks <= 0 || n + 1 >= ramp_ticks ? 1.0 : static_cast<double>(n + 1) / static_cast<double>(ramp_ticks);
}

// Where the virtual proxy starts: the mapped device position, unless that is
// inside the object (behind the contact face's outward plane at rest), in which case its
// projection onto that plane (*projected = true). Start-up.
Eigen::Vector3d initial_proxy_position(const Eigen::Vector3d& mapped_device_m, const rt::Scene& scene, const std::vector<int>& contact_nodes,
                                       bool* projected);

}  // namespace haptic::firmware
