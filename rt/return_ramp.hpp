#pragma once
// The return ramp of an edge (rt/README.md "An edge that returns after an outage"). While a
// neighbour's data is missing (over its index-delay bound: x_hat_j := x(k)), the copies drift apart
// (each follows its own user). When its data returns, the edge does not snap to the neighbour's copy
// at full gain: it couples to
//
//   target_j(k) = x_hat_j(k) - (1 - s) o_j,  s = (k - k_r) / ramp_ticks,  o_j = x_hat_j(k_r) - x(k_r),
//
// the offset between the two copies at the return tick k_r taken off linearly over ramp_ticks. At
// k_r the target is x(k_r), the dropped edge's own target (no step in the spring's stretch); from
// k_r + ramp_ticks on it is x_hat_j (the paper's law). The copies are pulled together at a bounded
// rate instead of within the consensus time, so a user's force moves by the same total amount but
// spread over the ramp.
// Energy: the target is what the edge's term of eq. (15) uses (the solve's right-hand side and the
// per-edge account, rt/edge_energy.hpp, read the same pointer), so whatever the moving target puts
// into the copy is in that edge's account and under its damage bound (EdgeEnergyGate), as any data
// of the edge is; the stretch starts at 0, where an instant return starts at o_j (stored energy
// 1/2 o_j^T P o_j at once). Eq. (18) alone does not cover a target that is not a neighbour's delayed
// state; the account does.
// A return ramps when the data was missing for at least after_ticks (a short drop returns as before,
// bit for bit), or when arm_all() was called (a rejoined station's first coupling: its links never
// had data), or when the edge returns during a drop's fade (the ramp starts at the fade's target:
// no step). Off (ramp_ticks = 0): target() returns x_hat_j unchanged.
// init() allocates; everything else is RT-safe (no allocation, no lock, no wait).
#include <cstdint>
#include <vector>

namespace haptic::rt {

class ReturnRamp {
 public:
  // Start-up: edges, dofs per state, ramp length and the outage that makes a return ramp, in ticks
  // (ramp_ticks = 0: off).
  void init(int edges, int dofs, std::int64_t ramp_ticks, std::int64_t after_ticks);
  bool on() const { return ramp_ticks_ > 0; }
  // The next tick on which each edge's data is within its bound starts a ramp (a rejoin).
  void arm_all();
  // Tick k of edge j: `present` = its data is within the index-delay bound this tick; x_hat the held
  // packet's state, x this station's copy at the start of the tick. Returns what the edge couples to
  // (x_hat, or the ramp's target in a buffer of the ramp's own, valid until the next call for j).
  // `faded`: the edge came back while its drop was fading (rt/drop_fade.hpp): the fade's target at
  // k, where a ramp then starts (o_j = x_hat_j(k_r) - faded), whatever the outage's length.
  const double* target(int j, std::int64_t k, bool present, const double* x_hat, const double* x,
                       const double* faded = nullptr);
  // The target of edge j's last present tick while ramping(j) (the buffer target() returned).
  const double* last_target(int j) const { return edge(j).target.data(); }
  bool ramping(int j) const { return edge(j).start_k >= 0; }
  std::uint64_t ramps(int j) const { return edge(j).ramps; }  // ramps started on edge j
  // The offset o_j (its largest coordinate, m) the last ramp of edge j started from (0: none yet).
  double last_offset_m(int j) const { return edge(j).offset_max_m; }

 private:
  struct Edge {
    std::int64_t down_since = -1;  // first tick of the current outage (-1: data present)
    std::int64_t start_k = -1;     // the ramp's return tick k_r (-1: not ramping)
    bool armed = false;
    std::uint64_t ramps = 0;
    double offset_max_m = 0;
    std::vector<double> offset, target;
  };
  const Edge& edge(int j) const { return edges_[static_cast<std::size_t>(j)]; }
  void start(Edge& e, std::int64_t k, const double* x_hat, const double* x);
  std::vector<Edge> edges_;
  int dofs_ = 0;
  std::int64_t ramp_ticks_ = 0, after_ticks_ = 0;
};

}  // namespace haptic::rt
