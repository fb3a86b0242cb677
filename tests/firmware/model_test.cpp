// firmware/model: the one graph parser and delay model (Nbar, eq. 18 sums, bounds from measured
// round trips) that the simulator, the station and haptic-topology share.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
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
