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
// the edge has put into the copy: eq. (14) bounds it, so the per-edge damage bound and
// the adaptive passivity controller read it.
#include <array>
#include <cstdint>
#include <limits>
#include <span>

namespace haptic::rt {

inline constexpr int kMaxEdgeAccounts = 16;
// The default per-edge damage bound of the simulator and the station (station.edge_energy_bound_J,
// sim --edge-energy-bound; 0 = off): net/README.md, "Bounded damage from an authenticated peer".
inline constexpr double kDefaultEdgeEnergyBoundJ = 0.1;
// The default leak of the accounts (station.edge_energy_leak_W, sim --edge-energy-leak-W): 1 mW, about
// 8x the average inflow measured at a station that only receives (0.13 mW; rt/README.md).
inline constexpr double kDefaultEdgeEnergyLeakW = 1e-3;
// The station's default timed release of a tripped edge (station.edge_energy_hold_s; the simulator's
// --edge-energy-hold-s default is 0, off): held this long x 2^(trips - 1), like the state check's
// re-admission (station.state_check_readmit_s).
inline constexpr double kDefaultEdgeEnergyHoldS = 2.0;

class EdgeEnergyAccount {
 public:
  // Start-up (throws std::invalid_argument on bad input): the number of edges and each edge's
  // share of B_i (>= 0, finite; normalized to sum 1; empty or all zero: equal shares).
  void init(int edges, std::span<const double> damping_share = {});

  // One tick: coupling_J[j] = -T v_hat_i^T [D_ij (v_hat_i - delta v_hat_j) + P_ij (x_hat_i - x_hat_j)]
  // for each edge (coupling_J.size() == edges()), damping_J = -T |v_hat_i|^2_{B_i} <= 0. RT-safe.
  void record_tick(std::span<const double> coupling_J, double damping_J);

  // The leak (rt/README.md "The per-edge energy bound"): the power, W per edge (>= 0, finite; empty:
  // none), up to which energy that demonstrably LEFT the copy is taken off the edge's account, so an
  // honest station that only receives (energy from its neighbours, dissipated by its object and its
  // user) does not fill its accounts over a long session. Start-up; throws std::invalid_argument.
  void set_leak(std::span<const double> leak_W);
  // One tick's outflow: energy that left the copy other than through the controller port (the
  // contact port towards the user, the object's damping, the solver) = that tick's controller energy
  // minus the copy's energy change. Each edge with a positive account is credited its share of a
  // positive outflow, at most leak_W x T and never below 0. RT-safe.
  void credit_outflow(double outflow_J, double T);

  int edges() const { return edges_; }
  double share(int j) const { return share_[idx(j)]; }
  double coupling_J(int j) const { return coupling_[idx(j)]; }        // cumulative own coupling term
  double damping_J(int j) const { return damping_[idx(j)]; }          // cumulative share of B_i's term (<= 0)
  double credited_J(int j) const { return credited_[idx(j)]; }      // cumulative outflow credit (>= 0)
  double edge_J(int j) const { return coupling_[idx(j)] + damping_[idx(j)] - credited_[idx(j)]; }  // the account
  double last_tick_J(int j) const { return last_[idx(j)]; }           // the account's change in the last tick
  double peak_J(int j) const { return peak_[idx(j)]; }                // max over time of edge_J(j) (>= 0)
  double unshared_damping_J() const { return unshared_; }
  double total_J() const;  // sum_j (coupling_J(j) + damping_J(j)) + unshared_damping_J(): eq. (14)'s total
  std::uint64_t ticks() const { return ticks_; }

