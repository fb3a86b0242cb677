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

// E pairs (d, r) at once: d^T S d and r^T S d of each. Per row i and pair: acc = (S d)_i in 4 lanes
// (lane c: column c), its entries summed in two chains (even and odd positions in the row, then
// added: half the add latency a row), then d_i . acc and r_i . acc added lane by lane; lane 3 (the
// next node's first column) never summed. A row's values and columns are read once for the E pairs,
// and each pair's sums do not depend on E (the same bits alone or batched).
struct PairRows {
  int rows;
  const int *outer, *inner;
  const double* val;
  const double* const* d;
  const double* const* r;
  PairForms* out;
};
template <int E>
[[gnu::always_inline]] inline void pair_rows_body(const PairRows& a) {
  Lanes4 dd[E] = {}, rd[E] = {};
  const double *dp[E], *rp[E];  // in registers, not re-read through a
  for (int e = 0; e < E; ++e) {
    dp[e] = a.d[e];
    rp[e] = a.r[e];
  }
  const int* const outer = a.outer;
  const int* const inner = a.inner;
  const double* const val = a.val;
  const int lastnode = a.rows - 1;
  for (int i = 0; i < a.rows; ++i) {
    Lanes4 even[E] = {}, odd[E] = {};
    int p = outer[i];
    const int end = outer[i + 1];
    for (; p + 1 < end; p += 2) {
      const double v0 = val[p], v1 = val[p + 1];
      const int j0 = inner[p], j1 = inner[p + 1];
      for (int e = 0; e < E; ++e) {
        even[e] += Lanes4{v0, v0, v0, v0} * HAPTIC_NODE_LANES(dp[e], j0, j0 == lastnode);
        odd[e] += Lanes4{v1, v1, v1, v1} * HAPTIC_NODE_LANES(dp[e], j1, j1 == lastnode);
      }
    }
    if (p < end) {
      const double v = val[p];
      const int j = inner[p];
      for (int e = 0; e < E; ++e) even[e] += Lanes4{v, v, v, v} * HAPTIC_NODE_LANES(dp[e], j, j == lastnode);
    }
    const bool last = i == lastnode;
    for (int e = 0; e < E; ++e) {
      const Lanes4 acc = even[e] + odd[e];
      dd[e] += HAPTIC_NODE_LANES(dp[e], i, last) * acc;
      rd[e] += HAPTIC_NODE_LANES(rp[e], i, last) * acc;
    }
  }
  for (int e = 0; e < E; ++e) a.out[e] = {lane_sum<3>(dd[e]), lane_sum<3>(rd[e])};
}
[[gnu::noinline]] void pair_rows_1(const PairRows& a) { pair_rows_body<1>(a); }
[[gnu::noinline]] void pair_rows_2(const PairRows& a) { pair_rows_body<2>(a); }
[[gnu::noinline]] void pair_rows_3(const PairRows& a) { pair_rows_body<3>(a); }
#if defined(__x86_64__)
[[gnu::noinline]] __attribute__((target("avx"))) void pair_rows_1_avx(const PairRows& a) { pair_rows_body<1>(a); }
[[gnu::noinline]] __attribute__((target("avx"))) void pair_rows_2_avx(const PairRows& a) { pair_rows_body<2>(a); }
[[gnu::noinline]] __attribute__((target("avx"))) void pair_rows_3_avx(const PairRows& a) { pair_rows_body<3>(a); }
#endif
// a.d/a.r/a.out's first E (1-3) pairs, in the AVX build when avx.
void pair_rows(int E, const PairRows& a, bool avx) {
#if defined(__x86_64__)
  if (avx) {
    E == 1 ? pair_rows_1_avx(a) : E == 2 ? pair_rows_2_avx(a) : pair_rows_3_avx(a);
    return;
  }
#else
  (void)avx;
#endif
  E == 1 ? pair_rows_1(a) : E == 2 ? pair_rows_2(a) : pair_rows_3(a);
}

}  // namespace

PairForms SpatialMatrix::pair_forms(const double* d, const double* r, bool allow_avx) const {
  const int* outer = S.outerIndexPtr();
  const int* inner = S.innerIndexPtr();
  const double* val = S.valuePtr();
  const int rows = static_cast<int>(S.rows());
  if (width == 3) {
    PairForms f;
    pair_rows(1, PairRows{rows, outer, inner, val, &d, &r, &f}, allow_avx && cpu_has_avx());
    return f;
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

void SpatialMatrix::pair_forms_many(const double* const* d, const double* const* r, int m, PairForms* out, bool allow_avx) const {
  if (width != 3) {
    for (int e = 0; e < m; ++e) out[e] = pair_forms(d[e], r[e], allow_avx);
    return;
  }
  const bool avx = allow_avx && cpu_has_avx();
  for (int e = 0; e < m;) {
    const int left = m - e;
    const int E = left == 1 ? 1 : left == 2 || left == 4 ? 2 : 3;  // three pairs a pass, two when two or four are left
    pair_rows(E, PairRows{static_cast<int>(S.rows()), S.outerIndexPtr(), S.innerIndexPtr(), S.valuePtr(), d + e, r + e, out + e}, avx);
    e += E;
  }
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
