// firmware/model: the one graph parser, delay model (Nbar, eq. 18 sums, bounds from measured round
// trips), passivity budget and run-metric quantities that the simulator, the station, the merge and
// haptic-topology share.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
#include "firmware/model/metrics.hpp"
#include "firmware/model/passivity_budget.hpp"
#include "firmware/model/probe_loss.hpp"
#include "firmware/scenario.hpp"
#include "tests/support/error_of.hpp"

using namespace haptic;

using haptic::test::error_of;

TEST_GROUP(Model){};

TEST(Model, graph_parser_normalizes_and_names_the_key_on_bad_input) {
  STRCMP_EQUAL("1-2 2-4 3-4", model::to_string_1based(model::parse_graph_1based("4-2, 1-2,3-4", 4)).c_str());
  STRCMP_CONTAINS("station.topology: '1-5' must join users numbered 1..4",
                  error_of([] { (void)model::parse_graph_1based("1-5", 4, "station.topology"); }).c_str());
  STRCMP_CONTAINS("'1-2x' is not a link like 1-2", error_of([] { (void)model::parse_graph_1based("1-2x", 4); }).c_str());
  STRCMP_CONTAINS("listed twice", error_of([] { (void)model::parse_graph_1based("1-2,2-1", 4); }).c_str());
  STRCMP_CONTAINS("to itself", error_of([] { (void)model::parse_graph_1based("3-3", 4); }).c_str());
  CHECK_TRUE(model::is_connected(model::parse_graph_1based("1-2,2-3,3-4", 4), 4));
  CHECK_FALSE(model::is_connected(model::parse_graph_1based("1-2,3-4", 4), 4));
  CHECK_FALSE(model::is_connected({{0, 1}, {1, 7}}, 4));
  STRCMP_CONTAINS("must connect all users", error_of([] { model::validate_graph({{0, 1}, {2, 3}}, 4, "--topology"); }).c_str());
  STRCMP_CONTAINS("no link path from user 1 reaches users 3, 4", error_of([] { model::validate_graph({{0, 1}, {2, 3}}, 4, "--topology"); }).c_str());
  STRCMP_CONTAINS("reaches user 3", error_of([] { model::validate_graph({{0, 1}, {1, 3}}, 4, "--topology"); }).c_str());
}

TEST(Model, nbar_is_the_ceiling_of_the_largest_delay_in_ticks_plus_the_loss_allowance) {
  const Eigen::MatrixXi nbar = model::index_delay_bounds_ticks(model::paper_delay_matrix_ms(), 0.5, 0.002, 1);
  CHECK_EQUAL(0, nbar(1, 1));
  CHECK_EQUAL(3 + 1, nbar(0, 1));    // 1.5 x 4 ms = 6 ms = 3 ticks
  CHECK_EQUAL(6 + 1, nbar(1, 0));    // 1.5 x 8 ms = 12 ms
  CHECK_EQUAL(180 + 1, nbar(3, 1));  // 1.5 x 240 ms
  CHECK_EQUAL(4, model::index_delay_bound_ticks(6.00001, 0.002, 0));  // just over 3 ticks
  CHECK_EQUAL(3, model::index_delay_bound_ticks(6.0, 0.002, 0));
}

TEST(Model, under_the_papers_receive_rule_nbar_adds_the_delay_spread) {
  // Independently: delays uniform in mean [0.5, 1.5] (jitter 0.5); the paper's rule adds
  // ceil((max - min) / T) + 1 = ceil(mean / T) + 1 ticks; newest-by-sequence adds nothing.
  const Eigen::MatrixXd mean = model::paper_delay_matrix_ms();
  const Eigen::MatrixXi newest = model::index_delay_bounds_ticks(mean, 0.5, 0.002, 1);
  const Eigen::MatrixXi paper = model::index_delay_bounds_ticks(mean, 0.5, 0.002, 1, rt::RxRule::kMostRecentlyReceived);
  CHECK_EQUAL(0, model::receive_rule_ticks(rt::RxRule::kNewestBySequence, 50, 150, 0.002));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (i != j) CHECK_EQUAL(newest(i, j) + static_cast<int>(std::ceil(mean(i, j) / 2.0 - 1e-9)) + 1, paper(i, j));
  CHECK_EQUAL(1, model::receive_rule_ticks(rt::RxRule::kMostRecentlyReceived, 10, 10, 0.002));  // constant delay
  CHECK_THROWS(std::invalid_argument, model::receive_rule_ticks(rt::RxRule::kMostRecentlyReceived, 20, 10, 0.002));
}

