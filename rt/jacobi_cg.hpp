#pragma once
// Jacobi-preconditioned conjugate gradients for the step matrix A (symmetric positive definite),
// with `width` (1 or 3) interleaved right-hand sides solved as independent systems sharing each
// sparse matrix pass. Allocation-free after construction.
//
// Iteration cap: with the Jacobi-scaled matrix's eigenvalues in [lo, hi] (Gershgorin discs,
// computed at construction), kappa = hi/lo and rho = (sqrt(kappa)-1)/(sqrt(kappa)+1), PCG's error
// obeys |e_k|_A <= 2 rho^k |e_0|_A, hence |r_k|_2 <= 2 sqrt(kappa_A) rho^k |r_0|_2 with kappa_A
// Gershgorin's bound on A itself. iteration_cap() is the smallest k making that factor <= the
// tolerance (relative to r_0; the stop test is relative to b).
#include <vector>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

class JacobiCg {
 public:
  // Start-up: copies A (compressed rows), computes the Jacobi scaling and the Gershgorin bounds.
  // Throws std::invalid_argument if A is not square or not Gershgorin-positive after scaling.
  JacobiCg(const SparseColMajor& A, int width, double relative_tolerance);

  int size() const { return n_; }
  double condition_bound() const { return kappa_scaled_; }  // Gershgorin bound after Jacobi scaling
  int iteration_cap() const { return cap_; }
  long stored_doubles() const;
  const double* inverse_diagonal() const { return dinv_.data(); }  // 1 / A_ii, size()
  // x (guess in, solution out), residual := b - A x. Stops when sum_c |r_c|^2 <= tol^2 |b|^2 or
  // after max_iterations. Returns the iterations done (max_iterations + 1 if not converged).
  // RT-safe: no allocation, at most max_iterations + 1 matrix passes.
  int solve(const double* b, double* x, double* residual, int width, double tol, int max_iterations);
  // y := A x (width interleaved columns). RT-safe.
  void multiply(const double* x, double* y, int width) const;

 private:
  template <int W>
  int solve_fixed(const double* b, double* x, double* r, double tol, int max_iterations);
  template <int W>
  void multiply_fixed(const double* x, double* y) const;
  int n_ = 0;
  std::vector<int> rowptr_, colidx_;
  std::vector<double> val_, dinv_;
  std::vector<double> p_, q_;  // work vectors, n * 3
  double kappa_scaled_ = 1, kappa_a_ = 1;
  int cap_ = 1;
};

}  // namespace haptic::rt
