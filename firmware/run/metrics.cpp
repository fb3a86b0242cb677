#include "firmware/run/metrics.hpp"

#include <algorithm>
#include <cmath>

namespace haptic::firmware {

MetricsWindows metrics_windows(const UserScriptSpec& sc) {
  MetricsWindows w;
  w.push_start_s = sc.push_start_s;
  switch (sc.kind) {
    case UserScriptSpec::Kind::kPushHoldRelease:
      w.release_s = sc.release_s;
      w.push_end_s = sc.push_end_s;
      w.hold_start_s = sc.push_end_s + 0.5 * (sc.release_s - sc.push_end_s);
      w.hold_end_s = sc.release_s;
      break;
    case UserScriptSpec::Kind::kPerturb:
      w.release_s = sc.perturb_at_s + sc.perturb_duration_s;
      break;
    case UserScriptSpec::Kind::kHold:
    case UserScriptSpec::Kind::kRandom:
      w.release_s = 0;
      break;
  }
  return w;
}

CopiesSample measure_copies(const std::vector<const double*>& x, const Eigen::VectorXd& x_d) {
  CopiesSample s;
  s.consensus_error_m = model::consensus_error_m(x, static_cast<int>(x_d.size() / 3));
  s.deformation_m = model::deformation_m(x, x_d);
  return s;
}

RunMetrics::RunMetrics(const MetricsWindows& windows, double period_s) : w_(windows), T_(period_s) {
  abs_.level_m = w_.consensus_threshold_m;
}

void RunMetrics::note_after_release(Threshold& th, double t_next, double err) const {
  if (!(err < th.level_m)) th.last_violation_s = t_next;
}

void RunMetrics::add_copies(std::int64_t k, const CopiesSample& s) {
  const double t = static_cast<double>(k) * T_, t_next = static_cast<double>(k + 1) * T_;
  const double err = s.consensus_error_m;
  prev_k_ = last_k_;
  last_k_ = k;
  last_err_ = err;
  max_err_ = std::max(max_err_, err);
  if (!(t_next > w_.push_start_s && t_next <= w_.push_end_s)) growth_.add(t_next, err);  // not during the scripted push
  if (t_next > w_.release_s) {
    if (!after_release_ && err_at_release_)
      for (std::size_t f = 0; f < 2; ++f) rel_[f].level_m = kConsensusFractions[f] * *err_at_release_;
    after_release_ = true;
    note_after_release(abs_, t_next, err);
    if (err_at_release_)
      for (auto& th : rel_) note_after_release(th, t_next, err);
  } else {
    err_at_release_ = err;
  }
  deformation_.emplace_back(k, s.deformation_m);
  if (t >= w_.hold_start_s && t < w_.hold_end_s) {
    deform_sum_ += s.deformation_m;
    ++deform_n_;
  }
}

void RunMetrics::add_forces(std::int64_t k, const std::vector<Eigen::Vector3d>& forces) {
  const double t = static_cast<double>(k) * T_;
  if (!(t >= w_.hold_start_s && t < w_.hold_end_s) || forces.empty()) return;
  const model::ForceBalance b = model::force_balance(forces);
  hold_sum_ += b.sum_norm_N;
  hold_mean_ += b.mean_norm_N;
  ++hold_n_;
}

void RunMetrics::add_energies(double port_total_J, double controller_total_J) {
  port_min_ = std::min(port_min_.value_or(0.0), port_total_J);
  ctrl_max_ = std::max(ctrl_max_.value_or(0.0), controller_total_J);
}

void RunMetrics::add_speed(double v) { speed_max_ = std::max(speed_max_.value_or(0.0), std::isfinite(v) ? v : INFINITY); }

void RunMetrics::add_divergence(double t_s) {
  if (!diverged_at_) diverged_at_ = t_s;
}

std::optional<double> RunMetrics::consensus_time(const Threshold& th) const {
  if (diverged_at_ || !after_release_ || !(last_err_ < th.level_m)) return std::nullopt;
  return th.last_violation_s ? std::max(0.0, *th.last_violation_s - w_.release_s) : 0.0;
}

RunMetricsResult RunMetrics::result(std::int64_t ticks_run) const {
  RunMetricsResult r;
  r.period_s = T_;
  r.simulated_s = static_cast<double>(ticks_run) * T_;
  r.release_time_s = w_.release_s;
  r.hold_window_start_s = w_.hold_start_s;
  r.hold_window_end_s = w_.hold_end_s;
  if (last_k_ >= 0) {
    r.consensus_error_m = last_err_;
    r.max_consensus_error_m = max_err_;
    r.consensus_error_at_release_m = err_at_release_;
    r.consensus_time_s = consensus_time(abs_);
    if (err_at_release_) {
      r.consensus_time_10pct_s = consensus_time(rel_[0]);
      r.consensus_time_1pct_s = consensus_time(rel_[1]);
    }
    r.consensus_time_resolution_s = static_cast<double>(prev_k_ >= 0 ? last_k_ - prev_k_ : 1) * T_;
  }
  if (hold_n_ > 0) {
    r.hold_force_sum_N = hold_sum_ / static_cast<double>(hold_n_);
    r.hold_force_mean_N = hold_mean_ / static_cast<double>(hold_n_);
    if (*r.hold_force_mean_N > 0) r.hold_force_balance_ratio = model::force_balance_ratio(*r.hold_force_sum_N, *r.hold_force_mean_N);
  }
  if (deform_n_ > 0) {
    r.deformation_hold_m = deform_sum_ / static_cast<double>(deform_n_);
    for (const auto& [k, d] : deformation_)
      if (d >= 0.9 * *r.deformation_hold_m) {
        r.deformation_rise_time_s = static_cast<double>(k + 1) * T_ - w_.push_start_s;
        break;
      }
  }
  r.port_energy_min_J = port_min_;
  r.controller_energy_max_J = ctrl_max_;
  r.diverged = diverged_at_.has_value();
  r.diverged_at_s = diverged_at_;
  r.growth_detected_at_s = growth_.detected_at_s();
  r.growth_rate_per_s = growth_.rate_per_s();
  r.unstable = r.diverged || r.growth_detected_at_s.has_value();
  r.max_node_speed_m_per_s = speed_max_;
  return r;
}

}  // namespace haptic::firmware