TEST(Model, burst_loss_allowance_comes_from_the_chance_of_a_run_of_losses_in_the_burst_chain) {
  // Independently, for no loss outside bursts and total loss inside: n packets in a row are all lost
  // only inside one burst: pi_bad (1 - exit)^(n - 1), pi_bad = enter / (enter + exit).
  const model::LossModel m{0.0, 0.01, 0.2, 1.0};
  const double pi_bad = 0.01 / 0.21;
  for (int n : {1, 2, 5, 20}) DOUBLES_EQUAL(pi_bad * std::pow(0.8, n - 1), model::consecutive_loss_probability(m, n), 1e-15);
  DOUBLES_EQUAL(std::pow(0.05, 4), model::consecutive_loss_probability(model::LossModel{0.05}, 4), 1e-18);  // i.i.d.
  // the allowance: smallest L with 10000 ticks x 6 links x pi_bad 0.8^L <= 1 %: L = ceil(log(1e-2 / 6e4 / pi_bad) / log 0.8)
  const int expected = static_cast<int>(std::ceil(std::log(1e-2 / 6e4 / pi_bad) / std::log(0.8) - 1e-12));
  CHECK_EQUAL(expected, model::loss_allowance_from_loss(m, 10000, 6));
  CHECK_TRUE(expected > model::loss_allowance_from_loss(0.05, 10000, 6));  // bursts need far more than the same mean loss i.i.d.
  CHECK_THROWS(std::invalid_argument, model::consecutive_loss_probability(model::LossModel{0.0, 0.01, 0.0, 1.0}, 2));
}

TEST(Model, eq18_sums_of_the_paper_star_are_what_the_simulator_builds) {
  const auto built = firmware::build_scenario(firmware::make_scenario("paper-best"));
  // (Nbar_ij + Nbar_ji) T/2 per link of the star with the loss model's allowance of 5 ticks each way
  // (20 s = 10000 ticks, 6 directed links, loss 0.05: 0.05^5 x 60000 = 0.019 > 0.01 >= 0.05^6 x 60000):
  // 1-2: 8+11, 1-3: 8+8, 1-4: 8+10.
  CHECK_EQUAL(5, built.loss_allowance_ticks);
  const double expect[4] = {53, 19, 16, 18};
  for (int i = 0; i < 4; ++i) DOUBLES_EQUAL(expect[i], built.round_trip_sum_ms[static_cast<std::size_t>(i)], 1e-12);
}

TEST(Model, loss_allowance_is_the_smallest_with_an_over_bound_chance_per_run_below_the_target) {
  CHECK_EQUAL(0, model::loss_allowance_from_loss(0.0, 1e6, 6));
  for (double p : {0.001, 0.01, 0.05, 0.2})
    for (double ticks : {1e3, 1e4, 1e5}) {
      const int L = model::loss_allowance_from_loss(p, ticks, 6);
      CHECK(ticks * 6 * std::pow(p, L + 1) <= model::kOverBoundChancePerRun);
      CHECK(L == 0 || ticks * 6 * std::pow(p, L) > model::kOverBoundChancePerRun);
    }
  CHECK_EQUAL(5, model::loss_allowance_from_loss(0.05, 10000, 6));
  CHECK_THROWS(std::invalid_argument, model::loss_allowance_from_loss(1.0, 10, 1));
}

