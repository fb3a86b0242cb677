#pragma once
// The passivity budget: the one place that turns a delay model or a measured round trip into
// what eq. (18) and the rt core need, per link of one station, and the storage d^2 of eq. (13).
// Used by the scenario (simulator), the station's build phase, the multi-process merge and
// haptic-topology; rt/gains.hpp holds eq. (18) itself (damping_min_eq18), this file the policy
// around it (allowances, guard, margin, the pspm rule). Start-up/offline code (allocates, throws
// std::invalid_argument); not RT-safe.
//
// Per directed link i <- j, in ticks of T:
//   Nbar_ij = ceil(max one-way delay_ij / T) + allowances (delay model, index_delay_bounds_ticks), or
//   R_ij    = measured round trip + loss allowance + 2 x deadband allowance (the station's own
//             measurement): guard Nbar_ij = ceil(R_ij / 2), assumed Nbar_ij + Nbar_ji = 2 ceil(R_ij / 2)
//             + agreement ticks (covers the peer's guard while R_ji <= R_ij + 2 agreement ticks).
// The allowances, per direction:
//   loss:     L with ticks x directed links x p^(L+1) <= 1 % per run (loss_allowance_from_loss), or
//             from the loss a station measured while probing (round_trip_loss_allowance, x 2: a round trip);
//   deadband: the sender's transmission deadband sends at least every max_interval I ticks, so with
//             up to L packets lost in a row a state may be held (L + 1)(I - 1) ticks more
//             (rt::TxDeadbandConfig::added_index_delay_ticks);
//   clock:    late wakes, drift and the wander of free-running tick counts (clock_allowance_ticks).
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
#include "rt/gains.hpp"
#include "rt/set_position_modulation.hpp"
#include "rt/tx_deadband.hpp"

