#pragma once
// Precomputed sparse LDL^T factorization with an allocation-free solve for the tick.
// The factorization (AMD ordering + simplicial LDL^T, Eigen) runs once at start-up; the
// factors are copied into flat arrays that the tick only reads. solve_in_place() handles
// `width` interleaved right-hand sides (3 for an isotropic S (x) I3 system).
#include <vector>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

class SparseLdlt {
 public:
  SparseLdlt() = default;
  // Factor a symmetric positive-definite matrix. Throws std::runtime_error if it is not.
  explicit SparseLdlt(const SparseColMajor& A);

  int size() const { return n_; }
  long factor_nonzeros() const { return static_cast<long>(Lval_.size()); }
  // x (size()*width, interleaved: x[row*width + col]) := A^{-1} x. `scratch` must hold
  // size()*width doubles. RT-safe: no allocation, bounded O(nnz(L) * width) work.
  void solve_in_place(double* x, int width, double* scratch) const;

 private:
  int n_ = 0;
  template <int W>
  void solve_fixed(double* x, double* y) const;
  std::vector<int> colptr_, rowidx_;
  std::vector<double> Lval_;  // strictly lower part of unit-lower L, column-compressed (for L^T)
  std::vector<int> rowptr_, colidx_;
  std::vector<double> Lrow_;  // the same entries row-compressed (for L): both solves gather
  std::vector<double> dinv_;
  std::vector<int> perm_;  // y = P b  <=>  y[perm_[i]] = b[i]
};

}  // namespace haptic::rt