TEST(Model, a_measured_loss_is_taken_at_the_upper_end_of_its_confidence_interval) {
  // Wilson score interval at z = 1.96, hand-computed: 0 of 100 -> z^2 / (100 + z^2) = 0.03700;
  // 5 of 100 -> 0.11175; the point estimate is inside and the bound falls towards it as the probe grows.
  DOUBLES_EQUAL(3.8416 / 103.8416, model::loss_upper_bound(0, 100), 1e-12);
  DOUBLES_EQUAL(0.111752, model::loss_upper_bound(5, 100), 1e-5);
  CHECK(model::loss_upper_bound(50, 1000) < model::loss_upper_bound(5, 100));
  CHECK(model::loss_upper_bound(50, 1000) > 0.05);
  // the allowance is the loss model's at that probability: more loss or a shorter probe, more ticks
  CHECK_EQUAL(model::loss_allowance_from_loss(model::loss_upper_bound(5, 100), 5000, 6), model::loss_allowance_from_measured_loss(5, 100, 5000, 6));
  CHECK(model::loss_allowance_from_measured_loss(5, 100, 5000, 6) > model::loss_allowance_from_measured_loss(0, 100, 5000, 6));
  CHECK(model::loss_allowance_from_measured_loss(0, 100, 5000, 6) > model::loss_allowance_from_measured_loss(0, 10000, 5000, 6));
  CHECK_EQUAL(1000, model::loss_allowance_from_measured_loss(100, 100, 5000, 6));  // everything lost: the search's cap
  CHECK_THROWS(std::invalid_argument, model::loss_upper_bound(0, 0));
  CHECK_THROWS(std::invalid_argument, model::loss_upper_bound(3, 2));
}

TEST(Model, the_probe_loss_counts_packets_missing_or_later_than_the_bound_once_the_bound_has_passed) {
  firmware::ProbeLossCounter c(2);
  for (std::uint64_t s = 10; s < 110; ++s)
    if (s % 10 != 3) c.add(0, s);  // every 10th lost
  c.add(0, 20);                     // a duplicate counts once
  c.add(-1, 50);                    // not a neighbour
  const firmware::ProbeLoss all = c.loss(0, 0);
  CHECK_EQUAL(100, all.expected);
  CHECK_EQUAL(10, all.lost);
  // the last 9 ticks may still be on their way: 10..100, of which 13, 23, .., 93 lost
  const firmware::ProbeLoss settled = c.loss(0, 9);
  CHECK_EQUAL(91, settled.expected);
  CHECK_EQUAL(9, settled.lost);
  CHECK_EQUAL(1, settled.longest_gap);
  for (std::uint64_t s = 10; s < 2010; ++s)
    if (s < 30 || s >= 42) c.add(1, s);  // a burst of 12 in 2000 (the i.i.d. model alone: L = 3)
  CHECK_EQUAL(12, c.loss(1, 0).longest_gap);
  CHECK_EQUAL(3, model::loss_allowance_from_measured_loss(12, 2000, 5000, 6));
  CHECK_EQUAL(24, firmware::round_trip_loss_allowance(c.loss(1, 0), 5000, 6));  // the burst, not the i.i.d. model's L
  firmware::ProbeLossCounter none(2);
  CHECK_EQUAL(0, none.loss(1, 0).expected);  // nothing from neighbour 1: nothing measured
  CHECK_EQUAL(-1, firmware::round_trip_loss_allowance(none.loss(1, 0), 5000, 6));
  // twice the per-direction allowance of the loss model (each direction's Nbar gets it)
  CHECK_EQUAL(2 * model::loss_allowance_from_measured_loss(10, 100, 5000, 6), firmware::round_trip_loss_allowance(all, 5000, 6));
}

TEST(Model, the_probe_loss_at_the_deadbands_pace_counts_packets_not_silent_ticks) {
  // neighbours that send every 5th tick (the deadband's pace while probing): 200 packets, 0, 5, .., 995
  firmware::ProbeLossCounter paced(1, 5);
  for (std::uint64_t s = 0; s < 1000; s += 5)
    if (s != 100 && s != 500 && s != 505 && s != 510) paced.add(0, s);  // one lost, then three in a row
  const firmware::ProbeLoss p = paced.loss(0, 0);
  CHECK_EQUAL(200, p.expected);
  CHECK_EQUAL(4, p.lost);
  CHECK_EQUAL(3, p.longest_gap);
  // the packets due by (newest - 12): 0 .. 980, 197 of them, the same 4 lost
  CHECK_EQUAL(197, paced.loss(0, 12).expected);
  CHECK_EQUAL(4, paced.loss(0, 12).lost);
  // counted tick by tick, the same silences would be 4/5 lost
  firmware::ProbeLossCounter per_tick(1);
  for (std::uint64_t s = 0; s < 1000; s += 5) per_tick.add(0, s);
  CHECK(per_tick.loss(0, 0).lost > 700);
  CHECK_EQUAL(0, firmware::ProbeLossCounter(1, 5).loss(0, 0).expected);
  // a running neighbour sends more often on a change: a gap shorter than the pace loses nothing,
  // and a silence of g ticks holds at least ceil(g / 5) - 1 lost packets
  firmware::ProbeLossCounter run(1, 5);
  for (std::uint64_t s : {0, 1, 2, 7, 12, 13, 20, 31}) run.add(0, s);
  const firmware::ProbeLoss r = run.loss(0, 0);
  CHECK_EQUAL(3, r.lost);  // 13 -> 20: ceil(7 / 5) - 1 = 1; 20 -> 31: ceil(11 / 5) - 1 = 2; the gaps of 5 and less: none
  CHECK_EQUAL(2, r.longest_gap);
  CHECK_EQUAL(11, r.expected);
}

