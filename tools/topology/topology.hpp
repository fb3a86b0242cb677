#pragma once
// Network topology optimization of Section IV (eq. 27).
//
// The first-order information-mixing model
//     p_i(k+1) = s p_i(k) + (1-s) (sum_{j in N_i} P_ij)^{-1} sum_{j in N_i} P_ij p_j(k - N_ij)
// (s = self weight, 0 in the paper) is lifted to the companion matrix J(G, P_ij, N_ij) of size
// nN(Nbar+1) with blocks A_0..A_Nbar (A_k^ij = (sum P)^-1 P_ij when k = N_ij), and graphs are
// ranked by |lambda_{n+1}(J)|, the largest eigenvalue modulus after the n eigenvalues at 1.
// N_ij = round(mean delay_ij / T) (row i receives from column j).
//
// Structure used (exact, stated in every result):
//  * SingleMode: every edge's P_ij = a_ij I + b_ij K_hat with (a_ij, b_ij) all proportional
//    (the paper's P_ij = 1000[I/2 + K_int/(2 lambda_max)] on every link). Then the normalized
//    weights do not depend on the mode and one scalar problem of size N(Nbar+1) is exact.
//  * ModeSplit: P_ij = a_ij I + b_ij K_hat with K_hat symmetric: J splits by the eigen-modes mu
//    of K_hat into n scalar problems with weights p_ij(mu) = a_ij + b_ij mu; lambda_{n+1} is the
//    largest second-modulus over the distinct modes.
//  * GeneralDense: explicit n x n P_ij blocks; the dense lifted matrix (small n and Nbar only).
// Eigenvalue methods for the scalar problem:
//  * Dense: nonsymmetric eigensolve of the lifted matrix (Eigen), O(L^3), L = N(Nbar+1).
//  * Power: shift-free, matrix-free growth rate of the deflated delay recursion. The lifted state
//    is a ring buffer of the last Nbar+1 information vectors, so one product costs O(N + |E|);
//    the consensus direction is removed exactly with the left eigenvector u at 1
//    (u_l = sum_{m>=l} A_m^T pi, pi the left Perron vector of sum_m A_m) every few steps, the state
//    is renormalized, and |lambda_{n+1}| = exp(slope of log ||x_k||) fitted over doubling windows
//    until two windows agree within power_tol. Only the modulus is needed, so rings of eigenvalues
//    of equal modulus (typical of long delays) do not slow it, unlike Krylov methods.
//    Accuracy is about power_tol in |lambda| (window-fit error ~ 1/steps); the projection every
//    16 steps assumes |lambda_{n+1}|^16 >> 1e-16, i.e. |lambda_{n+1}| > ~0.2 (consensus problems
//    of interest sit near 1; use Dense for fast-mixing toy cases).
//  * Arnoldi: Krylov-Schur restarted Arnoldi (complex arithmetic) on J - 1 u^T. Kept for
//    comparison: on long-delay problems the outer spectrum is a dense ring and it can converge to
//    Ritz values inside it (tests and README show where).
// Tests check Power and Arnoldi against Dense.
//
// Offline tool math: allocates freely, NOT real-time safe, never called from the tick.
#include <Eigen/Core>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace haptic::topology {

// The graph type, its parser and the delay model are the simulator's and the station's
// (firmware/model): one implementation, used here by name.
using Edge = model::Link;
using Graph = model::Graph;
using model::is_connected;
using model::normalized;
using model::parse_graph_1based;
using model::to_string_1based;
using model::paper_delay_matrix_ms;

// Per-edge gains as polynomials in one symmetric matrix K_hat: P_ij = a(i,j) I + b(i,j) K_hat.
// mode_values: the eigenvalues of K_hat (any multiplicities; n = size). When empty, n = 1 and
// mu = 0 is the only mode (scalar information state).
struct PolynomialGains {
  Eigen::MatrixXd a;            // N x N
  Eigen::MatrixXd b;            // N x N
  Eigen::VectorXd mode_values;  // eigenvalues of K_hat
};
PolynomialGains uniform_gains(int users, double a, double b, const Eigen::VectorXd& mode_values);
// The paper's P_ij = 1000 [I/2 + K_int / (2 lambda_max(K_int))]: a = b = 500, K_hat = K_int/lambda_max.
PolynomialGains paper_gains(int users, const Eigen::VectorXd& k_hat_eigenvalues);

// Explicit dense blocks: blocks[i*N + j] is P_ij (n x n), used only for the graph's edges.
struct DenseGains {
  int n = 1;
  std::vector<Eigen::MatrixXd> blocks;
};

enum class StructurePath { SingleMode, ModeSplit, GeneralDense };
enum class EigenMethod { Auto, Dense, Power, Arnoldi };
const char* to_string(StructurePath p);
const char* to_string(EigenMethod m);

struct SpectrumOptions {
  EigenMethod method = EigenMethod::Auto;
  int dense_max_size = 200;      // Auto: dense eigensolve up to this lifted size, Power above
  double self_weight = 0.0;      // s in [0, 1); 0 = the paper's model
  int arnoldi_wanted = 6;        // Ritz values kept at restart
  int arnoldi_subspace = 40;     // Krylov subspace size
  int arnoldi_max_restarts = 2000;
  double arnoldi_tol = 1e-10;    // residual ||J'x - theta x|| / |theta| for the leading Ritz pairs
  double mode_merge_tol = 1e-9;  // mode values closer than this are one mode
  double power_tol = 1e-6;       // Power: stop when two successive window estimates of
                                 // |lambda_2| differ by less than this
  long power_max_steps = 1L << 22;
};

