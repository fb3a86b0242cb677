// Theorem 1 in closed loop where eq. (18) is nearly tight: the paper's star with every
// one-way delay 1.33 ms (packets arrive within one tick: Nbar_ij = 1), no loss, no duplication,
// no loss allowance and D_ij = 0, user 1 perturbing at 2.5 s. Eq. (18) gives B = (6, 2, 2, 2) N s/m;
// the simulated system is stable at eq. (18) and diverges at 0.45 x eq. (18) (measured: at 6.76 s),
// and there the energy monitors show the controller ports generating energy.
#include <CppUTest/TestHarness.h>

#include <Eigen/Dense>
#include <cmath>
#include <algorithm>
#include <memory>
#include <optional>

#include "firmware/scenario.hpp"
#include "firmware/sim/simulator.hpp"
#include "tests/firmware/tight_case.hpp"

using namespace haptic::firmware;

namespace {
ScenarioSpec tight_spec(std::optional<double> factor_of_eq18) { return haptic::test::tight_case_spec(factor_of_eq18, 0.0, 8.0); }
}  // namespace

TEST_GROUP(Theorem1ClosedLoop){};

TEST(Theorem1ClosedLoop, tight_case_eq18_damping_matches_an_independent_evaluation) {
  // Independently: Nbar = ceil(1.5 x 1.33 ms / 2 ms) + 0 = 1 tick each way; lambda_max(P) = 1000 N/m
  // (P = 1000 [I/2 + K_int/(2 lambda_max)]); per edge (1 + 1)/2 x 0.002 s x 1000 N/m = 2 N s/m.
  const BuiltScenario b = build_scenario(tight_spec(std::nullopt));
  const double expect[4] = {6.0, 2.0, 2.0, 2.0};
  for (int i = 0; i < 4; ++i) DOUBLES_EQUAL(expect[i], b.damping_min[static_cast<std::size_t>(i)], 1e-9);
  // and the damping used meets (18) by the margin, not by definition of the test
  for (int i = 0; i < 4; ++i) DOUBLES_EQUAL(1.05 * expect[i], b.damping[static_cast<std::size_t>(i)], 1e-9);
  CHECK_TRUE(b.passivity_condition_met);
  CHECK_FALSE(build_scenario(tight_spec(0.99)).passivity_condition_met);
}

TEST(Theorem1ClosedLoop, tight_case_is_stable_and_passive_at_eq18) {
  const BuiltScenario b = build_scenario(tight_spec(1.0));
  const SimResult r = run_simulation(b, SimOptions{});
  CHECK_FALSE(r.metrics.diverged);
  CHECK_TRUE(*r.metrics.controller_energy_max_J <= r.passivity_bound_J + 1e-9);
  CHECK_TRUE(*r.metrics.port_energy_min_J >= -r.passivity_bound_J - 1e-9);
  CHECK_TRUE(*r.metrics.max_consensus_error_m > 1e-5);  // the perturbation really moved user 1's copy
  CHECK_TRUE(*r.metrics.consensus_error_m < 0.1 * *r.metrics.max_consensus_error_m);
}

TEST(Theorem1ClosedLoop, tight_case_diverges_at_0_45_of_eq18_and_the_energy_monitors_show_it) {
  const BuiltScenario b = build_scenario(tight_spec(0.45));
  CHECK_FALSE(b.passivity_condition_met);
  const SimResult r = run_simulation(b, SimOptions{});
  CHECK_TRUE(r.metrics.diverged);
  CHECK_TRUE(*r.metrics.diverged_at_s > 2.5);  // after the perturbation, growing from it
  // the controller ports generated energy far beyond c^2 (eq. 14 broken), the device ports
  // gave out energy beyond d^2 (eq. 13 broken)
  CHECK_TRUE(*r.metrics.controller_energy_max_J > r.passivity_bound_J + 1.0);
  CHECK_TRUE(*r.metrics.port_energy_min_J < -r.passivity_bound_J - 0.1);
}

