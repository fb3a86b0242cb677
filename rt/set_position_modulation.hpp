#pragma once
// Passive set-position modulation (PSPM; D. J. Lee and K. Huang, "Passive-set-position-modulation
// framework for interactive robotic systems", IEEE T-RO 26(2), 2010 — the same authors' framework
// for delayed, lossy, irregularly sampled links) applied to one consensus edge (i, j) of eq. (15):
// an alternative to eq. (18)'s worst-case damping B_i that keeps eq. (14) by construction.
//
// The edge's P term acts towards a set-position ybar held by this object instead of the received
// x_hat_j(k - N): tau_P = -P (x_hat_i - ybar). While ybar is held, the NPMI midpoint step makes that
// term exactly conservative: -T v_hat^T P (x_hat - ybar) = V(x(k)) - V(x(k+1)) with
// V(x) = 1/2 (x - ybar)^T P (x - ybar) >= 0 (x_hat = (x(k) + x(k+1)) / 2, x(k+1) - x(k) = T v_hat).
// Energy can enter only where ybar jumps, at a tick boundary: dV = V(x(k); ybar_new) - V(x(k); ybar_old).
// Each tick ybar moves towards the newest received x_hat_j, ybar_new = ybar_old + alpha (y - ybar_old),
// with the largest alpha in [0, 1] for which dV <= E, the edge's energy reservoir; then E -= dV
// (a jump that lowers V credits E). E starts at E0 (>= 0) and is filled only by energy the edge
// dissipated: its D term acts on the local velocity alone, -D v_hat (the received velocity is not
// used: its delayed product is not passive either), and T v_hat^T D v_hat >= 0 is credited each tick.
// Hence, with copies starting equal (V(0) = 0), the energy the edge ever put into the copy is
//   sum_k -T v_hat^T [D v_hat + P (x_hat - ybar)] = V(0) - V(now) + sum dV - sum dissipated <= E0,
// whatever the delays, losses, reordering or the neighbour's data: eq. (14) per edge with c^2 = E0,
// with no delay bound and no B_i (rt/README.md, "Passive set-position modulation").
// update()/credit() never allocate: RT-safe. init() allocates (start-up).
#include <cstdint>
#include <string>
#include <vector>

#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

// How a station keeps its consensus controller passive (eq. 14): eq. (18)'s damping B_i with the
// delay bound Nbar (the paper), or passive set-position modulation per edge (no bound, B_i free).
enum class ConsensusPassivity : std::uint8_t { kEq18Damping, kSetPositionModulation };
// "eq18" / "pspm" (throws std::invalid_argument naming `key`), and back.
ConsensusPassivity parse_consensus_passivity(const std::string& text, const std::string& key);
const char* consensus_passivity_name(ConsensusPassivity p);

class SetPositionModulator {
 public:
  // Start-up: ybar := x0 (all copies start from the same configuration), E := reservoir0_J (>= 0).
  void init(int dofs, const double* x0, double reservoir0_J);
  // One tick: moves ybar from its current value towards y (the newest received x_hat_j) as far as the
  // reservoir allows, given this copy's x(k) and the edge's P. scratch: 2 x dofs doubles. Returns alpha.
  double update(const double* y, const double* x, const SpatialMatrix& P, double* scratch);
  // update() in its two halves, for edges that share P (SpatialMatrix::pair_forms_many): prepare
  // writes d = y - ybar and r = x - ybar into scratch, finish takes P's forms on them (pair_forms(d, r))
  // and moves ybar. The same bits as update().
  void prepare(const double* y, const double* x, double* scratch) const;
  double finish(const PairForms& f, const double* scratch);
  // ybar := x (a copy that adopts another state, e.g. on rejoin, starts its springs relaxed); the
  // reservoir is kept. RT-safe (no allocation).
  void reset(const double* x) {
    for (std::size_t i = 0; i < ybar_.size(); ++i) ybar_[i] = x[i];
  }
  // Energy the edge dissipated this tick (T v_hat^T D v_hat >= 0) into the reservoir.
  void credit(double dissipated_J) { reservoir_J_ += dissipated_J; }
  const double* ybar() const { return ybar_.data(); }
  double reservoir_J() const { return reservoir_J_; }
  std::uint64_t limited_ticks() const { return limited_ticks_; }  // ticks with alpha < 1 (the reservoir bound acted)
  double injected_J() const { return injected_J_; }               // sum of dV > 0 over the run (energy the jumps put in)

 private:
  std::vector<double> ybar_;
  double reservoir_J_ = 0;
  std::uint64_t limited_ticks_ = 0;
  double injected_J_ = 0;
};

}  // namespace haptic::rt
