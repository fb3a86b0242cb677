// model::step_bounds / measured_step_bounds: one rule for the simulator's clock model and the real
// station's probing measurement (firmware/model/step_bounds.hpp).
#include <CppUTest/TestHarness.h>

#include "firmware/model/step_bounds.hpp"
#include "firmware/scenario.hpp"

using namespace haptic;

TEST_GROUP(StepBounds){};

TEST(StepBounds, TheClockModelsBoundsAreOneGridIntervalPlusOrMinusTheWakeDelayBound) {
  // T_k = g(k) - g(k-1) + d_k - d_{k-1}, g's interval T r (1 +- F), d in [0, J]
  const model::StepBounds b = model::step_bounds(0.002, 1.0 + 50e-6, 0.1, 0.0004);
  DOUBLES_EQUAL(0.002 * (1 + 50e-6) * 0.9 - 0.0004, b.t_min_s, 1e-15);
  DOUBLES_EQUAL(0.002 * (1 + 50e-6) * 1.1 + 0.0004, b.t_max_s, 1e-15);
  // a clock model that only shortens or lengthens still brackets the nominal period
  DOUBLES_EQUAL(0.002, model::step_bounds(0.002, 0.9, 0.0, 0.0).t_max_s, 0);
  DOUBLES_EQUAL(0.002, model::step_bounds(0.002, 1.1, 0.0, 0.0).t_min_s, 0);
}

TEST(StepBounds, TheSimulatorTakesItsClockModelsBoundsFromTheSameRule) {
  firmware::ScenarioSpec s = firmware::make_scenario("paper-best");
  s.timer_jitter_s = 0.0003;
  s.step_jitter = 0.05;
  const firmware::BuiltScenario b = firmware::build_scenario(s);
  for (int i = 0; i < s.users; ++i) {
    const model::StepBounds m = model::step_bounds(s.period_s, b.clock_rate[static_cast<std::size_t>(i)], 0.05, 0.0003);
    DOUBLES_EQUAL(m.t_min_s, b.t_min_s[static_cast<std::size_t>(i)], 0);
    DOUBLES_EQUAL(m.t_max_s, b.t_max_s[static_cast<std::size_t>(i)], 0);
  }
}

TEST(StepBounds, AStationsMeasuredBoundsAreItsWakeLatencyWithHeadroomAndNeverBeyondTheCap) {
  const double T = 0.002;
  const model::StepBounds quiet = model::measured_step_bounds(T, 100e-6, 0.2 * T);
  const double J = model::kWakeHeadroom * 100e-6 + model::kWakeFloor_s;
  DOUBLES_EQUAL(T - J, quiet.t_min_s, 1e-15);
  DOUBLES_EQUAL(T + J, quiet.t_max_s, 1e-15);
  CHECK_FALSE(quiet.capped);
  // an idle RT host: the floor keeps a margin
  CHECK(model::measured_step_bounds(T, 0.0, 0.2 * T).t_max_s >= T + model::kWakeFloor_s);
  // a starving host: capped, and said
  const model::StepBounds loaded = model::measured_step_bounds(T, 0.013, 0.2 * T);
  DOUBLES_EQUAL(0.8 * T, loaded.t_min_s, 1e-15);
  DOUBLES_EQUAL(1.2 * T, loaded.t_max_s, 1e-15);
  CHECK_TRUE(loaded.capped);
  // cap 0: the nominal period, a fixed step
  const model::StepBounds fixed = model::measured_step_bounds(T, 0.001, 0.0);
  DOUBLES_EQUAL(T, fixed.t_min_s, 0);
  DOUBLES_EQUAL(T, fixed.t_max_s, 0);
}