// Passive set-position modulation (rt/set_position_modulation.hpp) instead of eq. (18): B_i = 0.
TEST(Theorem1ClosedLoop, tight_case_without_damping_diverges_under_the_papers_law_and_is_passive_and_converges_under_modulation) {
  ScenarioSpec plain = tight_spec(std::nullopt);
  plain.damping_Ns_per_m = std::vector<double>(4, 0.0);
  const SimResult rp = run_simulation(build_scenario(plain), SimOptions{});
  CHECK_TRUE(rp.metrics.diverged);  // measured: at 2.84 s
  ScenarioSpec pspm = plain;
  pspm.consensus_passivity = haptic::rt::ConsensusPassivity::kSetPositionModulation;
  pspm.pspm_reservoir0_J = 0.0;
  const SimResult r = run_simulation(build_scenario(pspm), SimOptions{});
  CHECK_FALSE(r.metrics.diverged);
  CHECK_TRUE(*r.metrics.controller_energy_max_J <= r.passivity_bound_J + 1e-12);
  CHECK_TRUE(*r.metrics.port_energy_min_J >= -r.passivity_bound_J - 1e-12);
  CHECK_TRUE(*r.metrics.max_consensus_error_m > 1e-5);
  CHECK_TRUE(*r.metrics.consensus_error_m < 0.1 * *r.metrics.max_consensus_error_m);
  for (const auto& l : r.links) CHECK_TRUE(l.edge_energy.peak_J <= 1e-12);  // no edge end ever put energy in (E0 = 0)
}

TEST(Theorem1ClosedLoop, paper_worst_deforms_as_far_at_least_twice_as_fast_under_modulation_as_at_eq18) {
  // eq. (18) on the worst topology needs B_i up to 666 N s/m, which slows every push; the modulation
  // needs none (measured: rise to 90 % of the hold deformation 16.0 s vs 4.7 s, hold 1.835 vs 1.838 mm).
  ScenarioSpec eq18 = make_scenario("paper-worst");
  ScenarioSpec pspm = eq18;
  pspm.consensus_passivity = haptic::rt::ConsensusPassivity::kSetPositionModulation;
  pspm.pspm_reservoir0_J = 1e-3;
  const SimResult a = run_simulation(build_scenario(eq18), SimOptions{});
  const SimResult b = run_simulation(build_scenario(pspm), SimOptions{});
  CHECK_FALSE(b.metrics.diverged);
  CHECK_TRUE(*a.metrics.deformation_rise_time_s >= 2.0 * *b.metrics.deformation_rise_time_s);
  DOUBLES_EQUAL(*a.metrics.deformation_hold_m, *b.metrics.deformation_hold_m, 0.05 * *a.metrics.deformation_hold_m);
  CHECK_TRUE(b.metrics.consensus_time_s.has_value());
  CHECK_TRUE(*b.metrics.port_energy_min_J >= -b.passivity_bound_J - 1e-12);
  for (const auto& l : b.links) CHECK_TRUE(l.edge_energy.peak_J <= 1e-3 + 1e-12);
}

// Where eq. (18) binds in closed loop (scenario eq18-binds; rt/README.md "Where eq. (18) binds"): two
// copies of a heavy object (33 kg) on one link, constant delays of 5 ticks each way, D_ij = 0, no
// loss, no gate. The loop's own mode is then the slow antiphase motion of the two copies that eq.
// (18)'s worst case assumes, so the simulated boundary sits between 0.8x and 0.9x of eq. (18)
// (measured: 0.7x diverges at 10.9 s, 0.8x at 20.0 s, 0.9x and 1.0x passive), where the paper's
// four-user star needs at most 0.5x-0.6x.
namespace {
ScenarioSpec binds_spec(std::optional<double> factor_of_eq18) {
  ScenarioSpec s = make_scenario("eq18-binds");
  if (factor_of_eq18) {
    const BuiltScenario b = build_scenario(s);
    std::vector<double> d;
    for (double m : b.damping_min) d.push_back(*factor_of_eq18 * m);
    s.damping_Ns_per_m = d;
  }
  return s;
}
}  // namespace

TEST(Theorem1ClosedLoop, where_eq18_binds_eq18_asks_10_Ns_per_m_by_an_independent_evaluation) {
  // Nbar = ceil(9.9 ms / 2 ms) + 0 = 5 ticks each way; (5 + 5)/2 x 0.002 s x lambda_max(P) = 1000 N/m.
  for (double m : build_scenario(binds_spec(std::nullopt)).damping_min) DOUBLES_EQUAL(10.0, m, 1e-9);
}

