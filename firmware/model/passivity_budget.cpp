#include "firmware/model/passivity_budget.hpp"

#include <cmath>
#include <stdexcept>
#include <vector>

namespace haptic::model {

int clock_allowance_ticks(const ClockModel& c, double run_s, double period_s) {
  if (!c.any()) return 0;
  const double ticks = run_s / period_s;
  const double drift = 2.0 * c.clock_drift_ppm * 1e-6 * ticks;
  const double wander = 3.0 * std::sqrt(2.0 * ticks / 3.0) * c.step_jitter;
  return static_cast<int>(std::ceil(c.timer_jitter_s / period_s + drift + wander));
}

NbarAllowances delay_model_allowances(int loss_allowance_ticks, const LossModel& loss, double run_s, double period_s,
                                      int directed_links, const rt::TxDeadbandConfig& deadband, const ClockModel& clock) {
  NbarAllowances a;
  a.loss_ticks = loss_allowance_ticks >= 0 ? loss_allowance_ticks : loss_allowance_from_loss(loss, run_s / period_s, directed_links);
  a.deadband_ticks = deadband.added_index_delay_ticks(a.loss_ticks);
  a.clock_ticks = clock_allowance_ticks(clock, run_s, period_s);
  return a;
}

LinkBound link_bound_from_delay_model(const Eigen::MatrixXi& nbar, int i, int j) {
  LinkBound b;
  b.guard_ticks = nbar(i, j);
  b.round_trip_ticks = nbar(i, j) + nbar(j, i);
  b.assumed_sum_ticks = b.round_trip_ticks;
  return b;
}

double round_trip_bound_s(double max_s, double margin_fraction, double margin_s) { return max_s * (1.0 + margin_fraction) + margin_s; }

LinkBound link_bound_from_round_trip(int measured, int loss_round_trip, const rt::TxDeadbandConfig& deadband, int agreement,
                                     rt::RxRule rule) {
  // The deadband may hold a state longer in EACH direction, by its allowance for that direction's
  // loss allowance: each one-way guard ceil(R/2) needs that much more, so the round trip grows by
  // the sum (affine in L: added(L_ij + L_ji) + added(0)).
  LinkBound b;
  b.round_trip_ticks = measured + loss_round_trip + deadband.added_index_delay_ticks(loss_round_trip) + deadband.added_index_delay_ticks(0);
  // each direction's spread is at most its largest one-way delay, the guard ceil(R/2)
  b.round_trip_ticks += 2 * receive_rule_ticks(rule, index_guard_from_round_trip(b.round_trip_ticks));
  b.guard_ticks = index_guard_from_round_trip(b.round_trip_ticks);
  b.assumed_sum_ticks = assumed_round_trip_sum_ticks(b.round_trip_ticks, agreement);
  return b;
}

Damping damping_eq18(double t_min_i_s, std::span<const int> sums, std::span<const double> t_max_j_s, std::span<const rt::EdgeGains* const> gains,
                     double margin, double override_B, rt::ConsensusPassivity law) {
  if (sums.size() != t_max_j_s.size() || sums.size() != gains.size())
    throw std::invalid_argument("eq. (18): one round trip, T_j^max and gain set per neighbour needed");
  std::vector<rt::Eq18Neighbor> nb;
  for (std::size_t n = 0; n < sums.size(); ++n) nb.push_back({static_cast<double>(sums[n]), t_max_j_s[n], gains[n]});
  Damping d;
  // eq. (18) with T_j^max and T_i^min: its D_ij term 1/2 (T_j^max / T_i^min - 1) D_ij counts when steps vary
  d.min_Ns_per_m = rt::damping_min_eq18(t_min_i_s, nb);
  const bool pspm = law == rt::ConsensusPassivity::kSetPositionModulation;
  d.used_Ns_per_m = override_B >= 0 ? override_B : pspm ? 0.0 : (1.0 + margin) * d.min_Ns_per_m;
  d.condition_met = pspm || d.used_Ns_per_m >= d.min_Ns_per_m * (1 - 1e-12);
  return d;
}

double consensus_spring_J(const rt::EdgeGains& g, const double* x_p, const double* x_q) {
  const int dofs = g.P.dofs();
  Eigen::VectorXd dx = Eigen::Map<const Eigen::VectorXd>(x_p, dofs) - Eigen::Map<const Eigen::VectorXd>(x_q, dofs);
  Eigen::VectorXd Pdx = Eigen::VectorXd::Zero(dofs);
  g.P.multiply_add(1.0, dx.data(), Pdx.data());
  return dx.dot(Pdx) / 4.0;
}

double consensus_spring_bound_J(double lambda_max_P, const double* x_p, const double* x_q, int dofs) {
  const Eigen::VectorXd dx = Eigen::Map<const Eigen::VectorXd>(x_p, dofs) - Eigen::Map<const Eigen::VectorXd>(x_q, dofs);
  return lambda_max_P * dx.squaredNorm() / 4.0;
}

double pspm_reservoirs_J(rt::ConsensusPassivity law, int links, double reservoir0_J) {
  return law == rt::ConsensusPassivity::kSetPositionModulation ? 2.0 * static_cast<double>(links) * reservoir0_J : 0.0;
}

double eq13_d2_J(std::span<const double> copy_energy_J, std::span<const double> link_spring_J, double reservoirs_J) {
  double d2 = 0;
  for (double e : copy_energy_J) d2 += e;
  for (double e : link_spring_J) d2 += e;
  return d2 + reservoirs_J;
}

bool eq13_broken(const std::optional<double>& port_energy_min_J, double d2_J) {
  return port_energy_min_J && *port_energy_min_J < -d2_J - 1e-9 - 1e-9 * d2_J;
}

}  // namespace haptic::model
