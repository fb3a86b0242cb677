#include "rt/gains.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace haptic::rt {

namespace {
void check_symmetric(const SpatialMatrix& A, const char* what) {
  const SparseRowMajor T = A.S.transpose();
  if ((A.S - T).norm() > 1e-9 * std::max(1.0, A.S.norm()))
    throw std::invalid_argument(std::string(what) + " must be symmetric");
}
double lambda_min_dense_or_gersh(const SpatialMatrix& A) {
  // Lower bound on the smallest eigenvalue: -lambda_max(-A).
  SpatialMatrix neg = A;
  neg.S *= -1.0;
  return -lambda_max(neg);
}
// Gershgorin: every eigenvalue of a symmetric A is >= min_r (a_rr - sum_{c != r} |a_rc|). O(nnz);
// where it proves a sign the eigen-solve above is not needed.
double gershgorin_lower(const SpatialMatrix& A) {
  double low = std::numeric_limits<double>::infinity();
  for (int r = 0; r < A.S.outerSize(); ++r) {
    double diag = 0, off = 0;
    for (SparseRowMajor::InnerIterator it(A.S, r); it; ++it) {
      if (it.col() == r)
        diag += it.value();
      else
        off += std::abs(it.value());
    }
    low = std::min(low, diag - off);
  }
  return low;
}
// A = c I: every stored entry on the diagonal, all equal (none stored: c = 0).
bool scalar_identity(const SpatialMatrix& A, double& c) {
  c = A.S.nonZeros() > 0 ? A.S.valuePtr()[0] : 0.0;
  if (A.S.nonZeros() != 0 && A.S.nonZeros() != A.S.rows()) return false;
  for (int r = 0; r < A.S.outerSize(); ++r)
    for (SparseRowMajor::InnerIterator it(A.S, r); it; ++it)
      if (it.col() != r || it.value() != c) return false;
  return true;
}
bool same_matrix(const SpatialMatrix& a, const SpatialMatrix& b) {
  if (&a == &b) return true;
  const auto& x = a.S;
  const auto& y = b.S;
  if (a.width != b.width || x.rows() != y.rows() || x.nonZeros() != y.nonZeros()) return false;
  const auto nnz = static_cast<std::size_t>(x.nonZeros());
  return std::equal(x.outerIndexPtr(), x.outerIndexPtr() + x.outerSize() + 1, y.outerIndexPtr()) &&
         std::equal(x.innerIndexPtr(), x.innerIndexPtr() + nnz, y.innerIndexPtr()) && std::equal(x.valuePtr(), x.valuePtr() + nnz, y.valuePtr());
}
// Eq. (18)'s coefficients of neighbour n's P_ij and D_ij: c_P = (N_ij + N_ji)/2 T_j^max and
// c_D = max(0, (T_j^max / T_i^min - 1)/2).
struct Eq18Coefficients {
  double P, D;
};
Eq18Coefficients eq18_coefficients(double t_min_i, const Eq18Neighbor& n) {
  const double cP = n.round_trip_ticks / 2.0 * n.t_max_j_s;
  const double cD = 0.5 * (n.t_max_j_s / t_min_i - 1.0);
  return {cP, std::max(0.0, cD)};
}
// Eq. (18)'s lambda_max(sum_j c_P,j P + c_D,j d_j I) = sum_j c_P,j lambda_max(P) + sum_j c_D,j d_j
// when every neighbour has the same P and a scalar D (the paper's gains): the terms share their
// eigenvectors. Used above kDenseEigenRows, where the alternative is a power iteration on the sum
// per station (below, the dense solver keeps its own bits). False: not that case.
bool eq18_shared_gains(double t_min_i, std::span<const Eq18Neighbor> nb, double& beta) {
  const EdgeGains& g0 = *nb.front().gains;
  if (g0.P.S.rows() <= kDenseEigenRows) return false;
  double cP = 0, cD = 0;
  for (const auto& n : nb) {
    double d = 0;
    if (!same_matrix(n.gains->P, g0.P) || !scalar_identity(n.gains->D, d)) return false;
    const Eq18Coefficients c = eq18_coefficients(t_min_i, n);
    cP += c.P;
    cD += c.D * d;
  }
  beta = cP * g0.lambda_max_P + cD;
  return true;
}
}  // namespace

namespace {
// P and D checked; their largest eigenvalues computed, or taken from `known` ({P's, D's}) when given.
EdgeGains checked_gains(const SpatialMatrix& P, const SpatialMatrix& D, const double* known) {
  check_symmetric(P, "P_ij");
  check_symmetric(D, "D_ij");
  if (P.dofs() != D.dofs()) throw std::invalid_argument("P_ij and D_ij must have the same size");
  EdgeGains g;
  g.P = P;
  g.D = D;
  g.lambda_max_P = known ? known[0] : lambda_max(P);
  g.lambda_max_D = known ? known[1] : lambda_max(D);
  if (!(gershgorin_lower(P) > 0) && !(lambda_min_dense_or_gersh(P) > 0)) throw std::invalid_argument("P_ij must be positive definite");
  if (gershgorin_lower(D) < 0 && lambda_min_dense_or_gersh(D) < -1e-9 * std::max(1.0, g.lambda_max_D))
    throw std::invalid_argument("D_ij must be positive semidefinite");
  g.description = "matrix gains";
  return g;
}
}  // namespace

EdgeGains matrix_edge_gains(const SpatialMatrix& P, const SpatialMatrix& D) { return checked_gains(P, D, nullptr); }

