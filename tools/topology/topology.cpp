// Network topology optimization, eq. (27). See topology.hpp. Offline math: not RT-safe.
#include "tools/topology/topology.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace haptic::topology {

namespace {

using cd = std::complex<double>;

void check_square(const Eigen::MatrixXd& m, const char* what) {
  if (m.rows() != m.cols() || m.rows() < 2) {
    throw std::invalid_argument(std::string(what) + ": must be a square N x N matrix with N >= 2");
  }
}

struct DirectedLink {
  int i;  // receiver
  int j;  // sender
  int steps;
  double w;
};

std::vector<DirectedLink> directed_links(const Graph& g, const Eigen::MatrixXd& weights,
                                         const Eigen::MatrixXi& steps) {
  std::vector<DirectedLink> out;
  out.reserve(2 * g.size());
  for (const Edge& e : g) {
    out.push_back({e.a, e.b, steps(e.a, e.b), weights(e.a, e.b)});
    out.push_back({e.b, e.a, steps(e.b, e.a), weights(e.b, e.a)});
  }
  return out;
}

int max_steps(const Graph& g, const Eigen::MatrixXi& steps) {
  int nbar = 0;
  for (const Edge& e : g) nbar = std::max({nbar, steps(e.a, e.b), steps(e.b, e.a)});
  return nbar;
}

// Deterministic uniform in [0, 1) from a 64-bit LCG/xorshift (same on every platform).
struct SplitMix {
  std::uint64_t s;
  double next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }
};

// Left eigenvector u at 1 of the lifted operator, lag-major (u[l*n + j] multiplies x_j(k - l)),
// normalized so that u^T 1 = 1: u_l = sum_{m >= l} A_m^T pi, pi the left Perron vector of
// W_total = s I + (1-s) W (pi^T (W_total - I) = 0, sum pi = 1).
Eigen::VectorXd left_eigenvector_at_one(int n, const std::vector<DirectedLink>& links, int depth, double s) {
  Eigen::MatrixXd wt = Eigen::MatrixXd::Identity(n, n) * s;
  for (const auto& l : links) wt(l.i, l.j) += (1.0 - s) * l.w;
  Eigen::MatrixXd a = wt.transpose() - Eigen::MatrixXd::Identity(n, n);
  a.row(n - 1).setOnes();
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
  rhs(n - 1) = 1.0;
  const Eigen::VectorXd pi = a.fullPivLu().solve(rhs);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(n * depth);
  for (int j = 0; j < n; ++j) u(j) += s * pi(j);
  for (const auto& l : links) {
    for (int lag = 0; lag <= l.steps; ++lag) u(lag * n + l.j) += (1.0 - s) * pi(l.i) * l.w;
  }
  u /= u.sum();
  return u;
}

// The scalar lifted operator J (matrix-free) and its deflation by the eigenvalue at 1:
// J' = J - 1 u^T / (u^T 1), u the left eigenvector at 1 built from the left Perron vector pi
// of W_total = s I + (1-s) W: u_l = sum_{m >= l} A_m^T pi.
class ScalarOperator {
 public:
  ScalarOperator(int users, const std::vector<DirectedLink>& links, int nbar, double self_weight)
      : n_(users), nbar_(nbar), s_(self_weight), links_(links), u_(left_eigenvector_at_one(users, links, nbar + 1, self_weight)) {}
  int size() const { return n_ * (nbar_ + 1); }

  // y = J' x. O(N Nbar + |E|).
  void apply(const Eigen::VectorXcd& x, Eigen::VectorXcd& y) const {
    y.resize(size());
    for (int i = 0; i < n_; ++i) y(i) = s_ * x(i);
    for (const auto& l : links_) y(l.i) += (1.0 - s_) * l.w * x(l.steps * n_ + l.j);
    if (nbar_ > 0) y.segment(n_, n_ * nbar_) = x.head(n_ * nbar_);
    const cd proj = u_.cast<cd>().dot(x);  // dot conjugates the first argument; u is real
    y.array() -= proj;
  }

 private:
  int n_;
  int nbar_;
  double s_;
  std::vector<DirectedLink> links_;
  Eigen::VectorXd u_;
};

// ZLARTG-style rotation: [c s; -conj(s) c] [f; g] = [r; 0].
void givens(cd f, cd g, double& c, cd& s) {
  const double af = std::abs(f), ag = std::abs(g);
  if (ag == 0.0) {
    c = 1.0;
    s = 0.0;
    return;
  }
  if (af == 0.0) {
    c = 0.0;
    s = std::conj(g) / ag;
    return;
  }
  const double nrm = std::hypot(af, ag);
  c = af / nrm;
  s = (f / af) * std::conj(g) / nrm;
}

