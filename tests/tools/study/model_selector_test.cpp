// The model selector (tools/study/model_selector.hpp) and the study's test problem across a mesh family.
#include <CppUTest/TestHarness.h>

#include <cmath>

#include "tools/study/model_selector.hpp"
#include "tools/study/study.hpp"

using namespace haptic;
using namespace haptic::rt;
using namespace haptic::study;

TEST_GROUP(ModelSelector){};

TEST(ModelSelector, picks_the_cheapest_candidate_meeting_the_accuracy) {
  const std::vector<ModelCandidate> c = {{"mesh", 33, 0, 0.002, 0.08, 1.0},
                                         {"mesh", 100, 0, 0.002, 0.03, 3.0},
                                         {"mesh", 300, 0, 0.002, 0.004, 10.0},
                                         {"mesh", 1000, 0, 0.002, 0.0, 40.0}};
  auto s = select_model(c, 0.05);
  CHECK_TRUE(s.found);
  LONGS_EQUAL(100, s.chosen.nodes);
  LONGS_EQUAL(1000, s.reference.nodes);
  DOUBLES_EQUAL(40.0 / 3.0, s.cost_saving_factor, 1e-12);
  LONGS_EQUAL(300, select_model(c, 0.01).chosen.nodes);
  LONGS_EQUAL(33, select_model(c, 0.1).chosen.nodes);
  CHECK_FALSE(select_model(c, 0.05, {"modal"}).found);
  CHECK_THROWS(std::invalid_argument, select_model(c, 0.0));
}

TEST(ModelSelector, a_looser_tolerance_picks_a_smaller_mesh_of_the_real_problem) {
  // Mesh family 33 / 100 / 250 against the 250-node exact solution, NPMI at the station's 2 ms;
  // cost proxy: nodes (the step is O(nnz) in the node count).
  PushProblemParams params;
  const auto ref = study::make_exact_case(250, params, 1.0, 0.008, false);
  std::vector<ModelCandidate> cands;
  for (int n : {33, 100, 250}) {
    const auto c = n == 250 ? ref : study::make_exact_case(n, params, 1.0, 0.008, false);
    const auto e = study::run_full(c, Integrator::kNpmi, 0.002, &ref);
    cands.push_back({"mesh", n, 0, 0.002, e.force_error_ref, static_cast<double>(c.problem.model.nodes)});
  }
  CHECK_TRUE(cands[2].force_error < 0.01);  // the reference itself: integration error only
  const auto tight = select_model(cands, 0.005), loose = select_model(cands, 0.2);
  CHECK_TRUE(tight.found && loose.found);
  CHECK_TRUE(loose.chosen.nodes < tight.chosen.nodes);
  LONGS_EQUAL(33, loose.chosen.nodes);
  CHECK_TRUE(loose.cost_saving_factor > 2.0);
}

TEST(ModelSelector, push_problem_keeps_mass_and_refuses_bad_parameters) {
  PushProblemParams params;
  for (int n : {33, 200}) {
    const auto p = make_push_problem(make_ball_mesh(n, 0.05), params);
    DOUBLES_EQUAL(params.total_mass_kg, p.model.node_mass_kg * p.model.nodes, 1e-12);
    CHECK_TRUE(p.contact_nodes.size() >= 3 && p.support_nodes.size() >= 3);
    // Felt force at rest = 0; full push with a rigid ball would be contact_stiffness * depth.
    DOUBLES_EQUAL(0.0, p.felt_force(0.0, 0.0), 1e-15);
  }
  params.cap_radius_m = 0.5;
  CHECK_THROWS(std::invalid_argument, make_push_problem(make_ball_mesh(33, 0.05), params));
}
