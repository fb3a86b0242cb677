#include "rt/jacobi_cg.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "rt/cpu_avx.hpp"
#include "rt/lanes.hpp"

namespace haptic::rt {

namespace {

using Index = std::size_t;

// max |a_ij - a_ji| <= 1e-12 max |a_ij|: CG needs a symmetric A, and the upper storage uses a_ij
// (i < j) for both.
void require_symmetric(const SparseColMajor& A, const SparseRowMajor& R) {
  const SparseRowMajor At(A.transpose());
  const SparseRowMajor diff = R - At;
  double scale = 0, worst = 0;
  for (int k = 0; k < R.nonZeros(); ++k) scale = std::max(scale, std::abs(R.valuePtr()[k]));
  for (int k = 0; k < diff.nonZeros(); ++k) worst = std::max(worst, std::abs(diff.valuePtr()[k]));
  if (!(worst <= 1e-12 * scale)) throw std::invalid_argument("JacobiCg: matrix is not symmetric");
}

}  // namespace

JacobiCg::JacobiCg(const SparseColMajor& A, int width, double relative_tolerance) {
  if (A.rows() != A.cols()) throw std::invalid_argument("JacobiCg: matrix is not square");
  if (width != 1 && width != 3) throw std::invalid_argument("JacobiCg: width must be 1 or 3");
  if (!(relative_tolerance > 0 && relative_tolerance < 1)) throw std::invalid_argument("JacobiCg: tolerance must be in (0, 1)");
  n_ = static_cast<int>(A.rows());
  SparseRowMajor R(A);  // rows of A
  R.makeCompressed();
  require_symmetric(A, R);
  const int* rp = R.outerIndexPtr();
  const int* ci = R.innerIndexPtr();
  const double* av = R.valuePtr();
  diag_.assign(static_cast<Index>(n_), 0.0);
  dinv_.assign(static_cast<Index>(n_), 0.0);
  int band = 0;
  long upper_entries = 0;
  for (int i = 0; i < n_; ++i)
    for (int p = rp[i]; p < rp[i + 1]; ++p) {
      if (ci[p] == i) diag_[static_cast<Index>(i)] += av[p];
      if (ci[p] > i) {
        band = std::max(band, ci[p] - i);
        ++upper_entries;
      }
    }
  for (int i = 0; i < n_; ++i) {
    if (!(diag_[static_cast<Index>(i)] > 0)) throw std::invalid_argument("JacobiCg: non-positive diagonal");
    dinv_[static_cast<Index>(i)] = 1.0 / diag_[static_cast<Index>(i)];
  }
  // Gershgorin discs of D^{-1/2} A D^{-1/2} (unit diagonal) and of A.
  double radius_scaled = 0, lo_a = INFINITY, hi_a = 0;
  for (int i = 0; i < n_; ++i) {
    double rs = 0, ra = 0;
    const double di = diag_[static_cast<Index>(i)];
    for (int p = rp[i]; p < rp[i + 1]; ++p) {
      const int j = ci[p];
      if (j == i) continue;
      const double a = std::abs(av[p]);
      ra += a;
      rs += a / std::sqrt(di * diag_[static_cast<Index>(j)]);
    }
    radius_scaled = std::max(radius_scaled, rs);
    lo_a = std::min(lo_a, di - ra);
    hi_a = std::max(hi_a, di + ra);
  }
  if (!(radius_scaled < 1) || !(lo_a > 0))
    throw std::invalid_argument("JacobiCg: matrix is not diagonally dominant enough for a proven iteration cap");
  kappa_scaled_ = (1 + radius_scaled) / (1 - radius_scaled);
  kappa_a_ = hi_a / lo_a;
  const double sk = std::sqrt(kappa_scaled_);
  const double rho = (sk - 1) / (sk + 1);
  const double need = relative_tolerance / (2 * std::sqrt(kappa_a_));
  cap_ = rho <= 0 ? 1 : std::max(1, static_cast<int>(std::ceil(std::log(need) / std::log(rho))));

  store_rows(R, band, upper_entries);
  use_avx(true);
  const auto w = static_cast<Index>(n_) * 3;
  p_.assign(w, 0.0);
  q_.assign(w, 0.0);
}

// Start-up: A's rows as the diagonal + strict upper triangle with 16-bit offsets when the band fits,
// else the full rows (rp, ci, av: R's compressed rows).
void JacobiCg::store_rows(const SparseRowMajor& R, int band, long upper_entries) {
  const int* rp = R.outerIndexPtr();
  const int* ci = R.innerIndexPtr();
  const double* av = R.valuePtr();
  upper_ = band <= std::numeric_limits<std::uint16_t>::max();
  if (upper_) {
    band_ = band;
    rowptr_.assign(static_cast<Index>(n_) + 1, 0);
    offset_.reserve(static_cast<Index>(upper_entries));
    val_.reserve(static_cast<Index>(upper_entries));
    for (int i = 0; i < n_; ++i) {
      for (int p = rp[i]; p < rp[i + 1]; ++p)
        if (ci[p] > i) {
          offset_.push_back(static_cast<std::uint16_t>(ci[p] - i));
          val_.push_back(av[p]);
        }
      rowptr_[static_cast<Index>(i) + 1] = static_cast<int>(val_.size());
    }
    window_chunk_ = std::max(band, 1);  // >= band: the copied slots do not overlap their source (2 band + 1 slots)
    window_.assign(static_cast<Index>(window_chunk_ + band + 1) * 4, 0.0);
    diag_.shrink_to_fit();
  } else {
    diag_ = {};
    rowptr_.assign(rp, rp + n_ + 1);
    colidx_.assign(ci, ci + R.nonZeros());
    val_.assign(av, av + R.nonZeros());
  }
}

bool JacobiCg::use_avx(bool allow) {
  avx_ = allow && cpu_has_avx();
  return avx_;
}

long JacobiCg::stored_doubles() const {
  return static_cast<long>(val_.size() + diag_.size() + dinv_.size() + window_.size() + p_.size() + q_.size()) +
         static_cast<long>(rowptr_.size() + colidx_.size()) / 2 + static_cast<long>(offset_.size()) / 4;
}

// One matrix pass: row_done(i, acc) receives acc = (A x)_i (W columns) for i = 0, 1, ..., n-1 in
// order. Upper storage: acc = partial_i + a_ii x_i + sum_{j>i} a_ij x_j, where partial_i collected
// a_ki x_k from the rows k < i in ascending k: the same terms in the same order as the full row's
// sum, so the two storages give the same bits for an exactly symmetric A. Entries are addressed from
// row i's own x and partial slot by the 16-bit offset (a sliding window, no wrap: Window below).
// Wide (W = 3): a row's columns in 4-lane vectors (the 4th lane reads the next node and is dropped;
// rows that reach the last node stay scalar), each lane the same multiply and add in the same order
// as the scalar loop (no FMA), so the results are identical bit for bit (rt/lanes.hpp). The entry
// loops are unrolled by 2: the same adds in the same order.

namespace {

struct UpperRows {
  int n;
  int band;  // the largest j - i of a stored entry
  const int* rowptr;
  const std::uint16_t* offset;
  const double* val;
  const double* diag;
};

template <int W, class RowDone>
[[gnu::always_inline]] inline RowDone full_rows(int n, const int* rp, const int* ci, const double* v, const double* x, RowDone row_done) {
  for (int i = 0; i < n; ++i) {
    double acc[W] = {};
    for (int e = rp[i]; e < rp[i + 1]; ++e) {
      const double a = v[e];
      const double* xj = x + static_cast<long>(ci[e]) * W;
      for (int c = 0; c < W; ++c) acc[c] += a * xj[c];
    }
    row_done(i, acc);
  }
  return row_done;
}

// The partial sums: S doubles a slot (S = 4 for the passes: aligned, non-overlapping 32-byte slots,
// so a slot's store forwards to its next load). Node j's slot is at position j - base; base moves
// by `chunk` (>= band) when row i reaches position chunk, the band of slots ahead then copied to
// the front, so a row addresses its partial slots and its x's by the same offset without a wrap.
struct Window {
  double* partial;  // (chunk + band + 1) * S doubles; or the output array itself when chunk >= n
  int chunk;
};

template <int W, int S, bool Wide, class RowDone>
[[gnu::always_inline]] inline RowDone upper_rows(const UpperRows& m, const double* __restrict x, Window win, RowDone row_done) {
  const int n = m.n;
  const int band = m.band;
  const int* rp = m.rowptr;
  const std::uint16_t* off = m.offset;
  const double* v = m.val;
  double* __restrict partial = win.partial;
  // Slot j collects a_ij x_i from the rows i < j; it is zeroed a band ahead (at row j - band: no
  // earlier row reaches it), so no pass over it is needed before.
  for (long k = 0; k < static_cast<long>(std::min(band + 1, n)) * S; ++k) partial[k] = 0.0;
  int base = 0;
  for (int i = 0; i < n; ++i) {
    const int e0 = rp[i], e1 = rp[i + 1];
    if (i - base == win.chunk) {  // the live slots (nodes i .. i + band - 1) to the front
      __builtin_memcpy(partial, partial + static_cast<long>(win.chunk) * S, sizeof(double) * S * static_cast<std::size_t>(band));
      base = i;
    }
    double* own = partial + static_cast<long>(i - base) * S;
    if (i > 0 && i + band < n)
      for (int c = 0; c < S; ++c) own[static_cast<long>(band) * S + c] = 0.0;
    const double* xi = x + static_cast<long>(i) * W;
    double acc[W];
    if constexpr (Wide) {
      static_assert(W == 3 && S == 4);
      if (i < n - 1 && (e1 == e0 || i + off[e1 - 1] < n - 1)) {  // offsets ascend: the last is the largest
        Lanes4 xv, o;
        __builtin_memcpy(&xv, xi, sizeof xv);
        xv[3] = 0;
        __builtin_memcpy(&o, own, sizeof o);
        const double di = m.diag[i];
        Lanes4 a4 = o + Lanes4{di, di, di, di} * xv;
#pragma GCC unroll 2
        for (int e = e0; e < e1; ++e) {
          const double a = v[e];
          const Lanes4 av = {a, a, a, a};
          const long d = off[e];
          Lanes4 xj, pj;
          __builtin_memcpy(&xj, xi + 3 * d, sizeof xj);
          __builtin_memcpy(&pj, own + 4 * d, sizeof pj);
          a4 += av * xj;
          pj += av * xv;
          __builtin_memcpy(own + 4 * d, &pj, sizeof pj);
        }
        row_done.wide(i, a4);
        continue;
      }
    }
    double xl[W];
    for (int c = 0; c < W; ++c) {
      xl[c] = xi[c];
      acc[c] = own[c] + m.diag[i] * xl[c];
    }
    for (int e = e0; e < e1; ++e) {
      const double a = v[e];
      const long d = off[e];
      const double* xj = xi + d * W;
      double* pj = own + d * S;
      for (int c = 0; c < W; ++c) {
        acc[c] += a * xj[c];
        pj[c] += a * xl[c];
      }
    }
    row_done(i, acc);
  }
  return row_done;
}

#if defined(__x86_64__)
template <int W, class RowDone>
__attribute__((target("avx"))) void upper_rows_avx(const UpperRows& m, const double* x, Window win,
                                                   RowDone& row_done) {  // by reference: AVX-sized members
  row_done = upper_rows<W, 4, W == 3>(m, x, win, row_done);
}
#endif

}  // namespace

template <int W, class RowDone>
RowDone JacobiCg::pass(const double* x, RowDone row_done) {
  if (!upper_) return full_rows<W>(n_, rowptr_.data(), colidx_.data(), val_.data(), x, row_done);
  const UpperRows m{n_, band_, rowptr_.data(), offset_.data(), val_.data(), diag_.data()};
  const Window win{window_.data(), window_chunk_};
#if defined(__x86_64__)
  if (avx_) {
    upper_rows_avx<W>(m, x, win, row_done);
    return row_done;
  }
#endif
  return upper_rows<W, 4, false>(m, x, win, row_done);
}

// Scalar; y itself collects the partial sums.
template <int W>
void JacobiCg::multiply_fixed(const double* x, double* y) const {
  const auto done = [y](int i, const double* acc) {
    for (int c = 0; c < W; ++c) y[static_cast<long>(i) * W + c] = acc[c];
  };
  if (!upper_) {
    full_rows<W>(n_, rowptr_.data(), colidx_.data(), val_.data(), x, done);
    return;
  }
  upper_rows<W, W, false>(UpperRows{n_, band_, rowptr_.data(), offset_.data(), val_.data(), diag_.data()}, x, Window{y, n_}, done);
}

void JacobiCg::multiply(const double* x, double* y, int width) const {
  if (width == 3)
    multiply_fixed<3>(x, y);
  else
    multiply_fixed<1>(x, y);
}

namespace {

// Row-local work, passed by value into the pass so its sums stay in registers. Sums are kept per
// column (lane c of a Lanes4; W short chains of adds). wide(i, acc) is the Wide rows' 4-lane
// version (W = 3, i < n - 1): each lane the scalar operator's operations in the same order, and a
// 4-lane store at row i also writes component 0 of row i + 1, which row i + 1 then overwrites.

// Initial pass: r = b - A x, p = z = D^{-1} r, |b|^2, |r|^2 and r.z per column.
template <int W>
struct InitialRows {
  const double* b;
  double* r;
  double* p;
  const double* dinv;
  Lanes4 bb = {}, rr = {}, rz = {};
  [[gnu::always_inline]] void operator()(int i, const double* acc) {
    for (int c = 0; c < W; ++c) {
      const long k = static_cast<long>(i) * W + c;
      r[k] = b[k] - acc[c];
      p[k] = dinv[i] * r[k];
      bb[c] += b[k] * b[k];
      rr[c] += r[k] * r[k];
      rz[c] += r[k] * p[k];
    }
  }
  [[gnu::always_inline]] void wide(int i, Lanes4 acc) {
    const long k = static_cast<long>(i) * 3;
    Lanes4 bv;
    __builtin_memcpy(&bv, b + k, sizeof bv);
    const Lanes4 rv = bv - acc;
    const double d = dinv[i];
    const Lanes4 pv = Lanes4{d, d, d, d} * rv;
    __builtin_memcpy(r + k, &rv, sizeof rv);
    __builtin_memcpy(p + k, &pv, sizeof pv);
    bb += bv * bv;
    rr += rv * rv;
    rz += rv * pv;
  }
};

// An iteration's pass: q = A p and p.q per column.
template <int W>
struct DirectionRows {
  const double* p;
  double* q;
  Lanes4 pq = {};
  [[gnu::always_inline]] void operator()(int i, const double* acc) {
    const long k = static_cast<long>(i) * W;
    for (int c = 0; c < W; ++c) {
      q[k + c] = acc[c];
      pq[c] += p[k + c] * acc[c];
    }
  }
  [[gnu::always_inline]] void wide(int i, Lanes4 acc) {
    const long k = static_cast<long>(i) * 3;
    Lanes4 pv;
    __builtin_memcpy(&pv, p + k, sizeof pv);
    __builtin_memcpy(q + k, &acc, sizeof acc);
    pq += pv * acc;
  }
};

}  // namespace

namespace {

// The CG's vector updates, W = 3 in 4 lanes a node (lane 3 never stored or summed; the last node's
// lane 3 reads 0): each lane the scalar loop's operations in the same order, so the baseline
// (SSE2 pairs) and AVX builds give the scalar loop's bits.
struct XrRows {
  int n;
  double *x, *r;
  const double *p, *q, *dinv;
  Lanes4 alpha;
};
struct XrSums {
  Lanes4 rz, rr;
};
[[gnu::always_inline]] inline XrSums xr_body(const XrRows& a) {
  Lanes4 rz = {}, rr = {};
  for (int i = 0; i < a.n; ++i) {
    const bool last = i == a.n - 1;
    const Lanes4 xv = HAPTIC_NODE_LANES(a.x, i, last) + a.alpha * HAPTIC_NODE_LANES(a.p, i, last);
    const Lanes4 rv = HAPTIC_NODE_LANES(a.r, i, last) - a.alpha * HAPTIC_NODE_LANES(a.q, i, last);
    HAPTIC_STORE_NODE(a.x, i, xv);
    HAPTIC_STORE_NODE(a.r, i, rv);
    const Lanes4 r2 = rv * rv;
    rz += r2 * a.dinv[i];
    rr += r2;
  }
  return {rz, rr};
}
struct PRows {
  int n;
  double* p;
  const double *r, *dinv;
  Lanes4 beta;
};
[[gnu::always_inline]] inline void p_body(const PRows& a) {
  for (int i = 0; i < a.n; ++i) {
    const bool last = i == a.n - 1;
    const Lanes4 pv = a.dinv[i] * HAPTIC_NODE_LANES(a.r, i, last) + a.beta * HAPTIC_NODE_LANES(a.p, i, last);
    HAPTIC_STORE_NODE(a.p, i, pv);
  }
}
[[gnu::noinline]] XrSums xr_rows(const XrRows& a) { return xr_body(a); }
[[gnu::noinline]] void p_rows(const PRows& a) { p_body(a); }
#if defined(__x86_64__)
[[gnu::noinline]] __attribute__((target("avx"))) XrSums xr_rows_avx(const XrRows& a) { return xr_body(a); }
[[gnu::noinline]] __attribute__((target("avx"))) void p_rows_avx(const PRows& a) { p_body(a); }
#endif

}  // namespace

// x += alpha p, r -= alpha q, and per column sum r^2 D^{-1} (rz_new) and sum r^2 (rrc).
template <int W>
void JacobiCg::update_xr(double* x, double* r, const double* alpha, double* rz_new, double* rrc) const {
  const double* p = p_.data();
  const double* q = q_.data();
  const double* dinv = dinv_.data();
  if constexpr (W == 3) {
    const XrRows a{n_, x, r, p, q, dinv, Lanes4{alpha[0], alpha[1], alpha[2], 0.0}};
#if defined(__x86_64__)
    const XrSums s = avx_ ? xr_rows_avx(a) : xr_rows(a);
#else
    const XrSums s = xr_rows(a);
#endif
    for (int c = 0; c < 3; ++c) {
      rz_new[c] = s.rz[c];
      rrc[c] = s.rr[c];
    }
    return;
  }
  for (int i = 0; i < n_; ++i)
    for (int c = 0; c < W; ++c) {
      const long k = static_cast<long>(i) * W + c;
      x[k] += alpha[c] * p[k];
      r[k] -= alpha[c] * q[k];
      rz_new[c] += r[k] * r[k] * dinv[i];
      rrc[c] += r[k] * r[k];
    }
}

// p := D^{-1} r + beta p per column.
template <int W>
void JacobiCg::update_p(const double* r, const double* beta) {
  double* p = p_.data();
  const double* dinv = dinv_.data();
  if constexpr (W == 3) {
    const PRows a{n_, p, r, dinv, Lanes4{beta[0], beta[1], beta[2], 0.0}};
#if defined(__x86_64__)
    if (avx_) {
      p_rows_avx(a);
      return;
    }
#endif
    p_rows(a);
    return;
  }
  for (int i = 0; i < n_; ++i)
    for (int c = 0; c < W; ++c) {
      const long k = static_cast<long>(i) * W + c;
      p[k] = dinv[i] * r[k] + beta[c] * p[k];
    }
}

// Preconditioned CG (Saad, Alg. 9.1) run on W independent systems; one matrix pass per iteration
// with the p.q products accumulated in it, z = D^{-1} r never stored (three vector passes); the
// initial residual is formed in the initial matvec's pass.
template <int W>
int JacobiCg::solve_fixed(const double* b, double* x, double* r, double tol, int max_iterations) {
  double* p = p_.data();
  double* q = q_.data();
  const double* dinv = dinv_.data();
  // r = b - A x, p = z = D^{-1} r and the products, in the initial matvec's pass (row-local).
  const InitialRows<W> init = pass<W>(x, InitialRows<W>{b, r, p, dinv});
  double rr = lane_sum<W>(init.rr);
  double rz[W];
  for (int c = 0; c < W; ++c) rz[c] = init.rz[c];
  const double threshold = tol * tol * lane_sum<W>(init.bb);
  int it = 0;
  while (rr > threshold) {
    if (it == max_iterations) return max_iterations + 1;
    ++it;
    const DirectionRows<W> dir = pass<W>(p, DirectionRows<W>{p, q});
    const Lanes4 pq = dir.pq;
    double alpha[W];
    for (int c = 0; c < W; ++c) alpha[c] = pq[c] > 0 ? rz[c] / pq[c] : 0.0;
    double rz_new[W] = {}, rrc[W] = {};
    update_xr<W>(x, r, alpha, rz_new, rrc);
    rr = rrc[0];
    for (int c = 1; c < W; ++c) rr += rrc[c];
    if (rr <= threshold) break;  // converged: the next direction is not needed
    double beta[W];
    for (int c = 0; c < W; ++c) {
      beta[c] = rz[c] > 0 ? rz_new[c] / rz[c] : 0.0;
      rz[c] = rz_new[c];
    }
    update_p<W>(r, beta);
  }
  return it;
}

int JacobiCg::solve(const double* b, double* x, double* residual, int width, double tol, int max_iterations) {
  return width == 3 ? solve_fixed<3>(b, x, residual, tol, max_iterations) : solve_fixed<1>(b, x, residual, tol, max_iterations);
}

}  // namespace haptic::rt