// Swap the adjacent diagonal entries k, k+1 of the upper-triangular t (t = U^* A U), as ZTREXC.
void swap_schur(Eigen::MatrixXcd& t, Eigen::MatrixXcd& u, int k) {
  const int n = static_cast<int>(t.rows());
  const cd t11 = t(k, k), t22 = t(k + 1, k + 1);
  double c;
  cd s;
  givens(t(k, k + 1), t22 - t11, c, s);
  // rows k, k+1 from column k+2: x' = c x + s y, y' = c y - conj(s) x
  for (int col = k + 2; col < n; ++col) {
    const cd x = t(k, col), y = t(k + 1, col);
    t(k, col) = c * x + s * y;
    t(k + 1, col) = c * y - std::conj(s) * x;
  }
  // columns k, k+1 above row k, with sn = conj(s)
  const cd sc = std::conj(s);
  for (int row = 0; row < k; ++row) {
    const cd x = t(row, k), y = t(row, k + 1);
    t(row, k) = c * x + sc * y;
    t(row, k + 1) = c * y - std::conj(sc) * x;
  }
  t(k, k) = t22;
  t(k + 1, k + 1) = t11;
  for (int row = 0; row < u.rows(); ++row) {
    const cd x = u(row, k), y = u(row, k + 1);
    u(row, k) = c * x + sc * y;
    u(row, k + 1) = c * y - std::conj(sc) * x;
  }
}

// A random start vector, mapped once by the operator so that it lies inside the range of J'
// (removes the deflated direction), normalized.
Eigen::VectorXcd arnoldi_start(const ScalarOperator& op) {
  const int L = op.size();
  SplitMix rng{12345};
  Eigen::VectorXcd v0(L);
  for (int i = 0; i < L; ++i) v0(i) = rng.next() - 0.5;
  {
    // start inside the range of J' (removes the deflated direction)
    Eigen::VectorXcd y;
    op.apply(v0, y);
    v0 = y;
  }
  return v0 / v0.norm();
}

// Extends the Arnoldi factorization from column kc to m (Gram-Schmidt twice). Returns m, or the
// size of an exact invariant subspace found on the way (its Ritz values are exact).
int arnoldi_expand(const ScalarOperator& op, Eigen::MatrixXcd& V, Eigen::MatrixXcd& H, int kc, int m,
                   Eigen::VectorXcd& w) {
  for (int j = kc; j < m; ++j) {
    op.apply(V.col(j), w);
    const double wnorm0 = w.norm();
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::VectorXcd h = V.leftCols(j + 1).adjoint() * w;
      w.noalias() -= V.leftCols(j + 1) * h;
      H.col(j).head(j + 1) += h;
    }
    const double beta = w.norm();
    if (beta <= 1e-13 * std::max(1.0, wnorm0)) {  // invariant subspace: Ritz values exact
      H(j + 1, j) = 0.0;
      return j + 1;
    }
    H(j + 1, j) = beta;
    V.col(j + 1) = w / beta;
  }
  return m;
}

// Krylov-Schur restart: Schur form of Hm, wanted (largest modulus) first, keep k.
void krylov_schur_restart(const Eigen::MatrixXcd& Hm, int m, int k, Eigen::MatrixXcd& V, Eigen::MatrixXcd& H) {
  Eigen::ComplexSchur<Eigen::MatrixXcd> schur(Hm, true);
  Eigen::MatrixXcd T = schur.matrixT();
  Eigen::MatrixXcd U = schur.matrixU();
  // the k-th largest modulus sets the wanted threshold
  std::vector<double> mods(m);
  for (int i = 0; i < m; ++i) mods[i] = std::abs(T(i, i));
  std::vector<double> sorted = mods;
  std::sort(sorted.begin(), sorted.end(), std::greater<>());
  const double thresh = sorted[k - 1];
  int placed = 0;
  for (int i = 0; i < m && placed < k; ++i) {
    if (std::abs(T(i, i)) >= thresh) {
      for (int p = i; p > placed; --p) swap_schur(T, U, p - 1);
      ++placed;
    }
  }
  const Eigen::MatrixXcd Q1 = U.leftCols(k);
  const Eigen::MatrixXcd Vk = V.leftCols(m) * Q1;
  const cd hm = H(m, m - 1);
  const Eigen::RowVectorXcd b = hm * U.row(m - 1).head(k);
  V.leftCols(k) = Vk;
  V.col(k) = V.col(m);
  H.setZero();
  H.topLeftCorner(k, k) = T.topLeftCorner(k, k).triangularView<Eigen::Upper>();
  H.row(k).head(k) = b;
}

