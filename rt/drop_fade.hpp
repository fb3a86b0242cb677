#pragma once
// The fade of an edge whose data aged out (rt/README.md "An edge whose data ages out: the fade").
// When a neighbour's newest data goes over its index-delay bound, the paper drops the edge at once
// (x_hat_j := x(k): the damper), which removes the spring's pull in one tick: a user whose copy
// was held by the others' forces feels it as a step. With a fade of fade_ticks H, the edge instead
// couples to a frozen anchor a_j, the last state it used (the held packet, or the return ramp's

//
//   target_j(k) = x(k) + w (a_j - x(k)),  w = 1 - h / H,  h = k - k_d  (k_d: the first tick over the bound),
//
// so the edge's term P (target_j - x(k)) = w P (a_j - x(k)) is the spring to a fixed point with
// stiffness w P, non-increasing in k; from h = H on the edge is the damper (the paper's action).
// Energy: a fixed anchor with non-increasing stiffness can give the copy at most what its spring
// stores at the drop, 1/2 (a_j - x(k_d))^T P (a_j - x(k_d)) (the implicit T/2 P of eq. 9 covers the
// discretization); the target is what the solve and the per-edge account read, so that energy is
// in the edge's account under its damage bound. Only an age drop fades: an edge isolated by the
// state check or gated by the energy bound drops at once (stop()), a liar's last state is not used.
// A return during the fade hands over to the return ramp from the fade's current target (handover()).
// init() allocates; everything else is RT-safe (no allocation, no lock, no wait).
#include <cstdint>
#include <vector>

namespace haptic::rt {

class DropFade {
 public:
  // Start-up: edges, dofs per state, the fade's length in ticks (0: off, the paper's immediate drop).
  void init(int edges, int dofs, std::int64_t fade_ticks);
  bool on() const { return fade_ticks_ > 0; }
  // Edge j's data went over the bound at tick k after it was used on tick k - 1: `last` is what it
  // coupled to then (copied: the anchor). Nothing when off.
  void start(int j, std::int64_t k, const double* last);
  bool fading(int j) const { return edge(j).start_k >= 0; }
  // The fading target of tick k (x: this station's copy at the start of the tick), in a buffer of
  // the fade's own valid until the next call for j; nullptr once h >= H (the fade is over: dropped).
  const double* target(int j, std::int64_t k, const double* x);
  // The data came back at tick k: the fade's target at k (where the edge's coupling stands; nullptr
  // if it was not fading or the fade was over) and the fade ends.
  const double* handover(int j, std::int64_t k, const double* x);
  void stop(int j) { edges_[static_cast<std::size_t>(j)].start_k = -1; }  // isolated, gated, left out: at once
  std::uint64_t fades(int j) const { return edge(j).fades; }  // fades started on edge j
  std::int64_t fade_ticks() const { return fade_ticks_; }

 private:
  struct Edge {
    std::int64_t start_k = -1;  // k_d (-1: not fading)
    std::uint64_t fades = 0;
    std::vector<double> anchor, target;
  };
  const Edge& edge(int j) const { return edges_[static_cast<std::size_t>(j)]; }
  std::vector<Edge> edges_;
  int dofs_ = 0;
  std::int64_t fade_ticks_ = 0;
};

}  // namespace haptic::rt