TEST(Theorem1ClosedLoop, where_eq18_binds_the_loop_is_passive_and_converges_at_eq18) {
  for (const std::optional<double> f : {std::optional<double>(), std::optional<double>(1.0)}) {
    const SimResult r = run_simulation(build_scenario(binds_spec(f)), SimOptions{});
    CHECK_FALSE(r.metrics.diverged);
    CHECK_EQUAL(std::string("stable"), sim_verdict(r));
    CHECK_TRUE(*r.metrics.controller_energy_max_J <= r.passivity_bound_J + 1e-9);  // eq. (14)
    CHECK_TRUE(*r.metrics.port_energy_min_J >= -r.passivity_bound_J - 1e-9);      // eq. (13)
    CHECK_TRUE(*r.metrics.max_consensus_error_m > 1e-5);  // the perturbation moved user 1's copy
    CHECK_TRUE(*r.metrics.consensus_error_m < 0.01 * *r.metrics.max_consensus_error_m);
  }
}

TEST(Theorem1ClosedLoop, where_eq18_binds_0_8_of_it_makes_the_controller_generate_energy_and_the_loop_diverge) {
  for (double f : {0.8, 0.5}) {
    const BuiltScenario b = build_scenario(binds_spec(f));
    CHECK_FALSE(b.passivity_condition_met);
    const SimResult r = run_simulation(b, SimOptions{});
    CHECK_TEXT(r.metrics.diverged, ("at " + std::to_string(f) + "x eq. (18)").c_str());
    CHECK_EQUAL(std::string("diverged"), sim_verdict(r));
    CHECK_TRUE(*r.metrics.controller_energy_max_J > r.passivity_bound_J + 1.0);  // eq. (14) broken
    CHECK_TRUE(*r.metrics.port_energy_min_J < -r.passivity_bound_J - 1.0);      // eq. (13) broken
  }
}

// Between the two: at 0.85x the loop grows too slowly for the divergence speed (50 m/s) and the growth
// detector (1.5x per 0.5 s) within the run (measured: consensus error 0.17 -> 23.5 mm in 30 s), yet the
// users' ports took energy out beyond -d^2. Such a run is never reported "stable": its verdict says
// eq. (13) was broken.
TEST(Theorem1ClosedLoop, where_eq18_binds_a_slow_instability_at_0_85_of_it_is_reported_not_passive_never_stable) {
  const SimResult r = run_simulation(build_scenario(binds_spec(0.85)), SimOptions{});
  CHECK_TRUE(*r.metrics.port_energy_min_J < -r.passivity_bound_J - 1e-6);
  CHECK_TRUE(*r.metrics.consensus_error_m > 10.0 * *r.metrics.consensus_error_at_release_m);  // growing, not settling
  const std::string v = sim_verdict(r);
  CHECK_TRUE(v != "stable");
  if (!r.metrics.diverged && !r.metrics.unstable) CHECK_EQUAL(std::string("not_passive"), v);
}

TEST_GROUP(ReceiveRule){};

TEST(ReceiveRule, the_papers_rule_uses_late_data_so_index_delays_grow_on_the_worst_topology) {
  // Fig. 4's "most recently received" against newest-by-sequence on the same seeded network: the
  // paper's rule keeps swapped (late) packets, so measured index delays are at least as large on
  // every link and larger on some, beyond the newest rule's Nbar on some link; each rule's own Nbar
  // (model::receive_rule_ticks adds the delay spread under the paper's rule) is never exceeded.
  ScenarioSpec s = make_scenario("paper-worst");
  s.duration_s = 10.0;
  const BuiltScenario bn = build_scenario(s);
  const SimResult newest = run_simulation(bn, SimOptions{});
  s.receive_rule = haptic::rt::RxRule::kMostRecentlyReceived;
  const SimResult paper = run_simulation(build_scenario(s), SimOptions{});
  CHECK_FALSE(newest.metrics.diverged);
  CHECK_FALSE(paper.metrics.diverged);
  bool larger = false, beyond_newest_bound = false;
  for (std::size_t l = 0; l < newest.links.size(); ++l) {
    CHECK_EQUAL(newest.links[l].sent, paper.links[l].sent);  // the same network
    CHECK_TRUE(paper.links[l].max_index_delay >= newest.links[l].max_index_delay);
    larger = larger || paper.links[l].max_index_delay > newest.links[l].max_index_delay;
    beyond_newest_bound = beyond_newest_bound || paper.links[l].max_index_delay > bn.nbar_ticks(paper.links[l].to, paper.links[l].from);
    CHECK_EQUAL(0u, newest.links[l].bound_violations);
    CHECK_EQUAL(0u, paper.links[l].bound_violations);
  }
  CHECK_TRUE(larger);
  CHECK_TRUE(beyond_newest_bound);
}

