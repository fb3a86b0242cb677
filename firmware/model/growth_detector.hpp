#pragma once
// Divergence by growth: a slow instability grows for seconds before any node
// reaches the 50 m/s speed threshold (the tight case at 0.45 x eq. 18: the consensus error grows
// from 0.6 mm to 0.6 m in 10 s). The detector takes the maximum of a signal (the consensus error,
// or an energy) over consecutive windows of window_s and reports growth when `windows`
// consecutive window maxima each exceed the previous one by at least `factor`, the first of them
// above `base` and the last above `floor` (so numerical noise and a push's ramp do not count). Used by
// the run metrics (firmware/run/metrics), so the simulator and the merge decide alike; they skip
// the scripted push (its cosine ramp rises like t^2 at first, 4x, 2.3x, 1.6x per window, which
// these criteria would call growth: 16 users did). A window without samples breaks a run.
// Not RT-safe (off the tick); allocation-free after construction.
#include <optional>

namespace haptic::firmware {

struct GrowthCriteria {
  double window_s = 0.5;   // window length
  double factor = 1.5;     // each window max >= factor x the previous one
  int windows = 3;         // that many times in a row (1.5^3 = 3.4x over 1.5 s; a linear ramp from 0 gives 2x, 1.5x, 1.33x: no)
  double floor = 1e-4;     // the last window max must exceed this (signal units)
  double base = 1e-5;      // a window below this does not start a run (from numerical zero every ratio is huge)
};

class GrowthDetector {
 public:
  explicit GrowthDetector(const GrowthCriteria& c = {}) : c_(c) {}
  // One sample at time t_s (increasing). Non-finite samples count as growth past any floor.
  void add(double t_s, double value);
  // Time (end of the last window of the run of growth) at which growth was first detected.
  const std::optional<double>& detected_at_s() const { return detected_at_; }
  // ln(last window max / first window max) / elapsed time over the detecting run of windows (1/s).
  const std::optional<double>& rate_per_s() const { return rate_; }
  const GrowthCriteria& criteria() const { return c_; }

 private:
  void close_window(double end_s);
  GrowthCriteria c_;
  double window_start_s_ = 0, window_max_ = 0;
  bool started_ = false, any_in_window_ = false;
  double prev_max_ = 0, run_first_max_ = 0;
  bool have_prev_ = false;
  int run_ = 0;
  std::optional<double> detected_at_, rate_;
};

}  // namespace haptic::firmware
