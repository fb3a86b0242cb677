#include "rt/jacobi_cg.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace haptic::rt {

JacobiCg::JacobiCg(const SparseColMajor& A, int width, double relative_tolerance) {
  if (A.rows() != A.cols()) throw std::invalid_argument("JacobiCg: matrix is not square");
  if (width != 1 && width != 3) throw std::invalid_argument("JacobiCg: width must be 1 or 3");
  if (!(relative_tolerance > 0 && relative_tolerance < 1)) throw std::invalid_argument("JacobiCg: tolerance must be in (0, 1)");
  n_ = static_cast<int>(A.rows());
  const SparseRowMajor R(A);  // symmetric: rows of A
  rowptr_.assign(R.outerIndexPtr(), R.outerIndexPtr() + n_ + 1);
  colidx_.assign(R.innerIndexPtr(), R.innerIndexPtr() + R.nonZeros());
  val_.assign(R.valuePtr(), R.valuePtr() + R.nonZeros());
  dinv_.assign(static_cast<std::size_t>(n_), 0.0);
  std::vector<double> diag(static_cast<std::size_t>(n_), 0.0);
  for (int i = 0; i < n_; ++i)
    for (int p = rowptr_[static_cast<std::size_t>(i)]; p < rowptr_[static_cast<std::size_t>(i) + 1]; ++p)
      if (colidx_[static_cast<std::size_t>(p)] == i) diag[static_cast<std::size_t>(i)] += val_[static_cast<std::size_t>(p)];
  for (int i = 0; i < n_; ++i) {
    if (!(diag[static_cast<std::size_t>(i)] > 0)) throw std::invalid_argument("JacobiCg: non-positive diagonal");
    dinv_[static_cast<std::size_t>(i)] = 1.0 / diag[static_cast<std::size_t>(i)];
  }
  // Gershgorin discs of D^{-1/2} A D^{-1/2} (unit diagonal) and of A.
  double radius_scaled = 0, lo_a = INFINITY, hi_a = 0;
  for (int i = 0; i < n_; ++i) {
    double rs = 0, ra = 0;
    for (int p = rowptr_[static_cast<std::size_t>(i)]; p < rowptr_[static_cast<std::size_t>(i) + 1]; ++p) {
      const int j = colidx_[static_cast<std::size_t>(p)];
      if (j == i) continue;
      const double a = std::abs(val_[static_cast<std::size_t>(p)]);
      ra += a;
      rs += a / std::sqrt(diag[static_cast<std::size_t>(i)] * diag[static_cast<std::size_t>(j)]);
    }
    radius_scaled = std::max(radius_scaled, rs);
    lo_a = std::min(lo_a, diag[static_cast<std::size_t>(i)] - ra);
    hi_a = std::max(hi_a, diag[static_cast<std::size_t>(i)] + ra);
  }
  if (!(radius_scaled < 1) || !(lo_a > 0))
    throw std::invalid_argument("JacobiCg: matrix is not diagonally dominant enough for a proven iteration cap");
  kappa_scaled_ = (1 + radius_scaled) / (1 - radius_scaled);
  kappa_a_ = hi_a / lo_a;
  const double sk = std::sqrt(kappa_scaled_);
  const double rho = (sk - 1) / (sk + 1);
  const double need = relative_tolerance / (2 * std::sqrt(kappa_a_));
  cap_ = rho <= 0 ? 1 : std::max(1, static_cast<int>(std::ceil(std::log(need) / std::log(rho))));
  const auto w = static_cast<std::size_t>(n_) * 3;
  p_.assign(w, 0.0);
  q_.assign(w, 0.0);
}

long JacobiCg::stored_doubles() const {
  return static_cast<long>(val_.size() + dinv_.size() + p_.size() + q_.size()) +
         static_cast<long>(rowptr_.size() + colidx_.size()) / 2;
}