ScalarSpectrum arnoldi_second_modulus(const ScalarOperator& op, const SpectrumOptions& opt) {
  ScalarSpectrum out;
  out.method = EigenMethod::Arnoldi;
  const int L = op.size();
  const int m = std::min(opt.arnoldi_subspace, L - 1);
  const int k = std::max(1, std::min(opt.arnoldi_wanted, m - 2));
  const int need = std::min(2, k);
  if (m < 4) throw std::invalid_argument("arnoldi: lifted size too small; use the dense method");

  Eigen::MatrixXcd V(L, m + 1);
  Eigen::MatrixXcd H = Eigen::MatrixXcd::Zero(m + 1, m);
  V.col(0) = arnoldi_start(op);
  int kc = 0;
  Eigen::VectorXcd w(L);
  for (int restart = 0; restart <= opt.arnoldi_max_restarts; ++restart) {
    out.restarts = restart;
    const int mm = arnoldi_expand(op, V, H, kc, m, w);
    const Eigen::MatrixXcd Hm = H.topLeftCorner(mm, mm);
    Eigen::ComplexEigenSolver<Eigen::MatrixXcd> ces(Hm, true);
    const Eigen::VectorXcd theta = ces.eigenvalues();
    std::vector<int> idx(mm);
    std::iota(idx.begin(), idx.end(), 0);
    std::sort(idx.begin(), idx.end(),
              [&](int x, int y) { return std::abs(theta(x)) > std::abs(theta(y)); });
    if (mm < m) {  // exact invariant subspace containing the start vector
      out.second_modulus = std::abs(theta(idx[0]));
      out.converged = true;
      return out;
    }
    const double beta_m = std::abs(H(m, m - 1));
    bool ok = true;
    for (int q = 0; q < need; ++q) {
      const Eigen::VectorXcd y = ces.eigenvectors().col(idx[q]);
      const double res = beta_m * std::abs(y(m - 1)) / y.norm();
      if (res > opt.arnoldi_tol) ok = false;
    }
    out.second_modulus = std::abs(theta(idx[0]));
    if (ok) {
      out.converged = true;
      return out;
    }
    krylov_schur_restart(Hm, m, k, V, H);
    kc = k;
  }
  out.converged = false;
  return out;
}

// Growth rate of the deflated delay recursion (see header, "Power").
ScalarSpectrum power_second_modulus(int n, const std::vector<DirectedLink>& links, int nbar,
                                    const SpectrumOptions& opt) {
  ScalarSpectrum out;
  out.method = EigenMethod::Power;
  const double s = opt.self_weight;
  const int depth = nbar + 1;
  const Eigen::VectorXd u = left_eigenvector_at_one(n, links, depth, s);
  // ring buffer: slot (k mod depth) holds x(k)
  Eigen::MatrixXd ring(n, depth);
  SplitMix rng{987654321};
  for (int c = 0; c < depth; ++c)
    for (int i = 0; i < n; ++i) ring(i, c) = rng.next() - 0.5;
  long k = depth - 1;  // newest slot index
  auto lagged = [&](long kk, int lag) { return static_cast<int>((kk - lag) % depth); };
  // project out the consensus direction and renormalize; returns log of the norm removed
  auto project_normalize = [&]() {
    double c = 0.0;
    for (int lag = 0; lag < depth; ++lag) c += u.segment(lag * n, n).dot(ring.col(lagged(k, lag)));
    ring.array() -= c;
    const double nrm = ring.norm();
    if (!(nrm > 0) || !std::isfinite(nrm)) return -std::numeric_limits<double>::infinity();
    ring /= nrm;
    return std::log(nrm);
  };
  project_normalize();
  const int q = 16;  // steps between projections
  std::vector<double> logs;  // cumulative log-norm after each block of q steps
  double cum = 0.0;
  Eigen::VectorXd y(n);
  // least-squares slope of logs over [i0, i1)
  auto slope = [&](std::size_t i0, std::size_t i1) {
    const double m = static_cast<double>(i1 - i0);
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (std::size_t i = i0; i < i1; ++i) {
      const double x = static_cast<double>(i);
      sx += x;
      sy += logs[i];
      sxx += x * x;
      sxy += x * logs[i];
    }
    return (m * sxy - sx * sy) / (m * sxx - sx * sx) / q;
  };
  double prev = -1.0;
  std::size_t window = 512;  // blocks
  long steps = 0;
  for (;;) {
    while (logs.size() < 2 * window) {
      for (int t = 0; t < q; ++t) {
        for (int i = 0; i < n; ++i) y(i) = s * ring(i, lagged(k, 0));
        for (const auto& l : links) y(l.i) += (1.0 - s) * l.w * ring(l.j, lagged(k, l.steps));
        ++k;
        ring.col(lagged(k, 0)) = y;
      }
      steps += q;
      const double lg = project_normalize();
      if (!std::isfinite(lg)) {  // the deflated recursion vanished exactly: nilpotent
        out.second_modulus = 0.0;
        out.restarts = static_cast<int>(steps / 1000);
        return out;
      }
      cum += lg;
      logs.push_back(cum);
    }
    const double est = std::exp(slope(window, 2 * window));
    out.second_modulus = std::min(1.0, est);
    if (prev >= 0 && std::abs(est - prev) < opt.power_tol) {
      out.converged = true;
      break;
    }
    if (steps * 2 > opt.power_max_steps) {
      out.converged = false;
      break;
    }
    prev = est;
    window *= 2;
  }
  out.restarts = static_cast<int>(steps / 1000);
  return out;
}

std::uint64_t binomial_capped(std::uint64_t n, std::uint64_t k, std::uint64_t cap) {
  if (k > n) return 0;
  k = std::min(k, n - k);
  long double r = 1;
  for (std::uint64_t i = 1; i <= k; ++i) {
    r = r * static_cast<long double>(n - k + i) / static_cast<long double>(i);
    if (r > static_cast<long double>(cap)) return cap + 1;
  }
  return static_cast<std::uint64_t>(r + 0.5L);
}