TEST(Model, bounds_from_a_measured_round_trip_cover_the_peer_within_the_agreement_margin) {
  CHECK_EQUAL(5, model::index_guard_from_round_trip(9));
  CHECK_EQUAL(5, model::index_guard_from_round_trip(10));
  // A's assumed sum must cover its own guard + B's guard while R_B <= R_A + 2 agreement.
  for (int ra = 0; ra < 40; ++ra)
    for (int agreement = 0; agreement < 4; ++agreement)
      for (int rb = 0; rb <= ra + 2 * agreement; ++rb)
        CHECK(model::index_guard_from_round_trip(ra) + model::index_guard_from_round_trip(rb) <=
              model::assumed_round_trip_sum_ticks(ra, agreement));
}

TEST(Model, delay_matrix_parser_checks_the_shape_and_reads_inf) {
  const Eigen::MatrixXd m = model::parse_delay_matrix("[0, 4, inf]; 8,0,80; 4,100,0", "--delays");
  CHECK_EQUAL(3, m.rows());
  CHECK(std::isinf(m(0, 2)));
  STRCMP_CONTAINS("--delay-matrix needs 4 rows", error_of([] { (void)model::parse_delay_matrix("0,1;1,0", "--delay-matrix", 4); }).c_str());
  STRCMP_CONTAINS("'x' is not a number", error_of([] { (void)model::parse_delay_matrix("0,x;1,0", "--delays"); }).c_str());
  const Eigen::MatrixXi steps = model::mean_delay_steps(m, 0.002);
  CHECK_EQUAL(-1, steps(0, 2));
  CHECK_EQUAL(40, steps(1, 2));
}

// The passivity budget (firmware/model/passivity_budget.hpp): the one rule for Nbar's allowances,
// the guard, B_i and the condition, used by the scenario and the station alike.
TEST(Model, the_delay_models_allowances_are_the_loss_models_plus_the_deadbands_plus_the_clocks) {
  // paper-best: 5 % loss over 20 s (10000 ticks) on 6 directed links -> 5 ticks (0.05^6 x 60000 <= 1 %)
  const model::NbarAllowances a = model::delay_model_allowances(-1, model::LossModel{0.05}, 20.0, 0.002, 6, {}, {});
  CHECK_EQUAL(5, a.loss_ticks);
  CHECK_EQUAL(5, a.total());
  CHECK_EQUAL(2, model::delay_model_allowances(2, model::LossModel{0.05}, 20.0, 0.002, 6, {}, {}).loss_ticks);  // given
  rt::TxDeadbandConfig band;
  band.position_deadband_m = 1e-5;
  band.max_interval_ticks = 4;
  const model::NbarAllowances d = model::delay_model_allowances(0, model::LossModel{0.0}, 20.0, 0.002, 6, band, model::ClockModel{0.0005, 0, 0});
  CHECK_EQUAL(3, d.deadband_ticks);
  CHECK_EQUAL(1, d.clock_ticks);  // a late wake: at most one tick more
  CHECK_EQUAL(4, d.total());
  // with L = 5 lost in a row a forced state can be held (5 + 1) x 3 ticks more
  const model::NbarAllowances e = model::delay_model_allowances(-1, model::LossModel{0.05}, 20.0, 0.002, 6, band, {});
  CHECK_EQUAL(18, e.deadband_ticks);
  CHECK_EQUAL(5 + 18, e.total());
  CHECK_EQUAL(0, model::clock_allowance_ticks({}, 20.0, 0.002));
  // drift: 2 x 75 ppm x 10000 ticks = 1.5 -> 2 ticks
  CHECK_EQUAL(2, model::clock_allowance_ticks(model::ClockModel{0, 0, 75}, 20.0, 0.002));
}

