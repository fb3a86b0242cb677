#include "rt/spatial_matrix.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "rt/cpu_avx.hpp"
#include "rt/lanes.hpp"

namespace haptic::rt {

SpatialMatrix SpatialMatrix::isotropic(const SparseRowMajor& node_level) {
  SpatialMatrix m;
  m.width = 3;
  m.S = node_level;
  m.S.makeCompressed();
  return m;
}

SpatialMatrix SpatialMatrix::full(const SparseRowMajor& dof_level) {
  if (dof_level.rows() % 3 != 0) throw std::invalid_argument("full SpatialMatrix needs 3n rows");
  SpatialMatrix m;
  m.width = 1;
  m.S = dof_level;
  m.S.makeCompressed();
  return m;
}

SpatialMatrix SpatialMatrix::identity(int nodes, double scale) {
  SparseRowMajor I(nodes, nodes);
  I.setIdentity();
  I *= scale;
  return isotropic(I);
}

SparseRowMajor SpatialMatrix::as_full() const {
  if (width == 1) return S;
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(S.nonZeros()) * 3);
  for (int r = 0; r < S.outerSize(); ++r)
    for (SparseRowMajor::InnerIterator it(S, r); it; ++it)
      for (int d = 0; d < 3; ++d) t.emplace_back(3 * r + d, 3 * static_cast<int>(it.col()) + d, it.value());
  SparseRowMajor F(3 * S.rows(), 3 * S.cols());
  F.setFromTriplets(t.begin(), t.end());
  return F;
}

void SpatialMatrix::multiply_add(double alpha, const double* x, double* y) const {
  const int* outer = S.outerIndexPtr();
  const int* inner = S.innerIndexPtr();
  const double* val = S.valuePtr();
  const int rows = static_cast<int>(S.rows());
  if (width == 3) {
    for (int r = 0; r < rows; ++r) {
      double a0 = 0, a1 = 0, a2 = 0;
      for (int p = outer[r]; p < outer[r + 1]; ++p) {
        const double v = val[p];
        const double* xc = x + 3 * inner[p];
        a0 += v * xc[0];
        a1 += v * xc[1];
        a2 += v * xc[2];
      }
      y[3 * r] += alpha * a0;
      y[3 * r + 1] += alpha * a1;
      y[3 * r + 2] += alpha * a2;
    }
  } else {
    for (int r = 0; r < rows; ++r) {
      double a = 0;
      for (int p = outer[r]; p < outer[r + 1]; ++p) a += val[p] * x[inner[p]];
      y[r] += alpha * a;
    }
  }
}

namespace {

struct PairRows {
  int rows;
  const int *outer, *inner;
  const double *val, *d, *r;
};
// Per row i: acc = (S d)_i in 4 lanes (lane c: column c), its entries summed in two chains (even
// and odd positions in the row, then added: half the add latency a row), then d_i . acc and
// r_i . acc added lane by lane; lane 3 (the next node's first column) never summed.
[[gnu::always_inline]] inline PairForms pair_rows_body(const PairRows& a) {
  Lanes4 dd = {}, rd = {};
  const int lastnode = a.rows - 1;
  for (int i = 0; i < a.rows; ++i) {
    Lanes4 even = {}, odd = {};
    int p = a.outer[i];
    const int end = a.outer[i + 1];
    for (; p + 1 < end; p += 2) {
      const double v0 = a.val[p], v1 = a.val[p + 1];
      const int j0 = a.inner[p], j1 = a.inner[p + 1];
      even += Lanes4{v0, v0, v0, v0} * HAPTIC_NODE_LANES(a.d, j0, j0 == lastnode);
      odd += Lanes4{v1, v1, v1, v1} * HAPTIC_NODE_LANES(a.d, j1, j1 == lastnode);
    }
    if (p < end) {
      const double v = a.val[p];
      const int j = a.inner[p];
      even += Lanes4{v, v, v, v} * HAPTIC_NODE_LANES(a.d, j, j == lastnode);
    }
    const Lanes4 acc = even + odd;
    const bool last = i == lastnode;
    dd += HAPTIC_NODE_LANES(a.d, i, last) * acc;
    rd += HAPTIC_NODE_LANES(a.r, i, last) * acc;
  }
  return {lane_sum<3>(dd), lane_sum<3>(rd)};
}
[[gnu::noinline]] PairForms pair_rows(const PairRows& a) { return pair_rows_body(a); }
#if defined(__x86_64__)
[[gnu::noinline]] __attribute__((target("avx"))) PairForms pair_rows_avx(const PairRows& a) { return pair_rows_body(a); }
#endif

}  // namespace

PairForms SpatialMatrix::pair_forms(const double* d, const double* r, bool allow_avx) const {
  const int* outer = S.outerIndexPtr();
  const int* inner = S.innerIndexPtr();
  const double* val = S.valuePtr();
  const int rows = static_cast<int>(S.rows());
  if (width == 3) {
    const PairRows a{rows, outer, inner, val, d, r};
#if defined(__x86_64__)
    if (allow_avx && cpu_has_avx()) return pair_rows_avx(a);
#else
    (void)allow_avx;
#endif
    return pair_rows(a);
  }
  PairForms f;
  for (int i = 0; i < rows; ++i) {
    double acc = 0;
    for (int p = outer[i]; p < outer[i + 1]; ++p) acc += val[p] * d[inner[p]];
    f.dAd += d[i] * acc;
    f.rAd += r[i] * acc;
  }
  return f;
}

SpatialMatrix linear_combination(std::initializer_list<std::pair<double, const SpatialMatrix*>> terms) {
  bool iso = true;
  long rows = -1;
  for (const auto& [c, m] : terms) {
    iso = iso && m->is_isotropic();
    if (rows < 0) rows = m->dofs();
    if (m->dofs() != rows) throw std::invalid_argument("linear_combination: size mismatch");
  }
  if (rows < 0) throw std::invalid_argument("linear_combination: no terms");
  SparseRowMajor acc(iso ? rows / 3 : rows, iso ? rows / 3 : rows);
  for (const auto& [c, m] : terms) acc += c * (iso ? m->S : m->as_full());
  acc.prune(0.0);
  return iso ? SpatialMatrix::isotropic(acc) : SpatialMatrix::full(acc);
}

double lambda_max(const SpatialMatrix& A) {
  const Eigen::Index n = A.S.rows();
  if (n <= kDenseEigenRows) {
    Eigen::MatrixXd D = Eigen::MatrixXd(A.S);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(D, Eigen::EigenvaluesOnly);
    return es.eigenvalues().maxCoeff();
  }
  // Power iteration on the node-level (or full) matrix, shifted to make it positive.
  double gersh = 0;
  for (int r = 0; r < n; ++r) {
    double s = 0;
    for (SparseRowMajor::InnerIterator it(A.S, r); it; ++it) s += std::abs(it.value());
    gersh = std::max(gersh, s);
  }
  Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(n, 1.0, 2.0);
  v.normalize();
  double lam = 0;
  for (int it = 0; it < 5000; ++it) {
    Eigen::VectorXd w = A.S * v + gersh * v;
    const double l = v.dot(w) - gersh;
    w.normalize();
    const double change = std::abs(l - lam);
    v = w;
    lam = l;
    if (it > 50 && change < 1e-12 * std::max(1.0, std::abs(lam))) break;
  }
  // Power iteration approaches from below; the residual bounds the error (Weyl).
  const Eigen::VectorXd r = A.S * v - lam * v;
  return lam + r.norm();
}

}  // namespace haptic::rt