template <int W>
void JacobiCg::multiply_fixed(const double* x, double* y) const {
  const int* rp = rowptr_.data();
  const int* ci = colidx_.data();
  const double* v = val_.data();
  for (int i = 0; i < n_; ++i) {
    double acc[W] = {};
    for (int p = rp[i]; p < rp[i + 1]; ++p) {
      const double a = v[p];
      const double* xj = x + static_cast<long>(ci[p]) * W;
      for (int c = 0; c < W; ++c) acc[c] += a * xj[c];
    }
    for (int c = 0; c < W; ++c) y[static_cast<long>(i) * W + c] = acc[c];
  }
}

void JacobiCg::multiply(const double* x, double* y, int width) const {
  if (width == 3)
    multiply_fixed<3>(x, y);
  else
    multiply_fixed<1>(x, y);
}

// Preconditioned CG (Saad, Alg. 9.1) run on W independent systems; one matrix pass per iteration
// with the p.q products accumulated in it, z = D^{-1} r never stored (three vector passes); the
// initial residual is formed in the initial matvec's pass.
template <int W>
int JacobiCg::solve_fixed(const double* b, double* x, double* r, double tol, int max_iterations) {
  double* p = p_.data();
  double* q = q_.data();
  const double* dinv = dinv_.data();
  const int* rp = rowptr_.data();
  const int* ci = colidx_.data();
  const double* av = val_.data();
  // r = b - A x, p = z = D^{-1} r and the products, in the initial matvec's pass (row-local).
  double bb = 0, rr = 0;
  double rz[W] = {};
  for (int i = 0; i < n_; ++i) {
    double acc[W] = {};
    for (int e = rp[i]; e < rp[i + 1]; ++e) {
      const double a = av[e];
      const double* xj = x + static_cast<long>(ci[e]) * W;
      for (int c = 0; c < W; ++c) acc[c] += a * xj[c];
    }
    for (int c = 0; c < W; ++c) {
      const long k = static_cast<long>(i) * W + c;
      r[k] = b[k] - acc[c];
      p[k] = dinv[i] * r[k];
      bb += b[k] * b[k];
      rr += r[k] * r[k];
      rz[c] += r[k] * p[k];
    }
  }
  const double threshold = tol * tol * bb;
  int it = 0;
  while (rr > threshold) {
    if (it == max_iterations) return max_iterations + 1;
    ++it;
    double pq[W] = {};
    for (int i = 0; i < n_; ++i) {  // q = A p, pq = p.q
      double acc[W] = {};
      for (int e = rp[i]; e < rp[i + 1]; ++e) {
        const double a = av[e];
        const double* pj = p + static_cast<long>(ci[e]) * W;
        for (int c = 0; c < W; ++c) acc[c] += a * pj[c];
      }
      const long k = static_cast<long>(i) * W;
      for (int c = 0; c < W; ++c) {
        q[k + c] = acc[c];
        pq[c] += p[k + c] * acc[c];
      }
    }
    double alpha[W];
    for (int c = 0; c < W; ++c) alpha[c] = pq[c] > 0 ? rz[c] / pq[c] : 0.0;
    double rz_new[W] = {};
    rr = 0;
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < W; ++c) {
        const long k = static_cast<long>(i) * W + c;
        x[k] += alpha[c] * p[k];
        r[k] -= alpha[c] * q[k];
        rz_new[c] += r[k] * r[k] * dinv[i];
        rr += r[k] * r[k];
      }
    if (rr <= threshold) break;  // converged: the next direction is not needed
    double beta[W];
    for (int c = 0; c < W; ++c) {
      beta[c] = rz[c] > 0 ? rz_new[c] / rz[c] : 0.0;
      rz[c] = rz_new[c];
    }
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < W; ++c) {
        const long k = static_cast<long>(i) * W + c;
        p[k] = dinv[i] * r[k] + beta[c] * p[k];
      }
  }
  return it;
}

int JacobiCg::solve(const double* b, double* x, double* residual, int width, double tol, int max_iterations) {
  return width == 3 ? solve_fixed<3>(b, x, residual, tol, max_iterations) : solve_fixed<1>(b, x, residual, tol, max_iterations);
}

}  // namespace haptic::rt