TEST(ReceiveRule, each_rules_own_nbar_holds_in_the_paper_runs) {
  // paper-best and paper-worst, whole runs, under either rule: no index delay above the Nbar the
  // scenario derived for the rule in force (no edge drop), and the paper's rule pays for it in Nbar.
  for (const char* name : {"paper-best", "paper-worst"}) {
    ScenarioSpec s = make_scenario(name);
    const BuiltScenario bn = build_scenario(s);
    s.receive_rule = haptic::rt::RxRule::kMostRecentlyReceived;
    const BuiltScenario bp = build_scenario(s);
    CHECK_TRUE(bp.nbar_ticks.sum() > bn.nbar_ticks.sum());
    const SimResult r = run_simulation(bp, SimOptions{});
    for (const auto& l : r.links) CHECK_EQUAL(0u, l.bound_violations);
  }
}

TEST_GROUP(BurstLoss){};

TEST(BurstLoss, the_burst_models_allowance_keeps_every_index_delay_within_nbar_and_the_iid_one_does_not) {
  // paper-best with Gilbert-Elliott bursts (1 % entry per packet, 5 packets mean, all lost inside)
  // on every link: Nbar from the burst chain has no over-bound event; the allowance the same mean
  // loss would get if it were independent is exceeded (so the burst model is what keeps eq. 18 true).
  ScenarioSpec s = make_scenario("paper-best");
  s.burst_enter_probability = 0.01;
  s.burst_mean_packets = 5;
  const BuiltScenario burst = build_scenario(s);
  const SimResult r = run_simulation(burst, SimOptions{});
  std::uint64_t over = 0;
  for (const auto& l : r.links) over += l.bound_violations;
  CHECK_EQUAL(0u, over);
  s.loss_allowance_ticks = haptic::model::loss_allowance_from_loss(0.05 + 0.01 / 0.21, s.duration_s / s.period_s, 6);
  CHECK_TRUE(s.loss_allowance_ticks < burst.loss_allowance_ticks);
  const SimResult iid = run_simulation(build_scenario(s), SimOptions{});
  over = 0;
  for (const auto& l : iid.links) over += l.bound_violations;
  CHECK_TRUE(over > 0);
}

TEST_GROUP(DelayTrace){};

TEST(DelayTrace, a_recorded_trace_replayed_on_every_link_sets_nbar_from_its_range_and_stays_within_it) {
  // A trace with spikes far beyond the paper's uniform support (5 ms most of the time, 60 ms every
  // 50th packet): Nbar = ceil(60 ms / T) + L under newest-by-sequence, + ceil((60 - 5) ms / T) + 1
  // under the paper's rule (computed here), and neither run has an over-bound event.
  auto trace = std::make_shared<std::vector<double>>();
  for (int k = 0; k < 500; ++k) trace->push_back(k % 50 == 0 ? 0.060 : 0.005);
  for (auto rule : {haptic::rt::RxRule::kNewestBySequence, haptic::rt::RxRule::kMostRecentlyReceived}) {
    ScenarioSpec s = make_scenario("paper-best");
    s.duration_s = 6.0;
    s.delay_trace = trace;
    s.receive_rule = rule;
    const BuiltScenario b = build_scenario(s);
    const int expected = 30 + b.loss_allowance_ticks + (rule == haptic::rt::RxRule::kNewestBySequence ? 0 : 28 + 1);
    CHECK_EQUAL(expected, b.nbar_ticks(0, 1));
    CHECK_EQUAL(expected, b.nbar_ticks(3, 0));
    const SimResult r = run_simulation(b, SimOptions{});
    std::int64_t longest = 0;
    for (const auto& l : r.links) {
      CHECK_EQUAL(0u, l.bound_violations);
      DOUBLES_EQUAL(0.060, l.delay_max_s, 1e-12);  // the trace, not the paper's delays
      longest = std::max(longest, l.max_index_delay);
    }
    // the paper's rule uses the late 60 ms packets (N reaches 30 ticks); newest-by-sequence drops them as stale
    if (rule == haptic::rt::RxRule::kMostRecentlyReceived) CHECK_TRUE(longest >= 30);
    else CHECK_TRUE(longest < 30);
  }
}