struct UnionFind {
  std::vector<int> p;
  explicit UnionFind(int n) : p(n) { std::iota(p.begin(), p.end(), 0); }
  int find(int x) {
    while (p[x] != x) x = p[x] = p[p[x]];
    return x;
  }
  bool unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    p[a] = b;
    return true;
  }
};

}  // namespace

const char* to_string(StructurePath p) {
  switch (p) {
    case StructurePath::SingleMode: return "single-mode (uniform polynomial gains, exact)";
    case StructurePath::ModeSplit: return "mode-split (per eigen-mode of K_hat, exact)";
    case StructurePath::GeneralDense: return "general dense (explicit P_ij blocks)";
  }
  return "?";
}

const char* to_string(EigenMethod m) {
  switch (m) {
    case EigenMethod::Auto: return "auto";
    case EigenMethod::Dense: return "dense";
    case EigenMethod::Power: return "power";
    case EigenMethod::Arnoldi: return "arnoldi";
  }
  return "?";
}


PolynomialGains uniform_gains(int users, double a, double b, const Eigen::VectorXd& mode_values) {
  PolynomialGains g;
  g.a = Eigen::MatrixXd::Constant(users, users, a);
  g.b = Eigen::MatrixXd::Constant(users, users, b);
  g.mode_values = mode_values;
  return g;
}

PolynomialGains paper_gains(int users, const Eigen::VectorXd& k_hat_eigenvalues) {
  return uniform_gains(users, 500.0, 500.0, k_hat_eigenvalues);
}

Eigen::MatrixXd mixing_weights(const Graph& g, int users, const Eigen::MatrixXd& p) {
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(users, users);
  for (const Edge& e : g) {
    for (int dir = 0; dir < 2; ++dir) {
      const int i = dir ? e.b : e.a, j = dir ? e.a : e.b;
      if (!(p(i, j) > 0)) {
        throw std::invalid_argument("gains: mode weight p_" + std::to_string(i + 1) +
                                    std::to_string(j + 1) + " = " + std::to_string(p(i, j)) +
                                    " must be > 0 (P_ij positive definite)");
      }
      w(i, j) = p(i, j);
    }
  }
  for (int i = 0; i < users; ++i) {
    const double sum = w.row(i).sum();
    if (sum > 0) w.row(i) /= sum;
  }
  return w;
}

Eigen::MatrixXd lifted_scalar_matrix(const Graph& g, const Eigen::MatrixXd& weights,
                                     const Eigen::MatrixXi& steps, double self_weight) {
  const int n = static_cast<int>(weights.rows());
  const int nbar = max_steps(g, steps);
  const int L = n * (nbar + 1);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(L, L);
  for (int i = 0; i < n; ++i) J(i, i) += self_weight;
  for (const auto& l : directed_links(g, weights, steps)) {
    J(l.i, l.steps * n + l.j) += (1.0 - self_weight) * l.w;
  }
  for (int r = n; r < L; ++r) J(r, r - n) = 1.0;
  return J;
}

Eigen::MatrixXd lifted_dense_matrix(const Graph& g, int users, const DenseGains& gains,
                                    const Eigen::MatrixXi& steps, double self_weight) {
  const int n = gains.n;
  if (static_cast<int>(gains.blocks.size()) != users * users) {
    throw std::invalid_argument("dense gains: need N*N blocks P_ij");
  }
  const int nbar = max_steps(g, steps);
  const int nn = n * users;
  const int L = nn * (nbar + 1);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(L, L);
  std::vector<Eigen::MatrixXd> sum(users, Eigen::MatrixXd::Zero(n, n));
  for (const Edge& e : g) {
    for (int dir = 0; dir < 2; ++dir) {
      const int i = dir ? e.b : e.a, j = dir ? e.a : e.b;
      const auto& p = gains.blocks[i * users + j];
      if (p.rows() != n || p.cols() != n) {
        throw std::invalid_argument("dense gains: block P_" + std::to_string(i + 1) + "," +
                                    std::to_string(j + 1) + " must be " + std::to_string(n) +
                                    " x " + std::to_string(n));
      }
      sum[i] += p;
    }
  }
  for (int i = 0; i < users; ++i) J.block(i * n, i * n, n, n) += self_weight * Eigen::MatrixXd::Identity(n, n);
  for (const Edge& e : g) {
    for (int dir = 0; dir < 2; ++dir) {
      const int i = dir ? e.b : e.a, j = dir ? e.a : e.b;
      const Eigen::MatrixXd wij = sum[i].fullPivLu().solve(gains.blocks[i * users + j]);
      J.block(i * n, steps(i, j) * nn + j * n, n, n) += (1.0 - self_weight) * wij;
    }
  }
  for (int r = nn; r < L; ++r) J(r, r - nn) = 1.0;
  return J;
}

Eigen::VectorXcd eigenvalues_by_modulus(const Eigen::MatrixXd& m) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(m, false);
  if (es.info() != Eigen::Success) throw std::runtime_error("dense eigensolver did not converge");
  Eigen::VectorXcd ev = es.eigenvalues();
  std::vector<cd> v(ev.data(), ev.data() + ev.size());
  std::sort(v.begin(), v.end(), [](cd x, cd y) { return std::abs(x) > std::abs(y); });
  return Eigen::Map<Eigen::VectorXcd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

