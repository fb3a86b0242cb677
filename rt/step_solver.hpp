#pragma once
// The linear step's solver A x = b (DESIGN.md, "The linear step"), chosen by scene size:
//  - direct: the start-up sparse LDL^T (rt/sparse_ldlt), exact to roundoff; best for small scenes;
//  - iterative: Jacobi-preconditioned conjugate gradients (rt/jacobi_cg), warm-started from the
//    previous tick, to a stated relative tolerance with an iteration cap proven sufficient at
//    start-up from the matrix's Gershgorin bounds (bounded work per tick). The step matrix is
//    nearly the identity after Jacobi scaling (condition number ~1.03 for the paper's gains), so a
//    handful of iterations reach 1e-8 (the default tolerance). Its residual r = b - A x is returned so the station can
//    count the energy it injects (-x^T r T) in its energy monitor.
// A is constant for a station (rt/README.md, "One matrix at any degree"): one solver per station.
#include <functional>
#include <memory>
#include <string>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

class StepSolver {
 public:
  virtual ~StepSolver() = default;
  struct Report {
    int iterations = 0;      // 0 for a direct solve
    bool converged = true;   // false: stopped at the iteration cap above the tolerance
  };
  // x := A^{-1} b for `width` interleaved right-hand sides (x[row*width + col]). On entry x holds an
  // initial guess (used by iterative solvers). When !exact(), residual (same size) receives
  // b - A x; a direct solver leaves it untouched. RT-safe: no allocation, bounded work.
  virtual Report solve(const double* b, double* x, double* residual, int width) = 0;
  // Start-up only: the same solve to the best accuracy the method reaches (contact Schur data).
  virtual void solve_accurately(const double* b, double* x, int width) = 0;
  virtual bool exact() const = 0;
  virtual const char* name() const = 0;
  virtual long stored_doubles() const = 0;  // size of the solver's data (memory reports)
  // The inverse of A's diagonal (one value per factor row, shared by the `width` columns) if the
  // solver keeps it (Jacobi-preconditioned CG), else nullptr: the station's warm start uses it for
  // a Jacobi step on its extrapolated guess (rt/README.md, "Solver by size").
  virtual const double* inverse_diagonal() const { return nullptr; }
};

enum class StepSolverKind { kAuto, kDirect, kIterative };

// Builds a solver for A (its factor dimension, width 3 or 1 right-hand sides). Start-up only.
using StepSolverFactory = std::function<std::unique_ptr<StepSolver>(const SparseColMajor& A, int width)>;

struct StepSolverConfig {
  StepSolverKind kind = StepSolverKind::kAuto;
  // kAuto: iterative from this many factor rows (nodes for the isotropic case) when the proven
  // iteration cap is at most max_iterations_cap; direct below (bench-rt-tick: direct is faster at
  // 275 nodes, PCG at 1021).
  int iterative_from_rows = 600;
  // ||b - A x||_2 <= tol ||b||_2 for the iterative solver. 1e-8 (rt/README.md, "Solver by size"):
  // the chart tools/bench/results/rt_tick_tolerance.png puts the residual's energy at <= 1e-9 of
  // the controller port's per tick at 1021-9915 nodes (counted in the energy monitor in any case),
  // one CG iteration per tick fewer than 1e-10.
  double relative_tolerance = 1e-8;
  int max_iterations_cap = 40;        // refuse (kIterative) or fall back (kAuto) above this
  StepSolverFactory custom;           // if set, used instead (benchmark baselines)
  void validate() const;              // throws std::invalid_argument naming the key (station.solver.*)
};

// Start-up: the solver the configuration asks for. Throws if kIterative cannot meet the
// tolerance within max_iterations_cap by the Gershgorin bound.
std::unique_ptr<StepSolver> make_step_solver(const StepSolverConfig& config, const SparseColMajor& A, int width);

// Start-up: the configuration key's value for the solver kind ("auto", "direct", "iterative").
StepSolverKind parse_step_solver_kind(const std::string& name);

}  // namespace haptic::rt
