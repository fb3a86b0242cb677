#pragma once
// Several sparse matrices A_1..A_T of one scene applied to their own vectors in ONE pass over a
// shared sparsity pattern (the tick's right-hand side and energies, DESIGN.md "The linear step"):
//
//   y = sum_t to_y[t] A_t u_t,   h = sum_t to_h[t] A_t u_t,   quad[t] = u_t^T A_t u_t
//
// Each A_t is stored as its diagonal (one value per row) plus its off-diagonal values on the
// union of the terms' off-diagonal patterns; a term with no off-diagonal entries (M, B, D = d I in
// the paper) costs only its diagonal. Compared with one multiply_add per matrix this reads the
// pattern and writes y once instead of T times. Isotropic terms (S (x) I3) work on node rows with
// three interleaved columns; if any term is not isotropic every term is expanded to 3n x 3n.
// When the off-diagonal values of every term are multiples of the first's (the paper's P =
// p[I/2 + K_int/(2 lambda_max)] and K = K_int + k_g I: both off-diagonals are multiples of K_int's),
// only the first term's values are stored and term s applies ratio_s x those (relative difference
// to its own values at most 1e-14 per entry, checked at construction): one value stream per pass
// instead of one per term (shared_values()).
#include <vector>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

class MultiTermOperator {
 public:
  static constexpr int kMaxTerms = 8;
  MultiTermOperator() = default;
  // Start-up (allocates). Throws std::invalid_argument on size mismatch or more than kMaxTerms.
  explicit MultiTermOperator(const std::vector<const SpatialMatrix*>& terms);

  int terms() const { return terms_; }
  int width() const { return width_; }  // 3: node rows with three columns; 1: dof rows
  long stored_doubles() const;
  bool shared_values() const { return shared_; }
  // The shared-values kernel runs an AVX build (4 lanes per block) when the CPU has AVX; it gives
  // the same results bit for bit. Tests: false forces the scalar build; returns whether AVX is used.
  bool use_avx(bool allow);

  // One pass: u[t] is term t's input (3n interleaved); y and h (each if not null; written, not
  // accumulated) receive the weighted sums; quad (if not null, terms() values, written) receives
  // u_t^T A_t u_t. RT-safe: no allocation, one pass over the pattern.
  void apply(const double* const* u, const double* to_y, const double* to_h, double* y, double* h, double* quad) const;

  // u^T A_0 u for a one-term operator (or term 0 of several). RT-safe, one pass, writes nothing.
  double quadratic_form(const double* u) const;

  // The tick's right-hand side (DESIGN.md step 4) in ONE pass, for the operator [M, K, P_0, D_0]
  // with shared off-diagonal values (the paper's gains): the terms' inputs are formed in the pass,
  //   u_M = v, u_K = x - x_d, u_P = na x - sum_n xs[n], u_D = sum_n vs[n],
  // u_K and u_P a band ahead of the rows into a small ring (the columns a row reads; L1/L2 sized),
  // u_M and u_D row by row; nothing of them is written to memory. y and quad as apply(). y equals
  // apply() on those inputs bit for bit; quad is summed per column, then over the columns.
  struct ConsensusInputs {
    const double* v = nullptr;
    const double* x = nullptr;
    const double* x_d = nullptr;
    const double* const* xs = nullptr;  // the active neighbours' x_hat (na of them)
    int na = 0;
    const double* const* vs = nullptr;  // the fresh neighbours' v_hat (nf of them)
    int nf = 0;
  };
  bool fuses_consensus() const { return ring_mask_ > 0; }  // [M, K, P, D], shared, isotropic, band fits
  // Writes the operator's ring (not const; not for concurrent calls on one operator).
  void apply_consensus(const ConsensusInputs& in, const double* to_y, double* y, double* quad);
  int ring_nodes() const { return ring_mask_ + 1; }

 private:
  // Start-up: apply_consensus's ring of input columns, when the terms are [M, K, P, D] as it needs.
  void prepare_consensus_ring();
  template <int W>
  void apply_w(const double* const* u, const double* to_y, const double* to_h, double* y, double* h, double* quad) const;
  int rows_ = 0, width_ = 3, terms_ = 0, off_terms_ = 0;
  bool shared_ = false;         // off_ holds slot 0's values only; slot s scales them by ratio_[s]
  bool avx_ = false;            // the CPU runs the AVX build of the shared kernel (same results)
  std::vector<double> ratio_;   // per slot (1 for slot 0)
  std::vector<int> off_term_;   // slot s -> term index (terms that have off-diagonal entries)
  std::vector<double> diag_;    // rows x terms
  std::vector<int> rowptr_, col_;
  std::vector<double> off_;     // nnz x off_terms (values of each slot on the union pattern)
  // apply_consensus: ring of ring_mask_ + 1 nodes (a power of two > the band's width), 8 doubles per
  // node [u_K 3, pad, u_P 3, pad] (one cache line), kept three times over so a row addresses its
  // columns by a fixed byte offset (rel_) without a wrap; node m at m & ring_mask_. 0: no fusion.
  int ring_mask_ = 0, band_ahead_ = 0;
  std::vector<int> rel_;
  std::vector<double> ring_;
};

}  // namespace haptic::rt