ScalarSpectrum scalar_second_modulus(const Graph& g, const Eigen::MatrixXd& weights,
                                     const Eigen::MatrixXi& steps, const SpectrumOptions& opt) {
  const int n = static_cast<int>(weights.rows());
  const int nbar = max_steps(g, steps);
  const int L = n * (nbar + 1);
  EigenMethod method = opt.method;
  if (method == EigenMethod::Auto) {
    method = L <= opt.dense_max_size ? EigenMethod::Dense : EigenMethod::Power;
  }
  if (method == EigenMethod::Arnoldi && L <= 8) method = EigenMethod::Dense;
  ScalarSpectrum out;
  if (method == EigenMethod::Dense) {
    const Eigen::VectorXcd ev = eigenvalues_by_modulus(lifted_scalar_matrix(g, weights, steps, opt.self_weight));
    out.second_modulus = ev.size() > 1 ? std::abs(ev(1)) : 0.0;
    out.method = EigenMethod::Dense;
  } else if (method == EigenMethod::Power) {
    out = power_second_modulus(n, directed_links(g, weights, steps), nbar, opt);
  } else {
    SpectrumOptions o = opt;
    o.arnoldi_subspace = std::min(opt.arnoldi_subspace, L - 2);
    const ScalarOperator op(n, directed_links(g, weights, steps), nbar, opt.self_weight);
    out = arnoldi_second_modulus(op, o);
  }
  out.lifted_size = L;
  out.nbar = nbar;
  return out;
}

namespace {

void check_graph(const Graph& g, int users) {
  if (!is_connected(g, users)) {
    throw std::invalid_argument("graph " + to_string_1based(g) + ": not connected over " +
                                std::to_string(users) + " users (eq. 27 needs a connected graph)");
  }
}

void check_links_available(const Graph& g, const Eigen::MatrixXi& steps) {
  for (const Edge& e : g) {
    if (steps(e.a, e.b) < 0 || steps(e.b, e.a) < 0) {
      throw std::invalid_argument("graph: link " + std::to_string(e.a + 1) + "-" + std::to_string(e.b + 1) +
                                  " has no delay in both directions (unavailable)");
    }
  }
}

void check_self_weight(double s) {
  if (!(s >= 0.0 && s < 1.0)) throw std::invalid_argument("self_weight: must be in [0, 1)");
}

}  // namespace

GraphScore score_graph(const Graph& g, const Eigen::MatrixXd& mean_delay_ms, double period_s,
                       const PolynomialGains& gains, const SpectrumOptions& opt) {
  const int users = static_cast<int>(mean_delay_ms.rows());
  check_graph(g, users);
  check_self_weight(opt.self_weight);
  if (gains.a.rows() != users || gains.a.cols() != users || gains.b.rows() != users ||
      gains.b.cols() != users) {
    throw std::invalid_argument("gains: a and b must be N x N (N = " + std::to_string(users) + ")");
  }
  const Eigen::MatrixXi steps = model::mean_delay_steps(mean_delay_ms, period_s);
  check_links_available(g, steps);
  // distinct modes
  std::vector<double> mu(gains.mode_values.data(), gains.mode_values.data() + gains.mode_values.size());
  if (mu.empty()) mu.push_back(0.0);
  std::sort(mu.begin(), mu.end());
  std::vector<double> modes;
  for (double v : mu) {
    if (modes.empty() || v - modes.back() > opt.mode_merge_tol) modes.push_back(v);
  }
  // proportional (a_ij, b_ij) on all directed links => weights independent of the mode
  bool proportional = true;
  double a0 = 0, b0 = 0;
  bool first = true;
  for (const Edge& e : g) {
    for (int dir = 0; dir < 2; ++dir) {
      const int i = dir ? e.b : e.a, j = dir ? e.a : e.b;
      const double a = gains.a(i, j), b = gains.b(i, j);
      if (first) {
        a0 = a;
        b0 = b;
        first = false;
      } else if (std::abs(a * b0 - b * a0) > 1e-12 * (std::abs(a * b0) + std::abs(b * a0) + 1e-300)) {
        proportional = false;
      }
    }
  }
  auto mode_p = [&](double m) {
    Eigen::MatrixXd p = gains.a + m * gains.b;
    return p;
  };
  GraphScore sc;
  sc.lambda_next_abs = 0.0;
  sc.converged = true;
  std::vector<double> to_eval = modes;
  if (proportional || modes.size() == 1) {
    // positivity must hold for every mode (P_ij positive definite) even though one suffices
    for (double m : {modes.front(), modes.back()}) (void)mixing_weights(g, users, mode_p(m));
    to_eval = {modes.front()};
    sc.path = StructurePath::SingleMode;
  } else {
    sc.path = StructurePath::ModeSplit;
  }
  sc.modes_evaluated = 0;
  for (double m : to_eval) {
    const Eigen::MatrixXd w = mixing_weights(g, users, mode_p(m));
    const ScalarSpectrum r = scalar_second_modulus(g, w, steps, opt);
    ++sc.modes_evaluated;
    sc.arnoldi_restarts += r.restarts;
    sc.converged = sc.converged && r.converged;
    sc.method = r.method;
    sc.lifted_size = r.lifted_size;
    sc.nbar = r.nbar;
    if (sc.modes_evaluated == 1 || r.second_modulus > sc.lambda_next_abs) {
      sc.lambda_next_abs = r.second_modulus;
      sc.worst_mode_value = m;
    }
  }
  return sc;
}

