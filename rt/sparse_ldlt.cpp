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
  // Row-compressed copy of the same strictly-lower entries.
  rowptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  for (int r : rowidx_) ++rowptr_[static_cast<std::size_t>(r) + 1];
  for (int i = 0; i < n_; ++i) rowptr_[static_cast<std::size_t>(i) + 1] += rowptr_[static_cast<std::size_t>(i)];
  colidx_.resize(rowidx_.size());
  Lrow_.resize(rowidx_.size());
  {
    std::vector<int> fill(rowptr_.begin(), rowptr_.end() - 1);
    for (int j = 0; j < n_; ++j)
      for (int p = colptr_[static_cast<std::size_t>(j)]; p < colptr_[static_cast<std::size_t>(j) + 1]; ++p) {
        const int r = rowidx_[static_cast<std::size_t>(p)];
        const int q = fill[static_cast<std::size_t>(r)]++;
        colidx_[static_cast<std::size_t>(q)] = j;
        Lrow_[static_cast<std::size_t>(q)] = Lval_[static_cast<std::size_t>(p)];
      }
  }
  perm_.resize(static_cast<std::size_t>(n_));
  const auto& P = ldlt.permutationP();
  if (P.size() == n_) {
    for (int i = 0; i < n_; ++i) perm_[static_cast<std::size_t>(i)] = P.indices()[i];
  } else {
    for (int i = 0; i < n_; ++i) perm_[static_cast<std::size_t>(i)] = i;
  }
}

template <int W>
void SparseLdlt::solve_fixed(double* x, double* y) const {
  constexpr int w = W;
  for (int i = 0; i < n_; ++i)
    for (int c = 0; c < w; ++c) y[static_cast<long>(perm_[i]) * w + c] = x[static_cast<long>(i) * w + c];
  // L z = y, row oriented: z_i = y_i - sum_{j<i} L_ij z_j (a gather per row)
  const int* rp = rowptr_.data();
  const int* ci = colidx_.data();
  const double* lr = Lrow_.data();
  for (int i = 0; i < n_; ++i) {
    double acc[w] = {};
    for (int p = rp[i]; p < rp[i + 1]; ++p) {
      const double* yj = y + static_cast<long>(ci[p]) * w;
      for (int c = 0; c < w; ++c) acc[c] += lr[p] * yj[c];
    }
    double* yi = y + static_cast<long>(i) * w;
    for (int c = 0; c < w; ++c) yi[c] -= acc[c];
  }
  for (int i = 0; i < n_; ++i)
    for (int c = 0; c < w; ++c) y[static_cast<long>(i) * w + c] *= dinv_[static_cast<std::size_t>(i)];
  // L^T u = z, column oriented on L = row oriented on L^T: u_j = z_j - sum_{i>j} L_ij u_i
  const int* cp = colptr_.data();
  const int* ri = rowidx_.data();
  const double* lv = Lval_.data();
  for (int j = n_ - 1; j >= 0; --j) {
    double acc[w] = {};
    for (int p = cp[j]; p < cp[j + 1]; ++p) {
      const double* yi = y + static_cast<long>(ri[p]) * w;
      for (int c = 0; c < w; ++c) acc[c] += lv[p] * yi[c];
    }
    double* yj = y + static_cast<long>(j) * w;
    for (int c = 0; c < w; ++c) yj[c] -= acc[c];
  }
  for (int i = 0; i < n_; ++i)
    for (int c = 0; c < w; ++c) x[static_cast<long>(i) * w + c] = y[static_cast<long>(perm_[i]) * w + c];
}

void SparseLdlt::solve_in_place(double* x, int width, double* y) const {
  switch (width) {
    case 1:
      solve_fixed<1>(x, y);
      break;
    case 3:
      solve_fixed<3>(x, y);
      break;
    default:  // not used by the station; keep a correct generic path
      for (int c = 0; c < width; ++c) {
        for (int i = 0; i < n_; ++i) y[i] = x[static_cast<long>(i) * width + c];
        solve_fixed<1>(y, y + n_);
        for (int i = 0; i < n_; ++i) x[static_cast<long>(i) * width + c] = y[i];
      }
  }
}

}  // namespace haptic::rt