TEST(Model, a_link_bound_from_a_measured_round_trip_adds_the_loss_and_the_deadbands_allowance_for_it_both_ways) {
  rt::TxDeadbandConfig band;
  band.position_deadband_m = 1e-5;
  band.max_interval_ticks = 3;
  // R = 10 + 4 + the deadband's (L_ij + 1) 2 + (L_ji + 1) 2 with L_ij + L_ji = 4: 10 + 4 + 12
  const model::LinkBound l = model::link_bound_from_round_trip(10, 4, band, 2);
  CHECK_EQUAL(26, l.round_trip_ticks);
  CHECK_EQUAL(13, l.guard_ticks);
  CHECK_EQUAL(28, l.assumed_sum_ticks);
  CHECK_EQUAL(10 + 2 * 2, model::link_bound_from_round_trip(10, 0, band, 2).round_trip_ticks);  // no loss: 2 (I - 1)
  CHECK_EQUAL(10, model::link_bound_from_round_trip(19, 0, {}, 0).guard_ticks);  // ceil(19 / 2)
  // the paper's receive rule: each direction adds its spread, at most the one-way guard ceil(R/2) + 1
  const model::LinkBound p = model::link_bound_from_round_trip(19, 0, {}, 0, rt::RxRule::kMostRecentlyReceived);
  CHECK_EQUAL(19 + 2 * (10 + 1), p.round_trip_ticks);
  CHECK_EQUAL(10 + (10 + 1), p.guard_ticks);
  Eigen::MatrixXi nbar(2, 2);
  nbar << 0, 7, 3, 0;
  const model::LinkBound m = model::link_bound_from_delay_model(nbar, 0, 1);
  CHECK_EQUAL(7, m.guard_ticks);
  CHECK_EQUAL(10, m.assumed_sum_ticks);
  DOUBLES_EQUAL(0.020 * 1.25 + 0.004, model::round_trip_bound_s(0.020, 0.25, 0.004), 1e-15);
}

TEST(Model, b_i_is_the_margin_over_eq18_unless_given_and_zero_under_pspm_and_the_condition_says_which) {
  const rt::EdgeGains g = rt::scalar_edge_gains(1, 1000.0, 5.0);
  const rt::EdgeGains* gains[] = {&g, &g};
  const int sums[] = {10, 20};
  const double tmax[] = {0.002, 0.002};
  const auto eq18 = rt::ConsensusPassivity::kEq18Damping, pspm = rt::ConsensusPassivity::kSetPositionModulation;
  const model::Damping d = model::damping_eq18(0.002, sums, tmax, gains, 0.05, -1, eq18);
  DOUBLES_EQUAL((10 + 20) / 2.0 * 0.002 * 1000.0, d.min_Ns_per_m, 1e-9);  // eq. (18), T^max = T^min
  DOUBLES_EQUAL(1.05 * d.min_Ns_per_m, d.used_Ns_per_m, 1e-12);
  CHECK_TRUE(d.condition_met);
  const model::Damping low = model::damping_eq18(0.002, sums, tmax, gains, 0.05, 0.5 * d.min_Ns_per_m, eq18);
  DOUBLES_EQUAL(0.5 * d.min_Ns_per_m, low.used_Ns_per_m, 0);
  CHECK_FALSE(low.condition_met);
  // exactly the minimum, rounded a little below: still met (the 1e-12 check)
  CHECK_TRUE(model::damping_eq18(0.002, sums, tmax, gains, 0, d.min_Ns_per_m * (1 - 1e-14), eq18).condition_met);
  const model::Damping p = model::damping_eq18(0.002, sums, tmax, gains, 0.05, -1, pspm);
  DOUBLES_EQUAL(0.0, p.used_Ns_per_m, 0);
  DOUBLES_EQUAL(d.min_Ns_per_m, p.min_Ns_per_m, 1e-12);  // what eq. (18) would have asked for
  CHECK_TRUE(p.condition_met);                            // eq. (14) by the modulation
  DOUBLES_EQUAL(3.0, model::damping_eq18(0.002, sums, tmax, gains, 0.05, 3.0, pspm).used_Ns_per_m, 0);
}