GraphScore score_graph_dense(const Graph& g, const Eigen::MatrixXd& mean_delay_ms, double period_s,
                             const DenseGains& gains, const SpectrumOptions& opt) {
  const int users = static_cast<int>(mean_delay_ms.rows());
  check_graph(g, users);
  check_self_weight(opt.self_weight);
  const Eigen::MatrixXi steps = model::mean_delay_steps(mean_delay_ms, period_s);
  check_links_available(g, steps);
  const Eigen::MatrixXd J = lifted_dense_matrix(g, users, gains, steps, opt.self_weight);
  const Eigen::VectorXcd ev = eigenvalues_by_modulus(J);
  GraphScore sc;
  sc.path = StructurePath::GeneralDense;
  sc.method = EigenMethod::Dense;
  sc.lifted_size = static_cast<int>(J.rows());
  sc.nbar = max_steps(g, steps);
  sc.lambda_next_abs = ev.size() > gains.n ? std::abs(ev(gains.n)) : 0.0;
  return sc;
}


std::vector<Graph> enumerate_connected_graphs(int users, int links, int degree_cap,
                                              std::uint64_t max_candidates,
                                              const Eigen::MatrixXi& allowed) {
  if (users < 2) throw std::invalid_argument("users: need N >= 2");
  if (links < users - 1) {
    throw std::invalid_argument("links: " + std::to_string(links) + " cannot connect " +
                                std::to_string(users) + " users (need >= N-1)");
  }
  std::vector<Edge> pairs;
  for (int a = 0; a < users; ++a) {
    for (int b = a + 1; b < users; ++b) {
      if (allowed.size() == 0 || (allowed(a, b) && allowed(b, a))) pairs.push_back({a, b});
    }
  }
  if (links > static_cast<int>(pairs.size())) {
    throw std::invalid_argument("links: " + std::to_string(links) + " exceeds the " +
                                std::to_string(pairs.size()) + " available pairs");
  }
  const std::uint64_t count = binomial_capped(pairs.size(), static_cast<std::uint64_t>(links), max_candidates);
  if (count > max_candidates) {
    throw std::invalid_argument("links: C(" + std::to_string(pairs.size()) + ", " + std::to_string(links) +
                                ") link subsets exceed the enumeration limit " +
                                std::to_string(max_candidates) + "; use the search instead");
  }
  std::vector<Graph> out;
  std::vector<int> deg(users, 0);
  Graph cur;
  // depth-first over combinations with degree-cap pruning
  auto rec = [&](auto&& self, std::size_t start) -> void {
    if (static_cast<int>(cur.size()) == links) {
      if (is_connected(cur, users)) out.push_back(cur);
      return;
    }
    const std::size_t remaining = static_cast<std::size_t>(links) - cur.size();
    for (std::size_t p = start; p + remaining <= pairs.size(); ++p) {
      const Edge e = pairs[p];
      if (degree_cap > 0 && (deg[e.a] >= degree_cap || deg[e.b] >= degree_cap)) continue;
      ++deg[e.a];
      ++deg[e.b];
      cur.push_back(e);
      self(self, p + 1);
      cur.pop_back();
      --deg[e.a];
      --deg[e.b];
    }
  };
  rec(rec, 0);
  return out;
}

namespace {

Eigen::MatrixXd round_trips(const Eigen::MatrixXd& d) { return d + d.transpose(); }

// Degree-capped tree grown from `root`: each step adds the non-tree user v and tree user u
// (deg(u) < cap) minimizing key(u) + r(u,v), key(u) = 0 (MST, spt=false) or distance from root.
Graph capped_tree(const Eigen::MatrixXd& r, int root, int cap, bool spt) {
  const int n = static_cast<int>(r.rows());
  std::vector<char> in(n, 0);
  std::vector<int> deg(n, 0);
  std::vector<double> dist(n, 0.0);
  in[root] = 1;
  Graph g;
  for (int step = 1; step < n; ++step) {
    double best = std::numeric_limits<double>::infinity();
    int bu = -1, bv = -1;
    for (int u = 0; u < n; ++u) {
      if (!in[u] || (cap > 0 && deg[u] >= cap)) continue;
      for (int v = 0; v < n; ++v) {
        if (in[v] || !std::isfinite(r(u, v))) continue;
        const double key = (spt ? dist[u] : 0.0) + r(u, v);
        if (key < best) {
          best = key;
          bu = u;
          bv = v;
        }
      }
    }
    if (bu < 0) throw std::invalid_argument("degree_cap: too small to connect all users");
    in[bv] = 1;
    ++deg[bu];
    ++deg[bv];
    dist[bv] = dist[bu] + r(bu, bv);
    g.push_back({bu, bv});
  }
  return normalized(g);
}

void add_cheapest_links(Graph& g, const Eigen::MatrixXd& r, int links, int cap) {
  const int n = static_cast<int>(r.rows());
  std::vector<int> deg(n, 0);
  Eigen::MatrixXi used = Eigen::MatrixXi::Zero(n, n);
  for (const Edge& e : g) {
    ++deg[e.a];
    ++deg[e.b];
    used(e.a, e.b) = used(e.b, e.a) = 1;
  }
  std::vector<Edge> cand;
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      if (!used(a, b) && std::isfinite(r(a, b))) cand.push_back({a, b});
    }
  }
  std::sort(cand.begin(), cand.end(), [&](const Edge& x, const Edge& y) { return r(x.a, x.b) < r(y.a, y.b); });
  for (const Edge& e : cand) {
    if (static_cast<int>(g.size()) >= links) break;
    if (cap > 0 && (deg[e.a] >= cap || deg[e.b] >= cap)) continue;
    g.push_back(e);
    ++deg[e.a];
    ++deg[e.b];
  }
  if (static_cast<int>(g.size()) < links) {
    throw std::invalid_argument("links: cannot place " + std::to_string(links) +
                                " links within the degree cap");
  }
}

