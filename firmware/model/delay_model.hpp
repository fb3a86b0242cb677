#pragma once
// The delay model around the tick, one implementation for the simulator, the real station, the
// multi-process merge and tools/topology:
//  - the paper's mean one-way delay matrix (Section V) and a text parser for such matrices;
//  - the index-delay bound of eq. (18): Nbar_ij = ceil(max one-way delay_ij / T) + allowances
//    (firmware/model/passivity_budget.hpp), with max delay = (1 + jitter fraction) x mean for a uniform jitter;
//  - eq. (18)'s per-user sum  sum_j (Nbar_ij + Nbar_ji) T / 2;
//  - the same bounds from a round trip R_ij a station measured itself (ticks): guard
//    Nbar_ij = ceil(R_ij / 2), assumed Nbar_ij + Nbar_ji = 2 ceil(R_ij / 2) + agreement ticks;
//  - the mixing model's N_ij = round(mean_ij / T) of Section IV (eq. 27).
// Row i receives from column j everywhere. Start-up/offline code (allocates; not RT-safe).
#include <string>

#include <Eigen/Core>

#include "firmware/model/graph.hpp"
#include "rt/rx_link.hpp"

namespace haptic::model {

// The loss allowance of Nbar from the loss model's support. Under independent loss with
// probability p per packet, N_ij^k > ceil(max delay / T) + L at tick k only if the L + 1 packets
// sent in ticks k - ceil(max delay / T) - L .. k - ceil(max delay / T) were all lost (each of
// them, delivered, arrives by tick k): probability <= p^(L+1). The allowance is the smallest L
// with ticks x directed_links x p^(L+1) <= per_run (union bound: the chance that a run sees an
// over-bound event at all). p = 0: 0. Throws std::invalid_argument for p outside [0, 1).
inline constexpr double kOverBoundChancePerRun = 0.01;
int loss_allowance_from_loss(double loss_probability, double ticks, int directed_links, double per_run = kOverBoundChancePerRun);

// A link's loss: independent with probability p per packet, optionally under Gilbert-Elliott
// bursts (net::LinkImpairment's chain, stepped once per packet: good -> bad with burst_enter, bad ->
// good with burst_exit, loss burst_loss in the bad state and p in the good one; off when
// burst_enter = 0).
struct LossModel {
  double p = 0;
  double burst_enter = 0;
  double burst_exit = 1;
  double burst_loss = 1;
  bool bursty() const { return burst_enter > 0; }
};
// The chance that n given consecutive packets are all lost, with the chain in its stationary state
// (p^n without bursts). Throws std::invalid_argument for probabilities outside their ranges.
double consecutive_loss_probability(const LossModel& loss, int n);
// The allowance as above for any LossModel: the smallest L with ticks x directed_links x
// consecutive_loss_probability(L + 1) <= per_run (= loss_allowance_from_loss without bursts).
int loss_allowance_from_loss(const LossModel& loss, double ticks, int directed_links, double per_run = kOverBoundChancePerRun);

// The same allowance from a measured loss: `lost` of `expected` packets (a station's probing). The
// loss probability put in is the upper end of the Wilson score interval at z = 1.96 (97.5 %
// one-sided), so a short probe with no loss still gets an allowance (0 of 100 lost: p <= 0.037),
// and the allowance falls as the probe grows. Throws std::invalid_argument when expected <= 0 or
// lost is outside [0, expected].
inline constexpr double kLossMeasurementZ = 1.96;
double loss_upper_bound(long long lost, long long expected, double z = kLossMeasurementZ);
int loss_allowance_from_measured_loss(long long lost, long long expected, double ticks, int directed_links,
                                      double per_run = kOverBoundChancePerRun);

// The paper's mean one-way delays (ms), Section V: [[0,4,4,4],[8,0,80,200],[4,100,0,200],[6,240,200,0]].
Eigen::MatrixXd paper_delay_matrix_ms();

// "0,4;8,0": rows separated by ';', entries by ','; blanks and [ ] ignored; "inf" = no link.
// users > 0: exactly that many rows and columns ("needs N rows", "row r needs N values");
// users <= 0: any square N >= 2. Throws std::invalid_argument naming `key`.
Eigen::MatrixXd parse_delay_matrix(const std::string& text, const std::string& key, int users = 0);

// eq. (18) index-delay bound for one directed link whose packets arrive at most max_delay_ms
// after they were sent: ceil(max_delay / T) + loss_allowance_ticks (ticks).
int index_delay_bound_ticks(double max_delay_ms, double period_s, int loss_allowance_ticks);
// The receive rule's share of Nbar (ticks) for a link whose delays lie in [min, max]. Newest by
// sequence: 0 (the bound above). The paper's rule (Fig. 4: the packet that arrived last is used, even
// an older one): with the held packet s* arrived at a*, every packet s with a* - min < s T <= k T - max
// would have arrived in (a*, k T] and replaced it, so those were lost: k T - a* <= (L + 1) T + max - min,
// and N = k - s* <= (k T - a* + max) / T. The held packet can be older by the delay spread:
// ceil((max - min) / T) + 1 ticks (the + 1: whole ticks).
int receive_rule_ticks(rt::RxRule rule, double min_delay_ms, double max_delay_ms, double period_s);
// The same for a spread already in whole ticks: 0 (newest) or spread_ticks + 1 (paper).
int receive_rule_ticks(rt::RxRule rule, int spread_ticks);
// The same for every ordered pair of a mean delay matrix with uniform jitter (delays in
// mean [1 - jitter_fraction, 1 + jitter_fraction]) under the receive rule in force; diagonal 0.
Eigen::MatrixXi index_delay_bounds_ticks(const Eigen::MatrixXd& mean_delay_ms, double jitter_fraction, double period_s,
                                         int loss_allowance_ticks, rt::RxRule rule = rt::RxRule::kNewestBySequence);
// The same for links whose every delay lies in [min_delay_ms, max_delay_ms] (a recorded delay trace
// replayed on every link): each ordered pair with a finite entry of `links` (a delay matrix; its
// values unused) gets the bound of that range; diagonal 0.
Eigen::MatrixXi index_delay_bounds_ticks_from_range(const Eigen::MatrixXd& links, double min_delay_ms, double max_delay_ms, double period_s,
                                                    int loss_allowance_ticks, rt::RxRule rule = rt::RxRule::kNewestBySequence);
// eq. (18) bookkeeping: per user sum over its links of (Nbar_ij + Nbar_ji) T / 2, in ms.
Eigen::VectorXd round_trip_half_sums_ms(const Graph& g, const Eigen::MatrixXi& nbar_ticks, double period_s);

// Bounds from a round trip R (ticks, measured by the station itself, loss allowance included):
// the guard the rt core enforces, Nbar_ij = ceil(R / 2) ...
int index_guard_from_round_trip(int round_trip_ticks);
// ... and the Nbar_ij + Nbar_ji eq. (18) assumes: 2 ceil(R/2) + agreement_ticks, which covers
// the peer's guard ceil(R_ji / 2) while R_ji <= R_ij + 2 agreement_ticks.
int assumed_round_trip_sum_ticks(int round_trip_ticks, int agreement_ticks);

// Section IV mixing model (eq. 27): N_ij = round(mean_ij / T); diagonal 0; +inf (no link) -> -1.
Eigen::MatrixXi mean_delay_steps(const Eigen::MatrixXd& mean_delay_ms, double period_s);

}  // namespace haptic::model
