#pragma once
// Per-edge split of eq. (14)'s consensus-controller energy at one station i. Eq. (15) gives, per
// tick k, the energy the controller port passes into the VO copy:
//
//   s_i(k) = v_hat_i^T tau_i T = -T |v_hat_i|^2_{B_i}
//            - sum_j T v_hat_i^T [ D_ij (v_hat_i - delta_ij v_hat_j) + P_ij (x_hat_i - x_hat_j) ]
//
// Edge j's account is its own coupling term plus its share w_j of the local-damping term
// (eq. 18's B_i is a sum over the edges, so each edge owns the part of B_i it requires; shares
// are normalized at start-up, equal by default). The accounts add up to eq. (14)'s total:
//   sum_j edge_J(j) + unshared_damping_J() == the station's EnergyMonitor::controller_J
// (unshared_damping_J is B_i's energy while the station has no edge). A positive account is energy
// the edge has put into the copy: eq. (14) bounds it, so the per-edge damage bound (issue 11) and
// the adaptive passivity controller (issue 15) read it.
#include <array>
#include <cstdint>
#include <span>

namespace haptic::rt {

inline constexpr int kMaxEdgeAccounts = 16;

class EdgeEnergyAccount {
 public:
  // Start-up (throws std::invalid_argument on bad input): the number of edges and each edge's
  // share of B_i (>= 0, finite; normalized to sum 1; empty or all zero: equal shares).
  void init(int edges, std::span<const double> damping_share = {});

  // One tick: coupling_J[j] = -T v_hat_i^T [D_ij (v_hat_i - delta v_hat_j) + P_ij (x_hat_i - x_hat_j)]
  // for each edge (coupling_J.size() == edges()), damping_J = -T |v_hat_i|^2_{B_i} <= 0. RT-safe.
  void record_tick(std::span<const double> coupling_J, double damping_J);

  int edges() const { return edges_; }
  double share(int j) const { return share_[idx(j)]; }
  double coupling_J(int j) const { return coupling_[idx(j)]; }        // cumulative own coupling term
  double damping_J(int j) const { return damping_[idx(j)]; }          // cumulative share of B_i's term (<= 0)
  double edge_J(int j) const { return coupling_[idx(j)] + damping_[idx(j)]; }  // the account
  double last_tick_J(int j) const { return last_[idx(j)]; }           // the account's change in the last tick
  double peak_J(int j) const { return peak_[idx(j)]; }                // max over time of edge_J(j) (>= 0)
  double unshared_damping_J() const { return unshared_; }
  double total_J() const;  // sum_j edge_J(j) + unshared_damping_J(): eq. (14)'s total
  std::uint64_t ticks() const { return ticks_; }

 private:
  static std::size_t idx(int j) { return static_cast<std::size_t>(j); }
  int edges_ = 0;
  std::array<double, kMaxEdgeAccounts> share_{}, coupling_{}, damping_{}, last_{}, peak_{};
  double unshared_ = 0;
  std::uint64_t ticks_ = 0;
};

}  // namespace haptic::rt
