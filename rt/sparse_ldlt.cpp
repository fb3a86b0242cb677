#include "rt/sparse_ldlt.hpp"

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <cstring>
#include <stdexcept>

namespace haptic::rt {

SparseLdlt::SparseLdlt(const SparseColMajor& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("SparseLdlt: matrix is not square");
  Eigen::SimplicialLDLT<SparseColMajor, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(A);
  if (ldlt.info() != Eigen::Success) throw std::runtime_error("SparseLdlt: factorization failed");
  const auto& d = ldlt.vectorD();
  for (Eigen::Index i = 0; i < d.size(); ++i)
    if (!(d[i] > 0.0)) throw std::runtime_error("SparseLdlt: matrix is not positive definite");
  n_ = static_cast<int>(A.rows());
  const SparseColMajor& L = ldlt.matrixL().nestedExpression();
  colptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  for (int j = 0; j < n_; ++j) {
    for (SparseColMajor::InnerIterator it(L, j); it; ++it) {
      if (it.row() > j) {
        rowidx_.push_back(static_cast<int>(it.row()));
        Lval_.push_back(it.value());
      }
    }
    colptr_[static_cast<std::size_t>(j) + 1] = static_cast<int>(rowidx_.size());
  }
  dinv_.resize(static_cast<std::size_t>(n_));
  for (int i = 0; i < n_; ++i) dinv_[static_cast<std::size_t>(i)] = 1.0 / d[i];
  perm_.resize(static_cast<std::size_t>(n_));
  const auto& P = ldlt.permutationP();
  if (P.size() == n_) {
    for (int i = 0; i < n_; ++i) perm_[static_cast<std::size_t>(i)] = P.indices()[i];
  } else {
    for (int i = 0; i < n_; ++i) perm_[static_cast<std::size_t>(i)] = i;
  }
}

void SparseLdlt::solve_in_place(double* x, int width, double* y) const {
  const int w = width;
  // y = P x
  for (int i = 0; i < n_; ++i) std::memcpy(y + static_cast<long>(perm_[i]) * w, x + static_cast<long>(i) * w, sizeof(double) * w);
  const int* cp = colptr_.data();
  const int* ri = rowidx_.data();
  const double* lv = Lval_.data();
  // L z = y (unit lower, column oriented)
  for (int j = 0; j < n_; ++j) {
    const double* yj = y + static_cast<long>(j) * w;
    for (int p = cp[j]; p < cp[j + 1]; ++p) {
      double* yi = y + static_cast<long>(ri[p]) * w;
      for (int c = 0; c < w; ++c) yi[c] -= lv[p] * yj[c];
    }
  }
  for (int j = 0; j < n_; ++j)
    for (int c = 0; c < w; ++c) y[static_cast<long>(j) * w + c] *= dinv_[j];
  // L^T u = z
  for (int j = n_ - 1; j >= 0; --j) {
    double* yj = y + static_cast<long>(j) * w;
    for (int p = cp[j]; p < cp[j + 1]; ++p) {
      const double* yi = y + static_cast<long>(ri[p]) * w;
      for (int c = 0; c < w; ++c) yj[c] -= lv[p] * yi[c];
    }
  }
  // x = P^{-1} y
  for (int i = 0; i < n_; ++i) std::memcpy(x + static_cast<long>(i) * w, y + static_cast<long>(perm_[i]) * w, sizeof(double) * w);
}

}  // namespace haptic::rt
