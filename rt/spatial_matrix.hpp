#pragma once
// A 3n x 3n matrix over the interleaved node coordinates [x1 y1 z1 x2 ...] of a scene, stored
// either as S (x) I3 with S node-level n x n ("isotropic", width 3) or as a full 3n x 3n S
// (width 1). The paper's M, K_int (K_rs = k I3), B, P_ij and D_ij are all isotropic, which lets
// the step factor an n x n matrix and solve three right-hand sides; general matrix gains
// (any SPD P_ij) still work through the full form.
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <initializer_list>
#include <utility>

namespace haptic::rt {

using SparseRowMajor = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;
using SparseColMajor = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// d^T A d and r^T A d (pair_forms below).
struct PairForms {
  double dAd = 0, rAd = 0;
};

struct SpatialMatrix {
  int width = 3;     // 3: operator is S (x) I3, S n x n;  1: operator is S, 3n x 3n
  SparseRowMajor S;  // compressed

  static SpatialMatrix isotropic(const SparseRowMajor& node_level);
  static SpatialMatrix full(const SparseRowMajor& dof_level);
  static SpatialMatrix identity(int nodes, double scale = 1.0);

  int dofs() const { return width == 3 ? static_cast<int>(S.rows()) * 3 : static_cast<int>(S.rows()); }
  bool is_isotropic() const { return width == 3; }
  // The 3n x 3n matrix (allocates; start-up only).
  SparseRowMajor as_full() const;
  // y += alpha * (this) * x on interleaved 3n vectors. RT-safe: no allocation.
  void multiply_add(double alpha, const double* x, double* y) const;
  // d^T (this) d and r^T (this) d in one pass over the rows, without forming (this) d (the
  // set-position modulation's two forms per edge and tick). Isotropic: a node's three columns in 4
  // lanes (rt/lanes.hpp), its AVX build when the CPU has AVX and allow_avx, the same bits either
  // way; full: scalar. Sums in another order than multiply_add then dot products: equal to those
  // up to rounding. RT-safe: no allocation.
  PairForms pair_forms(const double* d, const double* r, bool allow_avx = true) const;
  // pair_forms for m pairs (d[e], r[e]) in passes of up to three pairs each, a row's values and
  // columns read once a pass (the set-position modulators of a gain group's edges, which share P);
  // out[e] has the same bits as pair_forms(d[e], r[e]). RT-safe: no allocation.
  void pair_forms_many(const double* const* d, const double* const* r, int m, PairForms* out, bool allow_avx = true) const;
};

// sum_k c_k A_k. Isotropic if every term is isotropic. Start-up only (allocates).
SpatialMatrix linear_combination(std::initializer_list<std::pair<double, const SpatialMatrix*>> terms);

// Largest eigenvalue of a symmetric SpatialMatrix (dense solver up to kDenseEigenRows rows of S,
// Lanczos-free power iteration with a verified residual beyond). Start-up only.
inline constexpr int kDenseEigenRows = 600;
double lambda_max(const SpatialMatrix& A);

}  // namespace haptic::rt
