#pragma once
// The linear step's solver measured, not guessed: on the machine that runs the station, at start-up
// (build phase, off the RT thread), both solvers' ticks are timed on this station's own matrix and the
// faster one is used (station.solver = "auto"). Timing decides, so this is for the real station only:
// the simulator and "auto-fixed" keep rt's fixed size rule (StepSolverConfig::iterative_from_rows), so
// their results never depend on the machine's load. The choice is an explicit kind in the core's
// configuration: a session log records it and a replay uses it (bit-exact). Not RT-safe (allocates,
// builds two cores, reads the clock).
#include <string>

#include "rt/station.hpp"

namespace haptic::firmware {

struct SolverChoice {
  rt::StepSolverKind kind = rt::StepSolverKind::kAuto;  // what the core is built with
  bool measured = false;     // false: the fixed rule (outside the window below, or not asked)
  double direct_tick_us = 0;     // medians over the alternated timed ticks (measured only)
  double iterative_tick_us = 0;
  int timed_ticks = 0;           // per solver
  std::string note;              // why it was (not) measured
};

// Factor rows (nodes when the matrices are isotropic) within [rows/4, 4 rows] of
// config.solver.iterative_from_rows are measured; below and above the fixed rule's answer is kept
// (one solver is then several times faster: a start-up check would only cost time and memory).
// `ticks` ticks per solver, alternated one by one (direct, iterative, ...), after 10 untimed ones,
// with the neighbours sending a smoothly moving copy of the object (b changes every tick, as in a
// run). config.solver.kind must be kAuto; a failure to build the iterative solver keeps the direct.
SolverChoice measure_solver_choice(const rt::StationConfig& config, int ticks = 40);

}  // namespace haptic::firmware
