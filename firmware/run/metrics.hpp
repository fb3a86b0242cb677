#pragma once
// The run metrics: one implementation for the simulator (`haptic-station sim`, every tick) and
// the multi-process merge (`haptic-station merge`, on the ticks every station recorded). Samples
// come in tick order; each metric is null (std::nullopt) when its window held no sample, never 0.
// Not RT-safe (off the tick: the simulator's measurement step and the merge).
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "firmware/model/growth_detector.hpp"
#include "firmware/model/metrics.hpp"
#include "firmware/scenario.hpp"

namespace haptic::firmware {

// The windows the metrics are taken over, from the user script.
struct MetricsWindows {
  double release_s = 0;                     // consensus is timed from here
  double hold_start_s = 0, hold_end_s = 0;  // the hold window [start, end) (empty when equal)
  double push_start_s = 0;                  // the deformation rise time counts from here
  // The scripted push [push_start_s, push_end_s): the hands' goals move into the object, so the
  // copies' consensus error rises with the input (a cosine ramp grows like t^2 at first: 4x, 2.3x,
  // 1.6x per 0.5 s window); the growth detector does not look at it (empty when push_end_s <= push_start_s).
  double push_end_s = 0;
  double consensus_threshold_m = 1e-3;      // the absolute consensus threshold
};
MetricsWindows metrics_windows(const UserScriptSpec& script);

// The fractions of the consensus error at release that the relative consensus times reach.
inline constexpr double kConsensusFractions[] = {0.10, 0.01};

// The copies of the object at one instant: the consensus error and the deformation
// (firmware/model/metrics.hpp).
struct CopiesSample {
  double consensus_error_m = 0;
  double deformation_m = 0;
};
CopiesSample measure_copies(const std::vector<const double*>& x, const Eigen::VectorXd& x_d);

struct RunMetricsResult {
  double period_s = 0;
  double simulated_s = 0;                             // ticks run x T
  double release_time_s = 0;
  std::optional<double> consensus_error_m;            // at the last copies sample
  std::optional<double> max_consensus_error_m;
  std::optional<double> consensus_error_at_release_m; // the last copies sample at or before the release
  // After the release the error stays below the threshold from here on (null: never, diverged,
  // or no sample after the release). Absolute (< consensus_threshold_m) and relative (below
  // kConsensusFractions of the error at release).
  std::optional<double> consensus_time_s;
  std::optional<double> consensus_time_10pct_s, consensus_time_1pct_s;
  std::optional<double> consensus_time_resolution_s;  // spacing of the copies samples
  double hold_window_start_s = 0, hold_window_end_s = 0;
  std::optional<double> hold_force_sum_N, hold_force_mean_N, hold_force_balance_ratio;
  std::optional<double> deformation_hold_m;
  std::optional<double> deformation_rise_time_s;      // to 90 % of the hold deformation
  std::optional<double> port_energy_min_J;            // min over time of the cumulative total (13), from 0
  std::optional<double> controller_energy_max_J;      // max over time of the cumulative total (14), from 0
  bool diverged = false;                              // by speed (the core's divergence_speed_m_per_s)
  std::optional<double> diverged_at_s;
  // Divergence by growth (firmware/model/growth_detector.hpp): the consensus error's 0.5 s maxima grew
  // 1.5x or more three times in a row, to above 0.1 mm. unstable = diverged || growth detected.
  std::optional<double> growth_detected_at_s, growth_rate_per_s;
  bool unstable = false;
  std::optional<double> max_node_speed_m_per_s;       // may be inf
};

class RunMetrics {
 public:
  RunMetrics(const MetricsWindows& windows, double period_s);

  // The copies after tick k (time (k + 1) T). Ticks must increase.
  void add_copies(std::int64_t k, const CopiesSample& s);
  // The device forces commanded at tick k (its start k T), one per station.
  void add_forces(std::int64_t k, const std::vector<Eigen::Vector3d>& forces);
  // The totals over stations of (13) and (14) after tick k.
  void add_energies(double port_total_J, double controller_total_J);
  void add_speed(double max_node_speed_m_per_s);
  void add_divergence(double t_s);

  RunMetricsResult result(std::int64_t ticks_run) const;

 private:
  struct Threshold {
    double level_m = 0;
    std::optional<double> last_violation_s;  // last sample after the release at or above the level
  };
  void note_after_release(Threshold& th, double t_next, double err) const;
  std::optional<double> consensus_time(const Threshold& th) const;

  MetricsWindows w_;
  double T_;
  std::int64_t last_k_ = -1, prev_k_ = -1;
  double last_err_ = 0, max_err_ = 0;
  std::optional<double> err_at_release_;
  bool after_release_ = false;
  Threshold abs_;
  Threshold rel_[2];
  std::vector<std::pair<std::int64_t, double>> deformation_;  // (k, deformation)
  double hold_sum_ = 0, hold_mean_ = 0, deform_sum_ = 0;
  std::int64_t hold_n_ = 0, deform_n_ = 0;
  std::optional<double> port_min_, ctrl_max_, speed_max_, diverged_at_;
  GrowthDetector growth_;  // on the consensus error
};

}  // namespace haptic::firmware
