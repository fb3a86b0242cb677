#pragma once
// haptic-devices diag / map: the operator commands that drive an opened device (non-RT tools; the
// calling thread plays the station's tick: read_newest() then command_force() every 2 ms on
// absolute deadlines, so the device sees exactly the call pattern a station produces).
// None of these functions is RT-safe (they print, sleep and allocate); the device calls they make are.
#include <chrono>
#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "drivers/device.hpp"

namespace haptic::tools {

// Exit statuses of `haptic-devices diag` and `haptic-devices map` (documented in --help).
inline constexpr int kExitOk = 0;
inline constexpr int kExitBadOption = 2;     // a value out of range (the option is named)
inline constexpr int kExitNotStill = 3;      // map: the stylus was never held still long enough
inline constexpr int kExitDeviceFault = 5;   // the device entered its safe state during the run
inline constexpr int kExitNoDevice = 9;      // no device could be opened (same code as haptic-station)

inline constexpr int kExitCheckFailed = 1;    // check: at least one item FAILed
inline constexpr int kExitCheckSkipped = 4;   // check: no item failed, but at least one was SKIPped (not verified)

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

// ---- the pieces diag, map and check share (one implementation each) ----------------------------

// The tick pacer: 2 ms absolute deadlines (the station's default period), but a late tick is not
// followed by a burst of catch-up ticks (a burst would read the device faster than it produces
// samples and trip the stale check).
class TickPacer {
 public:
  TickPacer();
  double elapsed_s() const;
  void wait();

 private:
  std::chrono::steady_clock::time_point t0_, next_;
};

// The backend's own servo frame count (Touch: HD scheduler frames; Falcon: USB exchanges), 0 when it has none.
std::uint64_t servo_frames_of(const drivers::HapticDevice& dev);

// Prints the latched fault (and what to do about it); returns kExitDeviceFault.
int report_fault(const drivers::HapticDevice& dev, std::ostream& out);

// One phase of constant force along opt.axis (one tick per 2 ms, live position lines at opt.print_hz).
struct PushResult {
  double mean_speed = 0.0;     // mean |v| along the axis over the second half (measure), m/s
  double mean_velocity = 0.0;  // the same, signed, m/s
  double travel_m = 0.0;       // last position - first position along the axis (signed)
  int samples = 0;             // samples in the mean
  bool cut_short = false;      // the travel limit (opt.max_travel_mm) stopped the push
  bool faulted = false;        // the device entered its safe state
};
PushResult run_push(drivers::HapticDevice& dev, const DiagOptions& opt, double force_N, double seconds, bool measure,
                    TickPacer& pacer, double& next_print, std::ostream& out);

// diag's test at one force level: +F then -F for opt.push_s each (so the stylus comes back), and its
// report line (mean |speed| over the second half of each push).
struct LevelResult {
  double force_N = 0.0;
  PushResult plus, minus;
  double mean_speed = 0.0;  // over both pushes (NaN when no samples), m/s
  bool faulted = false;
};
LevelResult run_level(drivers::HapticDevice& dev, const DiagOptions& opt, double force_N, TickPacer& pacer,
                      double& next_print, std::ostream& out);

// b_d from two levels, (F2 - F1) / (v2 - v1) (firmware/deploy/README.md, "Measuring b_d"): the
// Coulomb friction cancels. Empty when the speed did not grow with the force.
std::optional<double> damping_from_levels(double F1_N, double v1_m_per_s, double F2_N, double v2_m_per_s);

// Servo rate since (frames0, samples0): the backend's own frames per second when it counts them,
// else fresh samples per second (at most the 500 Hz tick).
struct ServoRate {
  double hz = 0.0;
  std::uint64_t count = 0;
  bool own_frames = false;
  double seconds = 0.0;
};
ServoRate measure_servo_rate(const drivers::HapticDevice& dev, std::uint64_t frames0, std::uint64_t samples0, double elapsed_s);
std::string describe(const ServoRate& r);  // "998 Hz (998 servo frames of the device's own loop in 1.000 s)"

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
