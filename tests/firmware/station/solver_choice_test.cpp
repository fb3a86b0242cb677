// The linear step's solver measured at start-up (firmware/station/solver_choice.hpp): inside its window both
// ticks are timed and the faster is used; outside it, and when a kind is forced, nothing is timed.
#include <CppUTest/TestHarness.h>

#include "firmware/station/solver_choice.hpp"
#include "tests/support/ball_station.hpp"

using namespace haptic;

using Ball = test::BallStation;

TEST_GROUP(SolverChoice){};

TEST(SolverChoice, outside_the_window_or_with_a_forced_kind_nothing_is_timed) {
  Ball small(33);  // 33 factor rows < 600 / 4: the fixed rule's direct solver
  firmware::SolverChoice c = firmware::measure_solver_choice(small.cfg);
  CHECK_FALSE(c.measured);
  CHECK(c.kind == rt::StepSolverKind::kDirect);
  Ball large(3000);  // 2945 rows > 4 x 600: the fixed rule (auto: iterative, direct if its cap is too high)
  c = firmware::measure_solver_choice(large.cfg);
  CHECK_FALSE(c.measured);
  CHECK(c.kind == rt::StepSolverKind::kAuto);
  Ball mid(1000);
  mid.cfg.solver.kind = rt::StepSolverKind::kDirect;  // forced: kept, not timed
  c = firmware::measure_solver_choice(mid.cfg);
  CHECK_FALSE(c.measured);
  CHECK(c.kind == rt::StepSolverKind::kDirect);
}

TEST(SolverChoice, inside_the_window_both_ticks_are_timed_and_the_faster_is_used) {
  Ball mid(1000);  // 1021 factor rows, inside [150, 2400]
  const firmware::SolverChoice c = firmware::measure_solver_choice(mid.cfg, 12);
  CHECK_TRUE(c.measured);
  CHECK_EQUAL(12, c.timed_ticks);
  CHECK_TRUE(c.direct_tick_us > 0 && c.iterative_tick_us > 0);
  const rt::StepSolverKind faster = c.iterative_tick_us < c.direct_tick_us ? rt::StepSolverKind::kIterative : rt::StepSolverKind::kDirect;
  CHECK(c.kind == faster);
  printf("\n  1021 nodes: direct %.1f us, iterative %.1f us per tick\n", c.direct_tick_us, c.iterative_tick_us);
}
