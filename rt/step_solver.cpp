#include "rt/step_solver.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "rt/jacobi_cg.hpp"
#include "rt/sparse_ldlt.hpp"

namespace haptic::rt {

namespace {

class DirectStepSolver final : public StepSolver {
 public:
  DirectStepSolver(const SparseColMajor& A, int width)
      : F_(A), scratch_(static_cast<std::size_t>(A.rows()) * static_cast<std::size_t>(width)) {}
  Report solve(const double* b, double* x, double*, int width) override {
    const long m = static_cast<long>(F_.size()) * width;
    for (long i = 0; i < m; ++i) x[i] = b[i];
    F_.solve_in_place(x, width, scratch_.data());
    return {};
  }
  void solve_accurately(const double* b, double* x, int width) override { solve(b, x, nullptr, width); }
  bool exact() const override { return true; }
  const char* name() const override { return "direct"; }
  long stored_doubles() const override { return 2 * F_.factor_nonzeros() + static_cast<long>(scratch_.size()); }

 private:
  SparseLdlt F_;
  std::vector<double> scratch_;
};

class IterativeStepSolver final : public StepSolver {
 public:
  IterativeStepSolver(const SparseColMajor& A, int width, double tol) : cg_(A, width, tol), tol_(tol) {}
  Report solve(const double* b, double* x, double* residual, int width) override {
    const int it = cg_.solve(b, x, residual, width, tol_, cg_.iteration_cap());
    return {std::min(it, cg_.iteration_cap()), it <= cg_.iteration_cap()};
  }
  void solve_accurately(const double* b, double* x, int width) override {
    std::vector<double> r(static_cast<std::size_t>(cg_.size()) * static_cast<std::size_t>(width));
    cg_.solve(b, x, r.data(), width, 1e-15, 20 * cg_.iteration_cap() + 50);
  }
  bool exact() const override { return false; }
  const char* name() const override { return "iterative"; }
  long stored_doubles() const override { return cg_.stored_doubles(); }
  const double* inverse_diagonal() const override { return cg_.inverse_diagonal(); }
  const JacobiCg& cg() const { return cg_; }

 private:
  JacobiCg cg_;
  double tol_;
};

}  // namespace

void StepSolverConfig::validate() const {
  if (!(relative_tolerance > 0 && relative_tolerance < 1e-3))
    throw std::invalid_argument("station.solver.relative_tolerance must be in (0, 1e-3)");
  if (max_iterations_cap < 1 || max_iterations_cap > 1000)
    throw std::invalid_argument("station.solver.max_iterations_cap must be in [1, 1000]");
  if (iterative_from_rows < 0) throw std::invalid_argument("station.solver.iterative_from_rows must be >= 0");
}

std::unique_ptr<StepSolver> make_step_solver(const StepSolverConfig& c, const SparseColMajor& A, int width) {
  c.validate();
  if (c.custom) return c.custom(A, width);
  const bool want_iterative = c.kind == StepSolverKind::kIterative ||
                              (c.kind == StepSolverKind::kAuto && A.rows() >= c.iterative_from_rows);
  if (want_iterative) {
    try {
      auto s = std::make_unique<IterativeStepSolver>(A, width, c.relative_tolerance);
      if (s->cg().iteration_cap() <= c.max_iterations_cap) return s;
      if (c.kind == StepSolverKind::kIterative)
        throw std::invalid_argument("station.solver.max_iterations_cap = " + std::to_string(c.max_iterations_cap) +
                                    " is below the " + std::to_string(s->cg().iteration_cap()) +
                                    " iterations the tolerance needs for this step matrix");
    } catch (const std::invalid_argument& e) {
      if (c.kind == StepSolverKind::kIterative) throw std::invalid_argument(std::string("station.solver = \"iterative\": ") + e.what());
    }
  }
  return std::make_unique<DirectStepSolver>(A, width);
}

StepSolverKind parse_step_solver_kind(const std::string& name) {
  if (name == "auto") return StepSolverKind::kAuto;
  if (name == "direct") return StepSolverKind::kDirect;
  if (name == "iterative") return StepSolverKind::kIterative;
  throw std::invalid_argument("station.solver must be \"auto\", \"direct\" or \"iterative\" (got \"" + name + "\")");
}

}  // namespace haptic::rt
