#include "rt/multi_term_operator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <stdexcept>

#include "rt/cpu_avx.hpp"
#include "rt/lanes.hpp"

namespace haptic::rt {

namespace {
// The union of the terms' off-diagonal patterns (entries with a non-zero value), each row's
// columns ascending: ptr (rows + 1) and cols. Start-up, O(nnz log row length).
void union_pattern(const std::vector<SparseRowMajor>& S, std::vector<int>& ptr, std::vector<int>& cols) {
  const int rows = static_cast<int>(S[0].rows());
  ptr.assign(static_cast<std::size_t>(rows) + 1, 0);
  for (int r = 0; r < rows; ++r) {
    const std::size_t begin = cols.size();
    for (const auto& m : S)
      for (SparseRowMajor::InnerIterator it(m, r); it; ++it)
        if (it.col() != r && it.value() != 0.0) cols.push_back(static_cast<int>(it.col()));
    std::sort(cols.begin() + static_cast<std::ptrdiff_t>(begin), cols.end());
    cols.erase(std::unique(cols.begin() + static_cast<std::ptrdiff_t>(begin), cols.end()), cols.end());
    ptr[static_cast<std::size_t>(r) + 1] = static_cast<int>(cols.size());
  }
}
}  // namespace

MultiTermOperator::MultiTermOperator(const std::vector<const SpatialMatrix*>& terms) {
  if (terms.empty() || static_cast<int>(terms.size()) > kMaxTerms)
    throw std::invalid_argument("MultiTermOperator: 1 to " + std::to_string(kMaxTerms) + " terms");
  bool iso = true;
  for (const auto* m : terms) {
    iso = iso && m->is_isotropic();
    if (m->dofs() != terms[0]->dofs()) throw std::invalid_argument("MultiTermOperator: size mismatch");
  }
  width_ = iso ? 3 : 1;
  terms_ = static_cast<int>(terms.size());
  std::vector<SparseRowMajor> S;
  for (const auto* m : terms) S.push_back(iso ? m->S : m->as_full());
  rows_ = static_cast<int>(S[0].rows());
  diag_.assign(static_cast<std::size_t>(rows_) * static_cast<std::size_t>(terms_), 0.0);
  // Which terms have off-diagonal entries, and the union pattern (rows sorted by column) with
  // every term's value on it (terms x entries, 0 where a term has none).
  std::vector<bool> has_off(static_cast<std::size_t>(terms_), false);
  std::vector<int> ptr, cols;
  union_pattern(S, ptr, cols);
  const auto T = static_cast<std::size_t>(terms_);
  std::vector<double> vals(cols.size() * T, 0.0);
  for (int t = 0; t < terms_; ++t)
    for (int r = 0; r < rows_; ++r)
      for (SparseRowMajor::InnerIterator it(S[static_cast<std::size_t>(t)], r); it; ++it) {
        const int c = static_cast<int>(it.col());
        if (c == r) {
          diag_[static_cast<std::size_t>(r) * T + static_cast<std::size_t>(t)] += it.value();
        } else if (it.value() != 0.0) {
          has_off[static_cast<std::size_t>(t)] = true;
          const auto e = std::lower_bound(cols.begin() + ptr[static_cast<std::size_t>(r)], cols.begin() + ptr[static_cast<std::size_t>(r) + 1], c) - cols.begin();
          vals[static_cast<std::size_t>(e) * T + static_cast<std::size_t>(t)] += it.value();
        }
      }
  for (int t = 0; t < terms_; ++t)
    if (has_off[static_cast<std::size_t>(t)]) off_term_.push_back(t);
  off_terms_ = static_cast<int>(off_term_.size());
  use_avx(true);
  // Shared values: every slot's off-diagonal values a multiple of slot 0's (to 1e-14 per entry).
  ratio_.assign(static_cast<std::size_t>(off_terms_), 1.0);
  shared_ = off_terms_ > 1;
  const std::size_t entries = cols.size();
  for (int s = 1; s < off_terms_ && shared_; ++s) {
    const auto ts = static_cast<std::size_t>(off_term_[static_cast<std::size_t>(s)]);
    const auto t0 = static_cast<std::size_t>(off_term_[0]);
    double ratio = 0;
    for (std::size_t e = 0; e < entries && ratio == 0; ++e)
      if (vals[e * T + t0] != 0.0) ratio = vals[e * T + ts] / vals[e * T + t0];
    for (std::size_t e = 0; e < entries; ++e)
      if (!(std::abs(vals[e * T + ts] - ratio * vals[e * T + t0]) <= 1e-14 * std::abs(vals[e * T + ts]))) shared_ = false;
    ratio_[static_cast<std::size_t>(s)] = ratio;
  }
  if (!shared_) ratio_.assign(static_cast<std::size_t>(off_terms_), 1.0);
  const int stored_slots = shared_ ? 1 : off_terms_;
  rowptr_ = std::move(ptr);
  col_ = std::move(cols);
  off_.reserve(entries * static_cast<std::size_t>(stored_slots));
  for (std::size_t e = 0; e < entries; ++e)
    for (int s = 0; s < stored_slots; ++s) off_.push_back(vals[e * T + static_cast<std::size_t>(off_term_[static_cast<std::size_t>(s)])]);
  prepare_consensus_ring();
}

void MultiTermOperator::prepare_consensus_ring() {
  // apply_consensus: terms [M, K, P, D] with off-diagonal entries in K and P only, shared values,
  // isotropic; the ring holds the band of columns rows read (bounded: 4096 nodes, three copies of
  // 64 bytes each: 768 KB).
  const bool mkpd = terms_ == 4 && off_terms_ == 2 && off_term_[0] == 1 && off_term_[1] == 2 && shared_ && width_ == 3;
  if (mkpd) {
    int behind = 0, ahead = 0;
    for (int r = 0; r < rows_; ++r)
      if (rowptr_[static_cast<std::size_t>(r) + 1] > rowptr_[static_cast<std::size_t>(r)]) {
        behind = std::max(behind, r - col_[static_cast<std::size_t>(rowptr_[static_cast<std::size_t>(r)])]);
        ahead = std::max(ahead, col_[static_cast<std::size_t>(rowptr_[static_cast<std::size_t>(r) + 1]) - 1] - r);
      }
    int nodes = 1;
    while (nodes <= behind + ahead + 1) nodes *= 2;  // node m lives from row m - ahead - 1 to row m + behind
    if (nodes <= 4096) {
      ring_mask_ = nodes - 1;
      band_ahead_ = ahead;
      ring_.assign(static_cast<std::size_t>(nodes) * 3 * 8 + 8, 0.0);
      rel_.resize(col_.size());  // an entry's slot from its row's: (column - row) slots of 64 bytes
      for (int r = 0; r < rows_; ++r)
        for (int e = rowptr_[static_cast<std::size_t>(r)]; e < rowptr_[static_cast<std::size_t>(r) + 1]; ++e)
          rel_[static_cast<std::size_t>(e)] = (col_[static_cast<std::size_t>(e)] - r) * 64;
    }
  }
}

bool MultiTermOperator::use_avx(bool allow) {
  avx_ = allow && cpu_has_avx();
  return avx_;
}

long MultiTermOperator::stored_doubles() const {
  return static_cast<long>(diag_.size() + off_.size() + ring_.size()) + static_cast<long>(rowptr_.size() + col_.size() + rel_.size()) / 2;
}

// TT, S: number of terms and of off-diagonal slots known at compile time (the common cases), or
// -1 (run-time counts). Shared: one stored value per entry, slot s scaled by ratio[s]. Wide (W = 3,
// Shared): a row's off-diagonal sums in 4-lane vectors (the 3 columns and one unused lane, read from
// the next node; rows that reach the last node stay scalar), each lane the same multiply and add in
// the same order as the scalar loop, so the results are identical bit for bit.
template <int W, int TT, int S, bool Shared, bool Wide = false>
[[gnu::always_inline]] inline void apply_body(int rows, int terms_rt, int off_terms_rt, const int* off_term, const double* ratio, const double* diag,
                         const int* rowptr, const int* col, const double* off, const double* const* u, const double* to_y,
                         const double* to_h, double* y, double* h, double* quad) {
  constexpr int kT = MultiTermOperator::kMaxTerms;
  const int off_terms = S >= 0 ? S : off_terms_rt;
  const int terms = TT >= 0 ? TT : terms_rt;
  constexpr int kA = TT > 0 ? TT : kT;  // accumulators: exactly the terms when known
  double q[kT] = {};
  const double* up[kT];
  for (int t = 0; t < terms; ++t) up[t] = u[t];
  for (int i = 0; i < rows; ++i) {
    double acc[kA][W];
    const double* di = diag + static_cast<long>(i) * terms;
    for (int t = 0; t < terms; ++t)
      for (int c = 0; c < W; ++c) acc[t][c] = di[t] * up[t][static_cast<long>(i) * W + c];
    // Off-diagonal sums per slot (compile-time index: kept in registers), then added to their terms.
    constexpr int kS = S > 0 ? S : (S == 0 ? 1 : kT);
    double oacc[kS][W];
    const double* us[kS];
    for (int s = 0; s < off_terms; ++s) {
      us[s] = up[off_term[s]];
      for (int c = 0; c < W; ++c) oacc[s][c] = 0.0;
    }
    bool done = false;
    if constexpr (Wide && W == 3 && Shared && S > 0) {
      const int e0 = rowptr[i], e1 = rowptr[i + 1];
      if (e1 > e0 && col[e1 - 1] < rows - 1) {  // columns ascend: the last one is the largest
        Lanes4 o[kS] = {};
        for (int e = e0; e < e1; ++e) {
          const long j = static_cast<long>(col[e]) * 3;
          const Lanes4 a = {off[e], off[e], off[e], off[e]};
          for (int s = 0; s < S; ++s) {
            Lanes4 x;
            __builtin_memcpy(&x, us[s] + j, sizeof x);
            o[s] += a * x;
          }
        }
        for (int s = 0; s < S; ++s)
          for (int c = 0; c < 3; ++c) oacc[s][c] = o[s][c];
        done = true;
      }
    }
    for (int e = done ? rowptr[i + 1] : rowptr[i]; e < rowptr[i + 1]; ++e) {
      const long j = static_cast<long>(col[e]) * W;
      const double* ov = off + static_cast<long>(e) * (Shared ? 1 : off_terms);
      for (int s = 0; s < off_terms; ++s) {
        const double a = Shared ? ov[0] : ov[s];
        const double* uj = us[s] + j;
        for (int c = 0; c < W; ++c) oacc[s][c] += a * uj[c];
      }
    }
    for (int s = 0; s < off_terms; ++s)
      for (int c = 0; c < W; ++c) acc[off_term[s]][c] += Shared ? ratio[s] * oacc[s][c] : oacc[s][c];
    for (int c = 0; c < W; ++c) {
      double sy = 0, sh = 0;
      for (int t = 0; t < terms; ++t) {
        sy += to_y[t] * acc[t][c];
        sh += to_h[t] * acc[t][c];
      }
      if (y) y[static_cast<long>(i) * W + c] = sy;
      if (h) h[static_cast<long>(i) * W + c] = sh;
    }
    if (quad)
      for (int t = 0; t < terms; ++t)
        for (int c = 0; c < W; ++c) q[t] += up[t][static_cast<long>(i) * W + c] * acc[t][c];
  }
  if (quad)
    for (int t = 0; t < terms; ++t) quad[t] = q[t];
}

#define HAPTIC_MTO_PARAMS                                                                                                    \
  int rows, int terms_rt, int off_terms_rt, const int *off_term, const double *ratio, const double *diag, const int *rowptr, \
      const int *col, const double *off, const double *const *u, const double *to_y, const double *to_h, double *y, double *h, \
      double *quad
#define HAPTIC_MTO_ARGS rows, terms_rt, off_terms_rt, off_term, ratio, diag, rowptr, col, off, u, to_y, to_h, y, h, quad
template <int W, int TT, int S, bool Shared>
static void apply_kernel(HAPTIC_MTO_PARAMS) {
  apply_body<W, TT, S, Shared>(HAPTIC_MTO_ARGS);
}
#if defined(__x86_64__)
// The same kernel compiled for AVX (256-bit lanes), chosen at run time when the CPU has it.
template <int W, int TT, int S, bool Shared>
__attribute__((target("avx"))) static void apply_kernel_avx(HAPTIC_MTO_PARAMS) {
  apply_body<W, TT, S, Shared, true>(HAPTIC_MTO_ARGS);
}
#endif

template <int W>
void MultiTermOperator::apply_w(const double* const* u, const double* to_y, const double* to_h, double* y, double* h,
                                double* quad) const {
  static constexpr double kZeros[kMaxTerms] = {};
  if (!to_h) to_h = kZeros;
  const auto args = [&](auto kernel) {
    kernel(rows_, terms_, off_terms_, off_term_.data(), ratio_.data(), diag_.data(), rowptr_.data(), col_.data(), off_.data(), u,
           to_y, to_h, y, h, quad);
  };
  const int key = 10 * terms_ + off_terms_;
  if (shared_) {
#if defined(__x86_64__)
    if (avx_ && key == 42) {
      args(apply_kernel_avx<W, 4, 2, true>);
      return;
    }
#endif
    switch (key) {
      case 42: args(apply_kernel<W, 4, 2, true>); break;
      default: args(apply_kernel<W, -1, -1, true>); break;
    }
    return;
  }
  switch (key) {
    case 10: args(apply_kernel<W, 1, 0, false>); break;
    case 11: args(apply_kernel<W, 1, 1, false>); break;
    case 21: args(apply_kernel<W, 2, 1, false>); break;
    case 41: args(apply_kernel<W, 4, 1, false>); break;
    case 42: args(apply_kernel<W, 4, 2, false>); break;
    default: args(apply_kernel<W, -1, -1, false>); break;
  }
}

void MultiTermOperator::apply(const double* const* u, const double* to_y, const double* to_h, double* y, double* h,
                              double* quad) const {
  if (width_ == 3)
    apply_w<3>(u, to_y, to_h, y, h, quad);
  else
    apply_w<1>(u, to_y, to_h, y, h, quad);
}

namespace {
// apply_consensus's pass. Every quantity is a 4-lane vector over a node's 3 columns (lane 3 unused:
// it carries the next node's first column or 0 and is never stored or summed). The baseline build
// runs the same lane operations in SSE2 pairs, the AVX build in 256-bit registers: the same bits.
struct ConsensusPass {
  int rows, ahead, mask;
  const double* diag;  // rows x 4
  const int* rowptr;
  const int* rel;  // byte offset of an entry's slot from its row's
  const double* off;
  double ratio_k, ratio_p;
  double* ring;    // 3 copies of a ring of mask + 1 slots: node m at (m & mask) + {0, 1, 2} (mask + 1)
  MultiTermOperator::ConsensusInputs in;
  const double* to_y;
  double* y;
  double* quad;
};
[[gnu::always_inline]] inline void consensus_body(const ConsensusPass& a) {
  const int rows = a.rows, mask = a.mask, na = a.in.na, nf = a.in.nf;
  const double nad = static_cast<double>(na);
  double* __restrict ring = a.ring;
  const long span = 8L * (mask + 1);  // one copy of the ring, in doubles
  const auto produce = [&](int m) {  // u_K = x - x_d, u_P = na x - sum xs, as sum_group forms them
    const bool last = m == rows - 1;
    const Lanes4 xm = HAPTIC_NODE_LANES(a.in.x, m, last);
    const Lanes4 d = xm - HAPTIC_NODE_LANES(a.in.x_d, m, last);
    Lanes4 sx = nad * xm;
    for (int n = 0; n < na; ++n) sx -= HAPTIC_NODE_LANES(a.in.xs[n], m, last);
    // three copies, so a row at slot R + (i & mask) reaches every column of its band without a wrap
    double* slot = ring + 8L * (m & mask);
    for (long c = 0; c < 3; ++c) {
      __builtin_memcpy(slot + c * span, &d, sizeof d);
      __builtin_memcpy(slot + c * span + 4, &sx, sizeof sx);
    }
  };
  const int first = std::min(a.ahead, rows);
  for (int m = 0; m < first; ++m) produce(m);
  const double ty0 = a.to_y[0], ty1 = a.to_y[1], ty2 = a.to_y[2], ty3 = a.to_y[3];
  Lanes4 q0 = {}, q1 = {}, q2 = {}, q3 = {};
  for (int i = 0; i < rows; ++i) {
    if (i + a.ahead < rows) produce(i + a.ahead);
    const bool last = i == rows - 1;
    const Lanes4 vi = HAPTIC_NODE_LANES(a.in.v, i, last);
    Lanes4 svi = {};
    for (int n = 0; n < nf; ++n) svi += HAPTIC_NODE_LANES(a.in.vs[n], i, last);
    Lanes4 di, sxi;
    const double* own = ring + span + 8L * (i & mask);
    const char* own_bytes = reinterpret_cast<const char*>(own);
    __builtin_memcpy(&di, own, sizeof di);
    __builtin_memcpy(&sxi, own + 4, sizeof sxi);
    const double* dg = a.diag + 4L * i;
    Lanes4 acc0 = dg[0] * vi, acc1 = dg[1] * di, acc2 = dg[2] * sxi, acc3 = dg[3] * svi;
    Lanes4 ok = {}, op = {};
#pragma GCC unroll 2
    for (int e = a.rowptr[i]; e < a.rowptr[i + 1]; ++e) {
      const double* rj = reinterpret_cast<const double*>(own_bytes + a.rel[e]);
      Lanes4 uk, up;
      __builtin_memcpy(&uk, rj, sizeof uk);
      __builtin_memcpy(&up, rj + 4, sizeof up);
      const double w = a.off[e];
      ok += w * uk;
      op += w * up;
    }
    acc1 += a.ratio_k * ok;
    acc2 += a.ratio_p * op;
    Lanes4 yv = {};
    yv += ty0 * acc0;
    yv += ty1 * acc1;
    yv += ty2 * acc2;
    yv += ty3 * acc3;
    if (!last)
      __builtin_memcpy(a.y + 3L * i, &yv, sizeof yv);  // lane 3 lands on the next row's first column, written next
    else
      HAPTIC_STORE_NODE(a.y, i, yv);
    q0 += vi * acc0;
    q1 += di * acc1;
    q2 += sxi * acc2;
    q3 += svi * acc3;
  }
  if (a.quad) {
    a.quad[0] = lane_sum<3>(q0);
    a.quad[1] = lane_sum<3>(q1);
    a.quad[2] = lane_sum<3>(q2);
    a.quad[3] = lane_sum<3>(q3);
  }
}
void consensus_kernel(const ConsensusPass& a) { consensus_body(a); }
#if defined(__x86_64__)
__attribute__((target("avx"))) void consensus_kernel_avx(const ConsensusPass& a) { consensus_body(a); }
#endif
}  // namespace

void MultiTermOperator::apply_consensus(const ConsensusInputs& in, const double* to_y, double* y, double* quad) {
  ConsensusPass a{rows_, band_ahead_ + 1, ring_mask_, diag_.data(), rowptr_.data(), rel_.data(), off_.data(), ratio_[0], ratio_[1],
                  nullptr, in, to_y, y, quad};
  // 64-byte aligned ring slots: a node's two loads share one cache line
  a.ring = reinterpret_cast<double*>((reinterpret_cast<std::uintptr_t>(ring_.data()) + 63) & ~std::uintptr_t{63});
#if defined(__x86_64__)
  if (avx_) {
    consensus_kernel_avx(a);
    return;
  }
#endif
  consensus_kernel(a);
}

double MultiTermOperator::quadratic_form(const double* u) const {
  const double* us[kMaxTerms];
  for (int t = 0; t < terms_; ++t) us[t] = u;
  static constexpr double kZeros[kMaxTerms] = {};
  double q[kMaxTerms] = {};
  apply(us, kZeros, nullptr, nullptr, nullptr, q);
  return q[0];
}

}  // namespace haptic::rt
