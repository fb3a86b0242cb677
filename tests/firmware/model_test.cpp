// firmware/model: the one graph parser and delay model (Nbar, eq. 18 sums, bounds from measured
// round trips) that the simulator, the station and haptic-topology share.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
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
