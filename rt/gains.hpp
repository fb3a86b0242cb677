#pragma once
// Consensus gains of eq. (15) on one undirected edge (P_ij = P_ji, D_ij = D_ji, eq. 16) and
// the passivity conditions (18) and (26). Start-up only.
#include <span>
#include <string>
#include <vector>

#include "rt/scene.hpp"

namespace haptic::rt {

struct EdgeGains {
  SpatialMatrix P;  // N/m, symmetric positive definite
  SpatialMatrix D;  // N s/m, symmetric positive definite (semidefinite allowed, footnote 3)
  double lambda_max_P = 0;
  double lambda_max_D = 0;
  std::string description;
};

// The paper's gains (Section V): P_ij = p [I/2 + K_int / (2 lambda_max(K_int))], D_ij = d I.
EdgeGains paper_edge_gains(const Scene& scene, double p_N_per_m = 1000.0, double d_Ns_per_m = 5.0);
// Scalar gains: P_ij = p I, D_ij = d I.
EdgeGains scalar_edge_gains(int nodes, double p_N_per_m, double d_Ns_per_m);
// Any matrices (checked symmetric; P positive definite, D positive semidefinite).
EdgeGains matrix_edge_gains(const SpatialMatrix& P, const SpatialMatrix& D);
// The same P and D, stored alike, value for value (two copies of one edge's gains). Start-up only.
bool same_gains(const EdgeGains& a, const EdgeGains& b);

// One neighbour j of station i as eq. (18) sees it.
struct Eq18Neighbor {
  double round_trip_ticks = 0;  // bound on Nbar_ij + Nbar_ji (measured round trip, in ticks)
  double t_max_j_s = 0;         // T_j^max
  const EdgeGains* gains = nullptr;
};

// Smallest scalar B_i = beta I satisfying eq. (18) in the positive-semidefinite sense:
// beta = lambda_max( sum_j [ (Nbar_ij+Nbar_ji)/2 T_j^max P_ij + 1/2 (T_j^max/T_i^min - 1) D_ij ] ).
double damping_min_eq18(double t_min_i_s, std::span<const Eq18Neighbor> neighbors);

// Virtual coupling of Section III-C.
struct VirtualCouplingGains {
  double b_v_Ns_per_m = 2.0;     // extra VP damping b_v
  double B_vc_Ns_per_m = 0.0;    // coupling damping B_vc
  double K_vc_N_per_m = 200.0;   // coupling stiffness K_vc
};

// Eq. (26): b_d >= B_vc (T_k/T_{k-1} + 1) + K_vc T_k and b_v >= B_vc/2 (T_k/T_{k-1} - 1) + K_vc T_k / 2.
// Throws std::invalid_argument naming the gain that violates it.
void check_eq26(const VirtualCouplingGains& g, double device_damping_b_d_Ns_per_m, double period_s,
                double max_period_ratio = 1.0);
// The largest K_vc for which eq. (26) holds with b_d, B_vc, b_v and T as given: min over its two
// inequalities solved for K_vc, (b_d - B_vc (r + 1)) / T and (2 b_v - B_vc (r - 1)) / T (r =
// T_k/T_{k-1}). <= 0: no K_vc > 0 satisfies it (B_vc alone is too large). Not RT-relevant (start-up).
double max_K_vc_eq26(const VirtualCouplingGains& g, double device_damping_b_d_Ns_per_m, double period_s,
                     double max_period_ratio = 1.0);

}  // namespace haptic::rt