bool same_gains(const EdgeGains& a, const EdgeGains& b) { return same_matrix(a.P, b.P) && same_matrix(a.D, b.D); }

EdgeGains paper_edge_gains(const Scene& scene, double p, double d) {
  if (!(p > 0)) throw std::invalid_argument("consensus.p_N_per_m must be > 0");
  if (!(d >= 0)) throw std::invalid_argument("consensus.d_Ns_per_m must be >= 0");
  const SpatialMatrix I = SpatialMatrix::identity(scene.nodes);
  // lambda_max(P) = p/2 + p/2 lambda_max(K_int)/lambda_max_K_int = p and lambda_max(D) = d: given
  // above kDenseEigenRows, where each would be a power iteration; below, the dense solver's values.
  const double known[2] = {p, d};
  EdgeGains g = checked_gains(linear_combination({{p / 2, &I}, {p / (2 * scene.lambda_max_K_int), &scene.K_int}}),
                              SpatialMatrix::identity(scene.nodes, d), scene.nodes > kDenseEigenRows ? known : nullptr);
  std::ostringstream os;
  os << "P = " << p << "[I/2 + K_int/(2 lambda_max)], D = " << d << " I";
  g.description = os.str();
  return g;
}

EdgeGains scalar_edge_gains(int nodes, double p, double d) {
  if (!(p > 0)) throw std::invalid_argument("consensus.p_N_per_m must be > 0");
  if (!(d >= 0)) throw std::invalid_argument("consensus.d_Ns_per_m must be >= 0");
  EdgeGains g;
  g.P = SpatialMatrix::identity(nodes, p);
  g.D = SpatialMatrix::identity(nodes, d);
  g.lambda_max_P = p;
  g.lambda_max_D = d;
  std::ostringstream os;
  os << "P = " << p << " I, D = " << d << " I";
  g.description = os.str();
  return g;
}

double damping_min_eq18(double t_min_i, std::span<const Eq18Neighbor> nb) {
  if (!(t_min_i > 0)) throw std::invalid_argument("eq. (18): T_i^min must be > 0");
  if (nb.empty()) return 0.0;
  for (const auto& n : nb) {
    if (!n.gains) throw std::invalid_argument("eq. (18): neighbour without gains");
    if (!(n.round_trip_ticks >= 0)) throw std::invalid_argument("eq. (18): round trip must be >= 0");
    if (!(n.t_max_j_s >= t_min_i * 0 && n.t_max_j_s > 0)) throw std::invalid_argument("eq. (18): T_j^max must be > 0");
  }
  double beta = 0;
  if (eq18_shared_gains(t_min_i, nb, beta)) return std::max(0.0, beta);
  // Build sum_j c_P P_ij + c_D D_ij and take its largest eigenvalue (exact PSD bound for B_i = beta I).
  SpatialMatrix acc;
  bool first = true;
  for (const auto& n : nb) {
    const Eq18Coefficients c = eq18_coefficients(t_min_i, n);
    SpatialMatrix term = linear_combination({{c.P, &n.gains->P}, {c.D, &n.gains->D}});
    acc = first ? term : linear_combination({{1.0, &acc}, {1.0, &term}});
    first = false;
  }
  return std::max(0.0, lambda_max(acc));
}

void check_eq26(const VirtualCouplingGains& g, double b_d, double T, double ratio) {
  auto fail = [](const std::string& s) { throw std::invalid_argument(s); };
  if (!(T > 0)) fail("period_s must be > 0");
  if (!(ratio >= 1.0)) fail("max_period_ratio must be >= 1");
  if (!(g.K_vc_N_per_m > 0)) fail("virtual_coupling.K_vc_N_per_m must be > 0");
  if (!(g.B_vc_Ns_per_m >= 0)) fail("virtual_coupling.B_vc_Ns_per_m must be >= 0");
  if (!(g.b_v_Ns_per_m >= 0)) fail("virtual_coupling.b_v_Ns_per_m must be >= 0");
  const double need_bd = g.B_vc_Ns_per_m * (ratio + 1.0) + g.K_vc_N_per_m * T;
  const double need_bv = g.B_vc_Ns_per_m / 2.0 * (ratio - 1.0) + g.K_vc_N_per_m * T / 2.0;
  if (b_d < need_bd) {
    std::ostringstream os;
    os << "eq. (26) violated: device damping b_d = " << b_d << " N s/m < B_vc (T_k/T_k-1 + 1) + K_vc T = " << need_bd
       << " N s/m; lower virtual_coupling.K_vc_N_per_m or B_vc_Ns_per_m, or use a device with more damping";
    fail(os.str());
  }
  if (g.b_v_Ns_per_m < need_bv) {
    std::ostringstream os;
    os << "eq. (26) violated: virtual_coupling.b_v_Ns_per_m = " << g.b_v_Ns_per_m << " < B_vc/2 (T_k/T_k-1 - 1) + K_vc T/2 = "
       << need_bv;
    fail(os.str());
  }
}

double max_K_vc_eq26(const VirtualCouplingGains& g, double b_d, double T, double ratio) {
  const double from_bd = (b_d - g.B_vc_Ns_per_m * (ratio + 1.0)) / T;
  const double from_bv = (2.0 * g.b_v_Ns_per_m - g.B_vc_Ns_per_m * (ratio - 1.0)) / T;
  return std::min(from_bd, from_bv);
}

}  // namespace haptic::rt