TEST(Model, d2_of_eq13_counts_the_copies_the_consensus_springs_and_under_pspm_the_reservoirs) {
  const rt::EdgeGains g = rt::scalar_edge_gains(2, 100.0, 5.0);  // P = 100 I on 6 dofs
  const double a[6] = {0, 0, 0, 0, 0, 0}, b[6] = {0.1, 0, 0, 0, 0.2, 0};
  DOUBLES_EQUAL(100.0 * (0.01 + 0.04) / 4.0, model::consensus_spring_J(g, a, b), 1e-12);
  DOUBLES_EQUAL(model::consensus_spring_J(g, a, b), model::consensus_spring_bound_J(g.lambda_max_P, a, b, 6), 1e-12);  // P = p I: equal
  DOUBLES_EQUAL(0.0, model::pspm_reservoirs_J(rt::ConsensusPassivity::kEq18Damping, 3, 0.002), 0);
  DOUBLES_EQUAL(2 * 3 * 0.002, model::pspm_reservoirs_J(rt::ConsensusPassivity::kSetPositionModulation, 3, 0.002), 1e-15);
  const double copies[] = {0.5, 0.25}, springs[] = {0.125};
  DOUBLES_EQUAL(0.5 + 0.25 + 0.125 + 0.012, model::eq13_d2_J(copies, springs, 0.012), 1e-15);
}

TEST(Model, eq13_is_broken_when_the_port_energy_goes_below_minus_d2_beyond_rounding_only) {
  CHECK_FALSE(model::eq13_broken(std::nullopt, 0.0));                // nothing measured: no claim
  CHECK_FALSE(model::eq13_broken(0.0, 0.0));
  CHECK_FALSE(model::eq13_broken(-0.5 * 1e-9, 0.0));                 // rounding
  CHECK_TRUE(model::eq13_broken(-2e-9, 0.0));
  CHECK_FALSE(model::eq13_broken(-0.012, 0.012));                     // at -d^2: passive
  CHECK_TRUE(model::eq13_broken(-0.012 - 1e-6, 0.012));
}

// The run metrics' quantities (firmware/model/metrics.hpp), one definition each.
TEST(Model, the_consensus_error_is_the_largest_pairwise_node_distance_and_differs_from_the_distance_to_the_mean_shape) {
  const double x0[6] = {0, 0, 0, 1, 0, 0}, x1[6] = {0, 0, 0, 1, 0, 0}, x2[6] = {0, 0, 0.3, 1, 0, 0};
  const double* copies[] = {x0, x1, x2};
  DOUBLES_EQUAL(0.3, model::consensus_error_m(copies, 2), 1e-15);
  DOUBLES_EQUAL(0.3, model::max_node_distance_m(x0, x2, 2), 1e-15);
  const auto d = model::distance_from_mean_shape_m(copies, 2);
  DOUBLES_EQUAL(0.1, d[0][0], 1e-15);  // the mean is at z = 0.1
  DOUBLES_EQUAL(0.2, d[2][0], 1e-15);
  DOUBLES_EQUAL(0.0, d[2][1], 1e-15);
  const Eigen::Vector3d m = model::mean_node_position_m(copies, 0);
  DOUBLES_EQUAL(0.1, m.z(), 1e-15);
  const double far[6] = {INFINITY, 0, 0, 0, 0, 0};
  const double* with_inf[] = {x0, far};
  CHECK_TRUE(std::isinf(model::consensus_error_m(with_inf, 2)));
}

TEST(Model, the_force_balance_is_the_norm_of_the_sum_and_the_mean_of_the_norms) {
  const Eigen::Vector3d f[] = {Eigen::Vector3d(3, 0, 0), Eigen::Vector3d(-1, 0, 0), Eigen::Vector3d(0, 4, 0)};
  const model::ForceBalance b = model::force_balance(f);
  DOUBLES_EQUAL(std::sqrt(4.0 + 16.0), b.sum_norm_N, 1e-12);
  DOUBLES_EQUAL((3 + 1 + 4) / 3.0, b.mean_norm_N, 1e-12);
  DOUBLES_EQUAL(b.sum_norm_N / b.mean_norm_N, model::force_balance_ratio(b.sum_norm_N, b.mean_norm_N), 0);
  CHECK_TRUE(std::isnan(model::force_balance_ratio(1.0, 0.0)));
  model::StationTotals t;
  for (const auto& v : f) t.add_force(v), t.add_energies(1.0, -0.5);
  DOUBLES_EQUAL(2.0, t.force_N.x(), 0);
  DOUBLES_EQUAL(3.0, t.port_J, 0);
  DOUBLES_EQUAL(-1.5, t.controller_J, 0);
}