struct GraphScore {
  double lambda_next_abs = 1.0;  // |lambda_{n+1}(J)|, eq. (27)
  StructurePath path = StructurePath::SingleMode;
  EigenMethod method = EigenMethod::Dense;  // the one actually used (never Auto)
  int lifted_size = 0;           // size of each scalar problem (or of the dense J)
  int nbar = 0;                  // max N_ij over the graph's directed links
  int modes_evaluated = 1;       // distinct scalar problems solved
  double worst_mode_value = 0;   // mu attaining lambda_{n+1} (ModeSplit)
  int arnoldi_restarts = 0;      // summed over modes
  bool converged = true;         // Arnoldi converged (always true for Dense)
};

// Scalar problem helpers (exposed for tests).
// Row-normalized weights w_ij = p_ij / sum_{k in N_i} p_ik on the graph (p: N x N, positive on edges).
Eigen::MatrixXd mixing_weights(const Graph& g, int users, const Eigen::MatrixXd& p);
// Dense lifted scalar J of size N(Nbar+1), Nbar = max steps over the graph's directed links.
Eigen::MatrixXd lifted_scalar_matrix(const Graph& g, const Eigen::MatrixXd& weights,
                                     const Eigen::MatrixXi& steps, double self_weight);
// Dense lifted matrix for explicit blocks, size nN(Nbar+1).
Eigen::MatrixXd lifted_dense_matrix(const Graph& g, int users, const DenseGains& gains,
                                    const Eigen::MatrixXi& steps, double self_weight);
// All eigenvalues of a dense matrix sorted by decreasing modulus.
Eigen::VectorXcd eigenvalues_by_modulus(const Eigen::MatrixXd& m);

struct ScalarSpectrum {
  double second_modulus = 1.0;   // largest |lambda| after the one at 1
  EigenMethod method = EigenMethod::Dense;
  int lifted_size = 0;
  int nbar = 0;
  int restarts = 0;              // Arnoldi restarts, or Power steps / 1000
  bool converged = true;
};
ScalarSpectrum scalar_second_modulus(const Graph& g, const Eigen::MatrixXd& weights,
                                     const Eigen::MatrixXi& steps, const SpectrumOptions& opt);

// eq. (27) for one graph. Throws std::invalid_argument for a disconnected graph, non-positive
// mode weights or mismatched sizes (message names the input).
GraphScore score_graph(const Graph& g, const Eigen::MatrixXd& mean_delay_ms, double period_s,
                       const PolynomialGains& gains, const SpectrumOptions& opt);
GraphScore score_graph_dense(const Graph& g, const Eigen::MatrixXd& mean_delay_ms, double period_s,
                             const DenseGains& gains, const SpectrumOptions& opt);

// Feasible set: every connected graph on `users` with exactly `links` undirected links, each
// degree <= degree_cap (0: no cap), using only pairs with allowed(i,j) (empty: all pairs).
// Throws when more than max_candidates link subsets would have to be examined.
std::vector<Graph> enumerate_connected_graphs(int users, int links, int degree_cap,
                                              std::uint64_t max_candidates,
                                              const Eigen::MatrixXi& allowed = {});

// Heuristic search where enumeration is impossible (N = 16..64):
//  1. seeds: a degree-capped minimum spanning tree on round-trip delay, and degree-capped
//     shortest-path trees from the `hub_seeds` most central users; extra links (links > N-1)
//     are added cheapest round trip first; the best seed by eq. (27) is kept;
//  2. local search by edge swaps (remove a link, add a link that keeps the graph connected and
//     within the cap), candidates ordered by round trip, first improvement, until no swap
//     improves;
//  3. iterated local search: `kicks` times, apply `kick_swaps` seeded random swaps to the best
//     graph and descend again, keeping the best; everything stops when max_evaluations is spent.
struct SearchOptions {
  int links = 0;                 // 0: N-1 (a tree)
  int degree_cap = 0;            // 0: none
  int hub_seeds = 3;
  int remove_candidates = 8;     // links tried for removal per pass (longest round trip first)
  int add_candidates = 6;        // reconnecting links tried per removal (shortest first)
  int kicks = 10;                // iterated-local-search restarts
  int kick_swaps = 2;            // random swaps per kick
  std::uint64_t seed = 1;        // of the kicks (deterministic)
  int max_evaluations = 500;
};
struct SearchResult {
  Graph best;
  GraphScore best_score;
  Graph seed;                    // best seed before local search
  GraphScore seed_score;
  int evaluations = 0;
  int improvements = 0;
  std::vector<double> history;   // best |lambda_{n+1}| after each accepted move (first: seed)
};
SearchResult search_topology(const Eigen::MatrixXd& mean_delay_ms, double period_s,
                             const PolynomialGains& gains, const SpectrumOptions& spectrum,
                             const SearchOptions& search);

// Reproducible synthetic delays: users on a seeded width x height km map,
// delay_ij = base_ms + distance / speed_km_per_ms, times a per-direction factor in
// [1 - asymmetry, 1 + asymmetry]. positions_km receives N x 2 coordinates.
struct SyntheticMap {
  double width_km = 8000.0;
  double height_km = 4000.0;
  double base_ms = 2.0;
  double speed_km_per_ms = 100.0;  // fibre ~200 km/ms, halved for routing detours
  double asymmetry = 0.2;
  std::uint64_t seed = 1;
};
Eigen::MatrixXd synthetic_delays_ms(int users, const SyntheticMap& map, Eigen::MatrixXd* positions_km);

}  // namespace haptic::topology