namespace haptic::model {

// The station clocks of a run (ScenarioSpec's clock model): every wake late by up to
// timer_jitter_s, each grid interval T (1 + F u) (step_jitter F), two clocks drifting apart by up to
// 2 clock_drift_ppm.
struct ClockModel {
  double timer_jitter_s = 0;
  double step_jitter = 0;
  double clock_drift_ppm = 0;
  bool any() const { return timer_jitter_s > 0 || step_jitter > 0 || clock_drift_ppm > 0; }
};
// Extra index delay (ticks) the clock model can add to N_ij^k = k_i - seq_j over a run of run_s: a
// late wake of the receiver (at most one tick more), the drift of two clocks over the run
// (2 ppm T_run / T), and the wander of free-running tick counts (3 sigma of the difference of two
// sums of i.i.d. steps, sqrt(2 k / 3) F ticks). 0 without a clock model.
int clock_allowance_ticks(const ClockModel& clock, double run_s, double period_s);

// Nbar's allowances per direction (ticks) above ceil(max one-way delay / T).
struct NbarAllowances {
  int loss_ticks = 0;      // given, or loss_allowance_from_loss
  int deadband_ticks = 0;  // rt::TxDeadbandConfig::added_index_delay_ticks(loss_ticks)
  int clock_ticks = 0;     // clock_allowance_ticks
  int total() const { return loss_ticks + deadband_ticks + clock_ticks; }
};
// The delay model's allowances: loss_allowance_ticks >= 0 given, -1 from the loss model over the
// run's ticks and directed links (loss_allowance_from_loss); the deadband's for that loss allowance.
NbarAllowances delay_model_allowances(int loss_allowance_ticks, const LossModel& loss, double run_s, double period_s,
                                      int directed_links, const rt::TxDeadbandConfig& deadband, const ClockModel& clock);

// One link of one station as the budget sees it (ticks).
struct LinkBound {
  int guard_ticks = 0;        // Nbar_ij the rt core enforces (drops data older than this)
  int round_trip_ticks = 0;   // the round trip it comes from: Nbar_ij + Nbar_ji (model) or R_ij (measured)
  int assumed_sum_ticks = 0;  // Nbar_ij + Nbar_ji put into eq. (18)
};
// From the delay model's Nbar matrix (row i receives from column j): guard Nbar_ij, sum Nbar_ij + Nbar_ji.
LinkBound link_bound_from_delay_model(const Eigen::MatrixXi& nbar_ticks, int i, int j);
// The round-trip bound (s) a station takes from the largest round trip it measured while probing
// (and from a later sample above it): max x (1 + margin_fraction) + margin_s (net.rtt_margin_fraction,
// net.rtt_margin_s). The station hands it to net/ (net::RttConfig::bound_policy), which measures.
double round_trip_bound_s(double max_round_trip_s, double margin_fraction, double margin_s);
// From a round trip the station measured (ticks, net/'s bound with its margin), the link's agreed
// loss allowance (ticks on the round trip: L_ij + L_ji) and the transmission deadband (its allowance
// for that loss in both directions).
// Under the paper's receive rule each direction adds its delay spread (model::receive_rule_ticks):
// a one-way delay lies in [0, ceil(R/2)] ticks, so the spread is at most the guard: + ceil(R/2) + 1 ticks per direction.
LinkBound link_bound_from_round_trip(int measured_round_trip_ticks, int loss_allowance_round_trip_ticks, const rt::TxDeadbandConfig& deadband,
                                     int agreement_ticks, rt::RxRule rule = rt::RxRule::kNewestBySequence);

// B_i and whether the passivity condition holds.
struct Damping {
  double min_Ns_per_m = 0;  // eq. (18) on the assumed sums
  double used_Ns_per_m = 0;
  bool condition_met = false;  // eq. (18) with B_i used (eq18); by construction (pspm)
};
// eq. (18) (rt::damping_min_eq18) for station i with T_i^min and per neighbour (in the order of
// the spans) Nbar_ij + Nbar_ji, T_j^max and the edge gains; then B_i: override_Ns_per_m >= 0 given,
// else 0 under pspm (eq. 14 holds by the modulation, rt/set_position_modulation.hpp), else
// (1 + margin) x the minimum. The condition: pspm, or B_i >= minimum (1 - 1e-12, rounding).
Damping damping_eq18(double t_min_i_s, std::span<const int> assumed_sum_ticks, std::span<const double> t_max_j_s,
                     std::span<const rt::EdgeGains* const> gains, double margin, double override_Ns_per_m,
                     rt::ConsensusPassivity law);

// d^2 of eq. (13), the storage the system holds when the port energy starts to count: every copy's
// energy, the consensus springs phi_pq = |x_p - x_q|^2_P / 4 of the links, and under pspm every
// edge end's initial reservoir (eq. 14 with c^2 = E0 per directed edge: 2 E0 per link). The port
// energy sum_k v_hat^T f T stays above -d^2 when the system is passive.
double consensus_spring_J(const rt::EdgeGains& gains, const double* x_p, const double* x_q);
// The same bounded by lambda_max(P) |x_p - x_q|^2 / 4 (>= phi_pq): for readers that have the
// copies but not P (the merge); equal to consensus_spring_J when the copies agree.
double consensus_spring_bound_J(double lambda_max_P, const double* x_p, const double* x_q, int dofs);
double pspm_reservoirs_J(rt::ConsensusPassivity law, int links, double reservoir0_J);
double eq13_d2_J(std::span<const double> copy_energy_J, std::span<const double> link_spring_J, double reservoirs_J);
// Eq. (13) broken: the users' ports took more energy out of the system than its initial d^2 (the
// cumulative port energy's minimum below -d^2 beyond rounding, 1e-9 J + 1e-9 d^2): Theorem 1's
// conclusion does not hold for the run, whatever its speeds did (a slow instability can stay under
// the divergence speed and the growth detector's rate for a whole run). No port energy: false.
bool eq13_broken(const std::optional<double>& port_energy_min_J, double d2_J);

}  // namespace haptic::model