// One run of search_topology: the problem, its round trips and the result so far. Each member is
// one step of the search (seeds, swap neighbourhood, first-improvement descent, kicks).
class TopologySearch {
 public:
  TopologySearch(const Eigen::MatrixXd& mean_delay_ms, double period_s, const PolynomialGains& gains,
                 const SpectrumOptions& spectrum, const SearchOptions& search, int links)
      : mean_delay_ms_(mean_delay_ms), period_s_(period_s), gains_(gains), spectrum_(spectrum), search_(search),
        n_(static_cast<int>(mean_delay_ms.rows())), links_(links), r_(round_trips(mean_delay_ms)) {}

  // The best of the seeds: the MST and `hub_seeds` shortest-path trees from the most central
  // users, each degree-capped and filled up with the cheapest links.
  void seed() {
    std::vector<int> order(n_);
    std::iota(order.begin(), order.end(), 0);
    Eigen::VectorXd centrality(n_);
    for (int i = 0; i < n_; ++i) {
      double s = 0;
      for (int j = 0; j < n_; ++j) s += (i == j || !std::isfinite(r_(i, j))) ? 0.0 : r_(i, j);
      centrality(i) = s;
    }
    std::sort(order.begin(), order.end(), [&](int x, int y) { return centrality(x) < centrality(y); });
    std::vector<Graph> seeds;
    seeds.push_back(capped_tree(r_, order[0], search_.degree_cap, false));
    for (int h = 0; h < std::min(search_.hub_seeds, n_); ++h) seeds.push_back(capped_tree(r_, order[h], search_.degree_cap, true));
    bool have = false;
    for (Graph s : seeds) {
      add_cheapest_links(s, r_, links_, search_.degree_cap);
      s = normalized(s);
      const GraphScore sc = eval(s);
      if (!have || sc.lambda_next_abs < res_.best_score.lambda_next_abs) {
        res_.best = s;
        res_.best_score = sc;
        have = true;
      }
    }
    res_.seed = res_.best;
    res_.seed_score = res_.best_score;
    res_.history.push_back(res_.best_score.lambda_next_abs);
  }

  // Descends from the best graph.
  void descend() {
    auto [g, sc] = local_search(res_.best, res_.best_score);
    accept(g, sc);
  }

  // Iterated local search: kick the best graph by `kick_swaps` random swaps and descend again.
  void kick_and_descend() {
    SplitMix rng{search_.seed};
    for (int kick = 0; kick < search_.kicks && res_.evaluations < search_.max_evaluations; ++kick) {
      Graph g = res_.best;
      for (int k = 0; k < search_.kick_swaps; ++k) {
        const int ri = static_cast<int>(rng.next() * static_cast<double>(g.size()));
        auto [base, adds] = swap_candidates(g, ri, false);
        if (adds.empty()) continue;
        base.push_back(adds[static_cast<std::size_t>(rng.next() * static_cast<double>(adds.size()))]);
        g = normalized(base);
      }
      const GraphScore sc = eval(g);
      auto [lg, lsc] = local_search(g, sc);
      accept(lg, lsc);
    }
  }

  const SearchResult& result() const { return res_; }

 private:
  GraphScore eval(const Graph& g) {
    ++res_.evaluations;
    return score_graph(g, mean_delay_ms_, period_s_, gains_, spectrum_);
  }

