#pragma once
// haptic-devices check: a guided pass/fail device check (in the spirit of the vendor's
// Touch_Diagnostic) on an opened device, from the same 2 ms tick as diag and map (every safety limit
// of the driver applies). Items, in order, each PASS / FAIL / SKIP with the measured figure:
//   open        the device opened and says what it is (Touch: hdGetString model/serial/HD_VERSION,
//               whose major number must be the OpenHaptics ABI our binding targets; calibration OK)
//   servo_rate  the backend's own servo frames (else fresh samples) per second while idle
//   encoders    the user moves the stylus: every sensed axis moves by move_mm within timeout_s
//   workspace   the user sweeps the stylus: the extent reached along each axis vs the nominal box
//   buttons     the user presses and releases each button: each bit seen set, then clear
//   force       diag's push at the first --force-N level: +F then -F along the axis; the stylus must
//               travel at least min_push_mm in the force's direction each time, the driver must send
//               the force unreduced (no force/power clamp), and |v+| / |v-| within max_asymmetry
//   b_d         diag's second level and its b_d = (F2 - F1) / (v2 - v1)
// Without `yes`, each guided item waits for Enter on standard input (end of input counts as Enter).
// Not RT-safe (prints, sleeps, reads stdin); the device calls it makes are.
#include <iosfwd>
#include <set>
#include <string>

#include "drivers/device.hpp"
#include "tools/devices/device_session.hpp"

namespace haptic::tools {

inline constexpr const char* kCheckItems[] = {"open", "servo_rate", "encoders", "workspace", "buttons", "force", "b_d"};

struct CheckOptions {
  bool yes = false;                 // do not wait for Enter at the prompts (tests, scripted runs)
  double timeout_s = 30.0;          // each guided item (encoders, workspace, buttons) gives up after this
  double idle_s = 1.0;              // servo rate window at zero force, before the guided items
  double min_servo_hz = 450.0;      // servo_rate PASS threshold (90% of the station's 500 Hz tick)
  double move_mm = 10.0;            // encoders: each sensed axis must move this far
  double workspace_fraction = 0.8;  // workspace: extent reached / nominal extent, each axis
  int buttons = -1;                 // how many buttons to ask for; -1 = the device's (Touch 2, Falcon 4, SpaceMouse 2)
  double min_push_mm = 2.0;         // force: travel in the force's direction, each push
  double max_asymmetry = 2.0;       // force: |v+| / |v-| within [1 / x, x]
  DiagOptions push{{0.2, 0.4}};     // levels, axis, push_s, max_travel_mm (diag's push)
  std::set<std::string> skip;       // items to SKIP (reason: --skip)
};

// Runs the checklist. Returns kExitOk (all PASS), kExitCheckFailed (an item FAILed),
// kExitCheckSkipped (none failed, some SKIPped), or kExitDeviceFault (the device entered its safe
// state: that item FAILs naming the fault, the rest are not run).
int run_check(drivers::HapticDevice& dev, const CheckOptions& opt, std::ostream& out);

}  // namespace haptic::tools