 private:
  static std::size_t idx(int j) { return static_cast<std::size_t>(j); }
  int edges_ = 0;
  std::array<double, kMaxEdgeAccounts> share_{}, coupling_{}, damping_{}, last_{}, peak_{}, leak_W_{}, credited_{};
  double unshared_ = 0;
  std::uint64_t ticks_ = 0;
};

// The per-edge damage bound (argument in net/README.md, "Bounded damage from an
// authenticated peer", and rt/README.md): edge j trips when its account edge_J(j) exceeds
// bound_J(j) and stays tripped (latched) until the account has fallen to release_J(j) < bound_J(j)
// (hysteresis). While tripped the station applies the over-bound action to the edge (the damper
// D_ij + T/2 P_ij: its account can only fall), so the net energy the edge ever puts into the
// copy is at most bound_J + one tick's. The decision is taken at the start of a tick from the
// account after the previous tick.
//
// The timed release (hold_ticks > 0; rt/README.md "The timed release"): a tripped edge whose account
// stays above the release level (a damper only dissipates what this copy's own motion gives it; a
// leaf at rest never gets there) is released after it has stayed within its account (tripped, the
// damper, its account only falling) for hold_ticks x 2^(n - 1) ticks, n = its trips so far (at most
// x 1024): the excess of its account over the release level is then forgiven (forgiven_J: the gate
// compares account - forgiven with its levels; the account itself stays the true one). A neighbour
// that lies again trips again after at most bound - release more, and is held twice as long; so
// over a time t the edge puts in at most bound + one tick + r (bound - release + one tick) (+ the
// leak), r <= log2(1 + t / hold) timed releases. Every trip is counted and stays counted.

class EdgeEnergyGate {
 public:
  static constexpr double kOff = std::numeric_limits<double>::infinity();
  // Start-up (throws std::invalid_argument): per edge bound (> 0, +inf = off) and release level
  // (finite, < bound when the bound is finite); the timed release's hold per edge in ticks (>= 0,
  // 0 = none: released at the release level only; empty: none anywhere).
  void init(int edges, std::span<const double> bound_J, std::span<const double> release_J, std::span<const std::int64_t> hold_ticks = {});
  // Start of a tick: updates the latch of edge j from its account; true = act as the damper this
  // tick. RT-safe.
  bool update(int j, double account_J);
  // End of the same tick: edge j's own coupling energy of the tick (EdgeEnergyAccount::record_tick's
  // coupling_J[j]); while the edge acted as the damper it is <= 0, and its negative is added to
  // removed_J(j). RT-safe.
  void record_tick(int j, double coupling_J);
  bool tripped(int j) const { return tripped_[idx(j)] != 0; }
  std::uint64_t trips(int j) const { return trips_[idx(j)]; }            // times the latch closed
  std::uint64_t gated_ticks(int j) const { return gated_ticks_[idx(j)]; }  // ticks acted as the damper
  std::uint64_t trips() const;  // over all edges
  std::uint64_t releases(int j) const { return releases_[idx(j)]; }              // latch opened (either rule)
  std::uint64_t timed_releases(int j) const { return timed_releases_[idx(j)]; }  // of those, by the timed release
  double forgiven_J(int j) const { return forgiven_[idx(j)]; }                  // account excess forgiven at timed releases
  std::int64_t hold_ticks(int j) const { return hold_[idx(j)]; }
  // The ticks the n-th trip (n >= 1) holds the edge before its timed release: hold x 2^(n-1), at most x 1024.
  std::int64_t hold_after_trip(int j, std::uint64_t n) const { return hold_[idx(j)] << (n > 11 ? 10 : n - 1); }
  // The energy the damper action took out of the copy on edge j's gated ticks (>= 0): what the gate
  // removed, so a run it held says how much (firmware's summaries: "gate").
  double removed_J(int j) const { return removed_[idx(j)]; }
  double removed_J() const;  // over all edges
  double bound_J(int j) const { return bound_[idx(j)]; }
  double release_J(int j) const { return release_[idx(j)]; }

 private:
  static std::size_t idx(int j) { return static_cast<std::size_t>(j); }
  int edges_ = 0;
  std::array<double, kMaxEdgeAccounts> bound_{}, release_{}, removed_{}, forgiven_{};
  std::array<std::uint64_t, kMaxEdgeAccounts> trips_{}, gated_ticks_{}, releases_{}, timed_releases_{};
  std::array<std::int64_t, kMaxEdgeAccounts> hold_{}, held_{};  // the timed release's hold, ticks held since the trip
  std::array<unsigned char, kMaxEdgeAccounts> tripped_{};
};

}  // namespace haptic::rt