  // Swap neighbourhood of g: remove link ri, candidate links that keep g connected and capped.
  std::pair<Graph, std::vector<Edge>> swap_candidates(const Graph& g, int ri, bool sorted_short_first) const {
    const int n = n_;
    Graph base = g;
    const Edge removed = base[ri];
    base.erase(base.begin() + ri);
    UnionFind uf(n);
    std::vector<int> deg(n, 0);
    Eigen::MatrixXi used = Eigen::MatrixXi::Zero(n, n);
    for (const Edge& e : base) {
      uf.unite(e.a, e.b);
      ++deg[e.a];
      ++deg[e.b];
      used(e.a, e.b) = used(e.b, e.a) = 1;
    }
    const bool still_connected = is_connected(base, n);
    std::vector<Edge> adds;
    for (int a = 0; a < n; ++a) {
      for (int b = a + 1; b < n; ++b) {
        if (used(a, b) || (a == removed.a && b == removed.b) || !std::isfinite(r_(a, b))) continue;
        if (search_.degree_cap > 0 && (deg[a] >= search_.degree_cap || deg[b] >= search_.degree_cap)) continue;
        if (!still_connected && uf.find(a) == uf.find(b)) continue;
        adds.push_back({a, b});
      }
    }
    if (sorted_short_first) {
      std::sort(adds.begin(), adds.end(), [&](const Edge& x, const Edge& y) { return r_(x.a, x.b) < r_(y.a, y.b); });
    }
    return std::make_pair(base, adds);
  }

  // First-improvement local search from (cur, cur_sc); returns the local optimum.
  std::pair<Graph, GraphScore> local_search(Graph cur, GraphScore cur_sc) {
    bool improved = true;
    while (improved && res_.evaluations < search_.max_evaluations) {
      improved = false;
      std::vector<int> rem(cur.size());
      std::iota(rem.begin(), rem.end(), 0);
      std::sort(rem.begin(), rem.end(), [&](int x, int y) { return r_(cur[x].a, cur[x].b) > r_(cur[y].a, cur[y].b); });
      if (static_cast<int>(rem.size()) > search_.remove_candidates) rem.resize(search_.remove_candidates);
      for (int ri : rem) {
        auto [base, adds] = swap_candidates(cur, ri, true);
        if (static_cast<int>(adds.size()) > search_.add_candidates) adds.resize(search_.add_candidates);
        for (const Edge& f : adds) {
          if (res_.evaluations >= search_.max_evaluations) break;
          Graph cand = base;
          cand.push_back(f);
          cand = normalized(cand);
          const GraphScore sc = eval(cand);
          if (sc.lambda_next_abs < cur_sc.lambda_next_abs - 1e-12) {
            cur = cand;
            cur_sc = sc;
            improved = true;
            break;
          }
        }
        if (improved || res_.evaluations >= search_.max_evaluations) break;
      }
    }
    return std::make_pair(cur, cur_sc);
  }

  void accept(const Graph& g, const GraphScore& sc) {
    if (sc.lambda_next_abs < res_.best_score.lambda_next_abs - 1e-12) {
      res_.best = g;
      res_.best_score = sc;
      ++res_.improvements;
      res_.history.push_back(sc.lambda_next_abs);
    }
  }

  const Eigen::MatrixXd& mean_delay_ms_;
  const double period_s_;
  const PolynomialGains& gains_;
  const SpectrumOptions& spectrum_;
  const SearchOptions& search_;
  const int n_;
  const int links_;
  const Eigen::MatrixXd r_;  // round trips
  SearchResult res_;
};

}  // namespace

SearchResult search_topology(const Eigen::MatrixXd& mean_delay_ms, double period_s,
                             const PolynomialGains& gains, const SpectrumOptions& spectrum,
                             const SearchOptions& search) {
  check_square(mean_delay_ms, "delay matrix");
  const int n = static_cast<int>(mean_delay_ms.rows());
  const int links = search.links > 0 ? search.links : n - 1;
  if (links < n - 1 || links > n * (n - 1) / 2) {
    throw std::invalid_argument("links: must be in [N-1, N(N-1)/2] = [" + std::to_string(n - 1) + ", " +
                                std::to_string(n * (n - 1) / 2) + "]");
  }
  TopologySearch run(mean_delay_ms, period_s, gains, spectrum, search, links);
  run.seed();
  run.descend();
  run.kick_and_descend();
  return run.result();
}

Eigen::MatrixXd synthetic_delays_ms(int users, const SyntheticMap& map, Eigen::MatrixXd* positions_km) {
  if (users < 2) throw std::invalid_argument("users: need N >= 2");
  if (!(map.speed_km_per_ms > 0)) throw std::invalid_argument("speed_km_per_ms: must be > 0");
  if (!(map.asymmetry >= 0 && map.asymmetry < 1)) throw std::invalid_argument("asymmetry: must be in [0, 1)");
  SplitMix rng{map.seed};
  Eigen::MatrixXd pos(users, 2);
  for (int i = 0; i < users; ++i) {
    pos(i, 0) = rng.next() * map.width_km;
    pos(i, 1) = rng.next() * map.height_km;
  }
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(users, users);
  for (int i = 0; i < users; ++i) {
    for (int j = 0; j < users; ++j) {
      if (i == j) continue;
      const double dist = (pos.row(i) - pos.row(j)).norm();
      const double f = 1.0 + map.asymmetry * (2.0 * rng.next() - 1.0);
      d(i, j) = (map.base_ms + dist / map.speed_km_per_ms) * f;
    }
  }
  if (positions_km) *positions_km = pos;
  return d;
}


}  // namespace haptic::topology
