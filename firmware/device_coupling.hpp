#pragma once
// What couples this station's device to its virtual proxy (issue 12 item 2; Section III-C): the
// device damping b_d, the virtual-coupling gains K_vc, B_vc, b_v and the force limit, from the
// device's published capabilities and the [device] keys of the station file, and eq. (26) on them.
// Checked twice: by the plan (`run --check-config`, with the figures the device kind publishes)
// and at start-up with the opened device's own capabilities. Start-up only (not RT-safe).
#include <string>

#include "drivers/device.hpp"
#include "firmware/scenario.hpp"
#include "firmware/station_config.hpp"
#include "rt/gains.hpp"

namespace haptic::firmware {

struct DeviceCoupling {
  rt::VirtualCouplingGains gains{};  // K_vc, B_vc, b_v
  double b_d_Ns_per_m = 0.0;         // device damping used by eq. (26)
  std::string b_d_source;            // where b_d came from (the key, or the device's figure)
  double force_limit_N = 0.0;        // the one force limit: min(device capability, device.max_force_N)
  bool force_feedback = true;        // false: position input only (no actuated axis): eq. (26) does not apply
};

// The coupling for a device with capabilities `caps` and the file's [device] keys (-1 = from the
// device / the scenario). Throws std::invalid_argument naming device.damping_Ns_per_m when the
// device has force feedback but publishes no b_d (the Touch) and the file does not state one.
DeviceCoupling device_coupling(const StationFile& file, const ScenarioSpec& spec, const drivers::DeviceCapabilities& caps);

// Eq. (26) for this coupling at period T (rt::check_eq26). Throws std::invalid_argument naming the
// keys as written in the station file, and proposing the largest device.coupling_stiffness_N_per_m
// (K_vc) that satisfies it for the given b_d (rt::max_K_vc_eq26).
void check_device_coupling(const DeviceCoupling& coupling, double period_s);

}  // namespace haptic::firmware