namespace {
model::Graph complete_graph(int n) {
  model::Graph g;
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b) g.push_back({a, b});
  return g;
}
// The definition, directly: every pair of disjoint non-empty sets (3^N assignments), one of them
// r-reachable. An independent oracle for model::robustness.
int robustness_by_definition(const model::Graph& g, int n) {
  std::vector<std::vector<int>> nb(static_cast<std::size_t>(n));
  for (const auto& l : g) nb[static_cast<std::size_t>(l.a)].push_back(l.b), nb[static_cast<std::size_t>(l.b)].push_back(l.a);
  int total = 1;
  for (int i = 0; i < n; ++i) total *= 3;
  int best = n;
  std::vector<int> side(static_cast<std::size_t>(n));
  for (int code = 0; code < total; ++code) {
    int c = code, n1 = 0, n2 = 0;
    for (int i = 0; i < n; ++i, c /= 3) side[static_cast<std::size_t>(i)] = c % 3, n1 += c % 3 == 1, n2 += c % 3 == 2;
    if (n1 == 0 || n2 == 0) continue;
    int reach[3] = {0, 0, 0};
    for (int u = 0; u < n; ++u) {
      int outside = 0;
      for (int v : nb[static_cast<std::size_t>(u)]) outside += side[static_cast<std::size_t>(v)] != side[static_cast<std::size_t>(u)];
      reach[side[static_cast<std::size_t>(u)]] = std::max(reach[side[static_cast<std::size_t>(u)]], outside);
    }
    best = std::min(best, std::max(reach[1], reach[2]));
  }
  return best;
}
}  // namespace

TEST(Model, robustness_of_known_graphs_complete_is_half_rounded_up_trees_and_cycles_are_1) {
  for (int n = 2; n <= 12; ++n) CHECK_EQUAL((n + 1) / 2, model::robustness(complete_graph(n), n));
  CHECK_EQUAL(1, model::robustness(model::parse_graph_1based("1-2,1-3,1-4", 4), 4));          // the paper's star
  CHECK_EQUAL(1, model::robustness(model::parse_graph_1based("1-2,2-3,3-4,4-5,5-6", 6), 6));  // a path
  CHECK_EQUAL(1, model::robustness(model::parse_graph_1based("1-2,2-3,3-4,4-5,5-6,6-1", 6), 6));  // a cycle
  CHECK_EQUAL(0, model::robustness(model::parse_graph_1based("1-2,3-4", 4), 4));  // not connected
  // two triangles on user 1 plus a pendant pair: the witness pair {4, 5}, {2, 3, 6} leaves user 1 out,
  // so checking only splits of all users into two sets would call it 2-robust
  CHECK_EQUAL(1, model::robustness(model::parse_graph_1based("1-2,1-3,1-4,1-5,2-3,2-6,3-6,4-5", 6), 6));
  // K_5 is the smallest 3-robust graph (F = 1 under W-MSR needs at least 5 users)
  CHECK_FALSE(model::is_r_robust(complete_graph(4), 4, 3));
  CHECK_TRUE(model::is_r_robust(complete_graph(5), 5, 3));
  STRCMP_CONTAINS("lab.topology: robustness is checked exhaustively up to 20 users, not 21",
                  error_of([] { (void)model::robustness(complete_graph(21), 21, "lab.topology"); }).c_str());
}

TEST(Model, robustness_equals_the_definition_on_random_graphs_and_never_exceeds_the_least_degree) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = 2 + static_cast<int>(rng() % 6);
    const double p = 0.2 + 0.8 * static_cast<double>(rng() % 1000) / 1000.0;
    model::Graph g;
    for (int a = 0; a < n; ++a)
      for (int b = a + 1; b < n; ++b)
        if (static_cast<double>(rng() % 1000) / 1000.0 < p) g.push_back({a, b});
    const int r = model::robustness(g, n);
    CHECK_EQUAL(robustness_by_definition(g, n), r);
    std::vector<int> deg(static_cast<std::size_t>(n), 0);
    for (const auto& l : g) ++deg[static_cast<std::size_t>(l.a)], ++deg[static_cast<std::size_t>(l.b)];
    CHECK_TRUE(r <= *std::min_element(deg.begin(), deg.end()));
  }
}
