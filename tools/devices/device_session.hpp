#pragma once
// haptic-devices diag / map: the operator commands that drive an opened device (non-RT tools; the
// calling thread plays the station's tick: read_newest() then command_force() every 2 ms on
// absolute deadlines, so the device sees exactly the call pattern a station produces).
// None of these functions is RT-safe (they print, sleep and allocate); the device calls they make are.
#include <iosfwd>
#include <vector>

#include "drivers/device.hpp"

namespace haptic::tools {

// Exit statuses of `haptic-devices diag` and `haptic-devices map` (documented in --help).
inline constexpr int kExitOk = 0;
inline constexpr int kExitBadOption = 2;     // a value out of range (the option is named)
inline constexpr int kExitNotStill = 3;      // map: the stylus was never held still long enough
inline constexpr int kExitDeviceFault = 5;   // the device entered its safe state during the run
inline constexpr int kExitNoDevice = 9;      // no device could be opened (same code as haptic-station)

struct DiagOptions {
  std::vector<double> forces_N{0.2};  // test force levels, each in (0, 1] N; one or two
  int axis = 0;                       // 0 x, 1 y, 2 z (device frame)
  double push_s = 0.5;                // each push (+F, then -F) lasts this long, [0.1, 10]
  double settle_s = 0.25;             // zero force before and after, live readout only
  double max_travel_mm = 50.0;        // a push stops (force 0) beyond this travel from its start
  double print_hz = 4.0;              // live position lines per second
};

// Diagnostics (like the vendor's diagnostic tool): live position readout; for each force level a
// push of +F then -F along one axis (so the stylus comes back), the mean |speed| along the axis
// over the second half of each push (the plateau); the measured servo rate (the backend's own
// frames per second when it counts them, else fresh samples per second). With two levels it
// prints b_d = (F2 - F1) / (v2 - v1), which removes Coulomb friction (firmware/deploy/README.md,
// "Measuring b_d"). Returns kExitOk, or kExitDeviceFault naming the fault.
int run_diagnostics(drivers::HapticDevice& dev, const DiagOptions& opt, std::ostream& out);

struct MapOptions {
  double object_centre_m[3] = {0, 0, 0};  // the object's centre in the object frame
  double rotation_deg[3] = {0, 0, 0};     // map_rotation_deg to keep
  double scale = 1.0;                     // map_scale to keep
  double still_s = 1.0;                   // how long the stylus must be held still
  double still_mm = 2.0;                  // within this distance of where stillness began
  double timeout_s = 30.0;
};

// Guided set-up: waits until the stylus has been held still at the object's centre for still_s,
// then prints the [device] map_* keys whose offset maps that point onto object_centre_m
// (drivers::solve_offset). Returns kExitOk, kExitNotStill on timeout, kExitDeviceFault on a fault.
int run_mapping(drivers::HapticDevice& dev, const MapOptions& opt, std::ostream& out);

}  // namespace haptic::tools
