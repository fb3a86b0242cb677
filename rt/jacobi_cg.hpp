#pragma once
// Jacobi-preconditioned conjugate gradients for the step matrix A (symmetric positive definite),
// with `width` (1 or 3) interleaved right-hand sides solved as independent systems sharing each
// sparse matrix pass. Allocation-free after construction.
//
// Storage: A's diagonal plus its STRICT UPPER triangle in compressed rows with 16-bit column
// offsets j - i (value 8 B + offset 2 B per stored entry; at 9915 nodes 0.75 MB a pass instead of
// the full rows' 1.67 MB). Row i of a pass gathers sum_{j>i} a_ij x_j and scatters a_ij x_i into
// the partial sums of the rows j - i <= band ahead (a sliding window of slots, zeroed a band ahead,
// that stays in cache), so (A x)_i is final when row i is done and
// row-local work (r, p, dot products) fuses into the pass.
// A pass adds row i's terms in ascending column order, as the full rows do: for an exactly
// symmetric A the results are the full product's bits. When an offset does not fit in 16 bits the
// full rows with 32-bit columns are kept and used instead.
//
// Iteration cap: with the Jacobi-scaled matrix's eigenvalues in [lo, hi] (Gershgorin discs,
// computed at construction), kappa = hi/lo and rho = (sqrt(kappa)-1)/(sqrt(kappa)+1), PCG's error
// obeys |e_k|_A <= 2 rho^k |e_0|_A, hence |r_k|_2 <= 2 sqrt(kappa_A) rho^k |r_0|_2 with kappa_A
// Gershgorin's bound on A itself. iteration_cap() is the smallest k making that factor <= the
// tolerance (relative to r_0; the stop test is relative to b).
#include <cstdint>
#include <vector>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

class JacobiCg {
 public:
  // Start-up: copies A (diagonal + strict upper triangle, or the full rows when the band exceeds
  // 16-bit offsets), computes the Jacobi scaling and the Gershgorin bounds. Throws
  // std::invalid_argument if A is not square, not symmetric (to 1e-12 of an entry's size) or not
  // Gershgorin-positive after scaling.
  JacobiCg(const SparseColMajor& A, int width, double relative_tolerance);

  int size() const { return n_; }
  double condition_bound() const { return kappa_scaled_; }  // Gershgorin bound after Jacobi scaling
  int iteration_cap() const { return cap_; }
  long stored_doubles() const;
  // True when A is stored as diagonal + strict upper triangle with 16-bit offsets; band() is then
  // the largest j - i of a stored entry.
  bool upper_storage() const { return upper_; }
  int band() const { return band_; }
  const double* inverse_diagonal() const { return dinv_.data(); }  // 1 / A_ii, size()
  // The upper storage's passes run an AVX build (4 lanes a row) when the CPU has AVX; it gives the
  // same results bit for bit. Tests: false forces the scalar build; returns whether AVX is used.
  bool use_avx(bool allow);
  // x (guess in, solution out), residual := b - A x. Stops when sum_c |r_c|^2 <= tol^2 |b|^2 or
  // after max_iterations. Returns the iterations done (max_iterations + 1 if not converged).
  // RT-safe: no allocation, at most max_iterations + 1 matrix passes. Not for concurrent calls on
  // one object (the passes use its work vectors).
  int solve(const double* b, double* x, double* residual, int width, double tol, int max_iterations);
  // y := A x (width interleaved columns). RT-safe; x and y must not overlap.
  void multiply(const double* x, double* y, int width) const;

 private:
  void store_rows(const SparseRowMajor& R, int band, long upper_entries);  // start-up
  template <int W, class RowDone>
  RowDone pass(const double* x, RowDone row_done);
  template <int W>
  void multiply_fixed(const double* x, double* y) const;
  template <int W>
  void update_xr(double* x, double* r, const double* alpha, double* rz_new, double* rrc) const;
  template <int W>
  void update_p(const double* r, const double* beta);
  template <int W>
  int solve_fixed(const double* b, double* x, double* r, double tol, int max_iterations);
  int n_ = 0;
  bool upper_ = false;
  bool avx_ = false;
  int band_ = 0;
  std::vector<int> rowptr_;                 // upper: strict-upper rows; else full rows
  std::vector<std::uint16_t> offset_;       // upper: j - i
  std::vector<int> colidx_;                 // full rows only
  std::vector<double> val_, diag_, dinv_;   // diag_ used by the upper storage only
  std::vector<double> window_;  // upper: the passes' partial sums, (chunk + band + 1) * 4
  int window_chunk_ = 0;
  std::vector<double> p_, q_;  // work vectors, n * 3
  double kappa_scaled_ = 1, kappa_a_ = 1;
  int cap_ = 1;
};

}  // namespace haptic::rt
