// Scenario definitions and their argument parsers: clear errors for bad input.
#include <CppUTest/TestHarness.h>

#include <string>

#include "firmware/scenario.hpp"
#include "tests/support/error_of.hpp"

using namespace haptic::firmware;

using haptic::test::error_of;

TEST_GROUP(Scenario){};

TEST(Scenario, paper_scenarios_match_section_v) {
  for (const auto& name : scenario_names()) {
    if (name.rfind("paper-", 0) != 0) continue;  // eq18-binds: theorem1_closed_loop_test.cpp
    const auto s = make_scenario(name);
    CHECK_EQUAL(4, s.users);
    CHECK_EQUAL(3u, s.topology.size());
    DOUBLES_EQUAL(240.0, s.delay_ms(3, 1), 0);
    DOUBLES_EQUAL(0.05, s.loss_probability, 0);
    DOUBLES_EQUAL(0.01, s.duplicate_probability, 0);
  }
  const auto u = make_scenario("paper-unstable");
  CHECK_TRUE(u.damping_Ns_per_m.has_value());
  const auto b = build_scenario(u);
  CHECK_FALSE(b.passivity_condition_met);  // Fig. 10's damping is below eq. (18)
}

TEST(Scenario, contact_meshes_are_symmetric_so_a_steady_hold_exists) {
  const auto b = build_scenario(make_scenario("paper-best"));
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& d : b.push_direction) sum += d;
  CHECK_TRUE(sum.norm() < 1e-9);
  CHECK_EQUAL(33, b.scene.nodes);
}

TEST(Scenario, parsers_reject_bad_input_with_a_clear_message) {
  STRCMP_CONTAINS("unknown scenario 'x' (valid: paper-best", error_of([] { make_scenario("x"); }).c_str());
  STRCMP_CONTAINS("1..4", error_of([] { haptic::model::parse_graph_1based("1-5", 4, "--topology"); }).c_str());
  STRCMP_CONTAINS("not a link like 1-2", error_of([] { haptic::model::parse_graph_1based("12", 4, "--topology"); }).c_str());
  STRCMP_CONTAINS("needs 4 rows", error_of([] { haptic::model::parse_delay_matrix("0,1;1,0", "--delay-matrix", 4); }).c_str());
  STRCMP_CONTAINS("row 2 needs 2 values", error_of([] { haptic::model::parse_delay_matrix("0,1;1", "--delay-matrix", 2); }).c_str());
  STRCMP_CONTAINS("not a number", error_of([] { parse_list("1,x", "--damping"); }).c_str());
  auto s = make_scenario("paper-best");
  s.topology = {{0, 1}, {2, 3}};
  STRCMP_CONTAINS("connect all users", error_of([&] { s.validate(); }).c_str());
  s = make_scenario("paper-best");
  s.topology = {{0, 1}, {1, 0}, {0, 2}, {0, 3}};
  STRCMP_CONTAINS("listed twice", error_of([&] { s.validate(); }).c_str());
  s = make_scenario("paper-best");
  s.delay_ms(1, 2) = -3;
  STRCMP_CONTAINS("--delay-matrix entries", error_of([&] { s.validate(); }).c_str());
  s = make_scenario("paper-best");
  s.loss_probability = 1.0;
  STRCMP_CONTAINS("loss_probability", error_of([&] { s.validate(); }).c_str());
}

// haptic-station solo: one user, no link; eq. (18) over no neighbour gives B_i = 0 (the budget's rule,
// not a constant written here); the anchor is the scene's ground spring; a lone user with a link is refused.
TEST(Scenario, solo_is_one_user_without_links_and_eq18_gives_no_damping) {
  ScenarioSpec s = make_scenario("paper-unstable");  // a scenario with fixed B_i per user: solo drops them
  make_solo(s, 2.0);
  const BuiltScenario b = build_scenario(s);
  CHECK_EQUAL(1, b.spec.users);
  CHECK_EQUAL(0u, b.neighbors[0].size());
  DOUBLES_EQUAL(0.0, b.damping_min[0], 0);
  DOUBLES_EQUAL(0.0, b.damping[0], 0);
  CHECK_TRUE(b.passivity_condition_met);
  DOUBLES_EQUAL(2.0, b.scene.params.ground_stiffness_N_per_m, 0);
  CHECK_TRUE(b.spec.script.kind == UserScriptSpec::Kind::kRandom);
  CHECK_EQUAL(0, b.station_config(0).neighbors.size());
  ScenarioSpec linked = s;
  linked.topology = {{0, 1}};
  STRCMP_CONTAINS("a single user has no links", error_of([&] { linked.validate(); }).c_str());
  STRCMP_CONTAINS("--anchor = -1", error_of([&] { ScenarioSpec t = make_scenario("paper-best"); make_solo(t, -1); }).c_str());
}
