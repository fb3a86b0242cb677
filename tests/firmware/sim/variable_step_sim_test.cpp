// Variable steps in the simulator (ScenarioSpec's clock model, rt/README.md "Variable steps"):
// eq. (18) takes T_j^max / T_i^min with its D_ij term, every station integrates over its own
// wake-to-wake step within the bounds it was built for, and bad clock options are refused by name.
#include <CppUTest/TestHarness.h>

#include <Eigen/Dense>
#include <cmath>

#include "firmware/scenario.hpp"
#include "firmware/sim/simulator.hpp"
#include "tests/support/error_of.hpp"

using namespace haptic::firmware;
using haptic::test::error_of;

TEST_GROUP(VariableStepSim){};

TEST(VariableStepSim, eq18_takes_the_step_bounds_and_the_D_term_of_the_clock_model) {
  // Independent evaluation for the paper's gains: P_ij = p[I/2 + K_int/(2 lambda_max)] and
  // D_ij = d I commute, so lambda_max of eq. (18)'s sum is sum_j [(Nbar_ij + Nbar_ji)/2 T_j^max p
  // + 1/2 (T_j^max / T_i^min - 1) d]. Dropping the D term would miss 3 x 1/2 x 0.5 x 5 = 3.75 N s/m
  // on the hub (timer jitter 0.5 ms on T = 2 ms: T_k in [1.5, 2.5] ms).
  ScenarioSpec s = make_scenario("paper-best");
  s.timer_jitter_s = 0.0005;
  const BuiltScenario b = build_scenario(s);
  for (int i = 0; i < 4; ++i) {
    DOUBLES_EQUAL(0.0015, b.t_min_s[static_cast<std::size_t>(i)], 1e-15);
    DOUBLES_EQUAL(0.0025, b.t_max_s[static_cast<std::size_t>(i)], 1e-15);
  }
  for (int i = 0; i < 4; ++i) {
    double beta = 0;
    for (int j : b.neighbors[static_cast<std::size_t>(i)]) {
      const double rt = b.nbar_ticks(i, j) + b.nbar_ticks(j, i);
      beta += rt / 2.0 * b.t_max_s[static_cast<std::size_t>(j)] * s.p_gain_N_per_m;
      beta += 0.5 * (b.t_max_s[static_cast<std::size_t>(j)] / b.t_min_s[static_cast<std::size_t>(i)] - 1.0) * s.d_gain_Ns_per_m;
    }
    DOUBLES_EQUAL(beta, b.damping_min[static_cast<std::size_t>(i)], 1e-9 * beta);
  }
  // the stations are built with the same bounds
  const auto c = b.station_config(0);
  DOUBLES_EQUAL(0.0015, c.t_min(), 1e-15);
  DOUBLES_EQUAL(0.0025, c.t_max(), 1e-15);
  // the timer's late wake adds one tick to Nbar_ij
  const BuiltScenario fixed = build_scenario(make_scenario("paper-best"));
  CHECK_EQUAL(fixed.nbar_ticks(0, 1) + 1, b.nbar_ticks(0, 1));
}

TEST(VariableStepSim, each_station_integrates_over_its_own_steps_within_its_bounds) {
  // Short paper-best runs: with timer jitter, step jitter or clock drift the steps stay inside the
  // bounds eq. (18) was computed for (nothing clamped), the run stays stable, and the result
  // differs from the lockstep run (the steps are used); without them it is the lockstep run.
  ScenarioSpec s = make_scenario("paper-best");
  s.duration_s = 4.0;
  const SimResult base = run_simulation(build_scenario(s), SimOptions{});
  const SimResult again = run_simulation(build_scenario(s), SimOptions{});
  CHECK_TRUE((base.final_x[0] - again.final_x[0]).norm() == 0.0);  // deterministic
  for (int model = 0; model < 3; ++model) {
    ScenarioSpec v = s;
    if (model == 0) v.timer_jitter_s = 0.0005;  // T^max = 2.5 ms: eq. (26) K_vc T^max = 0.5 = b_d, the most it allows
    if (model == 1) v.step_jitter = 0.2;
    if (model == 2) v.clock_drift_ppm = 2000;
    const BuiltScenario b = build_scenario(v);
    const SimResult r = run_simulation(b, SimOptions{});
    CHECK_EQUAL(0u, r.steps_clamped);
    CHECK_FALSE(r.metrics.diverged_at_s.has_value());
    CHECK_TRUE((r.final_x[1] - base.final_x[1]).norm() > 1e-9);
    CHECK_TRUE(b.passivity_condition_met);
  }
}

TEST(VariableStepSim, bad_clock_options_are_refused_naming_the_option) {
  ScenarioSpec s = make_scenario("paper-best");
  s.timer_jitter_s = 0.0011;  // T / 2 = 1 ms
  STRCMP_CONTAINS("--timer-jitter-ms must be in [0, period/2)", error_of([&] { build_scenario(s); }).c_str());
  s = make_scenario("paper-best");
  s.step_jitter = 0.6;
  STRCMP_CONTAINS("--step-jitter must be in [0, 0.5]", error_of([&] { build_scenario(s); }).c_str());
  s = make_scenario("paper-best");
  s.clock_drift_ppm = -1;
  STRCMP_CONTAINS("--clock-drift-ppm must be in [0, 10000]", error_of([&] { build_scenario(s); }).c_str());
}
