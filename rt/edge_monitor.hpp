#pragma once
// Per-edge check of the states an authenticated neighbour reports (bounded position damage from
// an insider; rt/README.md "The neighbour state check"). The energy gate (rt/edge_energy.hpp)
// bounds the energy one edge puts into the copy, not how far it drags it: a neighbour that reports
// its state a few mm off pulls every copy along (the pull's energy goes into each station's own
// damping). This monitor isolates such an edge. Two checks on each new packet of edge j:
//
//  K (kinematic): the neighbour's x_hat must move as its own reported velocities say. NPMI gives
//    x_hat(s+1) - x_hat(s) = T_s/2 v_hat(s) + T_{s+1}/2 v_hat(s+1) exactly, T_s the sender's step of
//    tick s (x_hat = x + T_k/2 v_hat, x += T_k v_hat), so per node the unexplained displacement
//    U += x_hat(s) - x_hat(s0) - a v_hat(s0) - b v_hat(s) over a gap of g = s - s0 <= max_gap_ticks
//    packets, leaking with the time constant kinematic_window_s. At a fixed step a = b = g T/2. With
//    variable steps (the neighbour's StepBox [T^min, T^max], eq. 9) or a gap the steps are not
//    known: a and b are the one pair in [T^min/2, g T^max/2] that explains the packet best (least
//    squares over every node: the whole copy steps with one T_k). An honest sender took 1 to g
//    steps over g sequences: its sequence is its loop's tick on the wall-clock grid, and a loaded
//    host that skipped periods took one step (clamped to T^max) for several. So its residual is 0
//    after a gap of 1 whatever its steps, and after a skip (assuming g steps of T left (T_k - T)/2
//    |v| per tick and T/2 |v_hat(s0) + v_hat(s)| per skip: a loaded host's honest neighbours were
//    isolated). The fit's freedom is a time warp: a lie along the reported velocities of up to
//    (T^max - T^min)/2 |v| per packet, (g T^max - T^min)/2 |v| after a gap. Isolate
//    when some node's |U| > kinematic_bound_m. A packet after a longer gap (lost packets, a stalled
//    sender or receiver) is compared alone: its residual over the gap, whose honest size grows as the
//    velocities curve in between (~ (g T)^3 |jerk| / 12), against gap_bound_m(g) = kinematic_bound_m
//    (g / max_gap_ticks)^2; it does not enter U. Gaps above max_checked_gap_ticks re-anchor,
//    unchecked (counted): a jump hidden in one is a consistent lie (below). A state offset
//    that changes (a jump, an oscillation, a ramp faster than kinematic_bound_m / kinematic_window_s)
//    without the reported velocities to match is caught when it has changed by kinematic_bound_m.
//  P (disagreement; isolates only with a finite bound; with P off filtered only while the edge is
//    isolated, for re-admission): the neighbour's state, carried forward to this tick by its own velocity
//    (x_hat_j + (N - 1/2) T v_hat_j), against this copy's x(k), per node, filtered by a first-order
//    lag of time constant disagreement_window_s. Isolate when some node's filtered |difference| >
//    disagreement_bound_m. Catches a lie that is consistent with its velocities but far from the
//    honest copies (honest copies agree to ~0.2 mm in a clean run).
//
// What it cannot tell apart: a neighbour whose reported states are consistent with its reported
// velocities and stay within disagreement_bound_m of this copy looks exactly like an honest
// neighbour whose user pushes the object; such a lie still drags the copies, as a user would.
//
// Isolation is latched per edge: the edge contributes nothing but the damper (the station's action
// for an over-bound edge: x_hat_j := x(k), delta = 0, passive). It is re-admitted only after every
// packet for readmit_s x 2^(isolations - 1) was truthful: its own step consistent (|one packet's
// residual| <= kinematic_bound_m / 2 at every node) and the filtered disagreement within
// readmit_disagreement_m() at every node; then U restarts at 0. Time counts in ticks (k); no packet, no progress towards re-admission.
// init() allocates; observe() never allocates, locks or throws: RT-safe.
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace haptic::rt {

inline constexpr int kMaxMonitoredEdges = 16;

// Why an edge was isolated.
enum class EdgeLie : std::uint8_t { kNone = 0, kKinematic, kDisagreement };
// "none", "inconsistent_with_its_velocities", "far_from_this_copy"
const char* edge_lie_name(EdgeLie lie);

struct EdgeMonitorParams {
  static constexpr double kOff = std::numeric_limits<double>::infinity();
  double kinematic_bound_m = kOff;     // check K's threshold (+inf: off)
  double kinematic_window_s = 30.0;    // check K's leak time constant
  int max_gap_ticks = 4;               // check K integrates packets at most this many sequences apart
  int max_checked_gap_ticks = 32;      // ... and compares one packet against gap_bound_m after a gap up to this
  double disagreement_bound_m = kOff;  // check P's threshold (+inf: off)
  double disagreement_window_s = 0.2;  // check P's filter time constant
  double readmit_s = 2.0;              // truthful time before an isolated edge is re-admitted
  bool enabled() const { return kinematic_bound_m < kOff || disagreement_bound_m < kOff; }
  // The filtered disagreement an isolated edge must stay within to count as truthful: twice the
  // kinematic bound (a lie re-admitted below it drags the copies at most as one the kinematic check
  // just let through), at most half the disagreement bound.
  double readmit_disagreement_m() const {
    return 2 * kinematic_bound_m < 0.5 * disagreement_bound_m ? 2 * kinematic_bound_m : 0.5 * disagreement_bound_m;
  }
  // The truthful time the n-th isolation (n >= 1) needs before re-admission: readmit_s x 2^(n-1),
  // at most x 1024 (a liar that lies again after each re-admission gets there ever more slowly).
  double readmit_after_s(std::uint64_t n) const { return readmit_s * static_cast<double>(1u << (n > 11 ? 10 : n - 1)); }
  // Check K's bound on one packet's residual after a gap of g > max_gap_ticks sequences.
  double gap_bound_m(std::int64_t g) const {
    const double r = static_cast<double>(g) / static_cast<double>(max_gap_ticks);
    return kinematic_bound_m * r * r;
  }
  void validate() const;  // throws std::invalid_argument
};

// The station defaults (station.state_check_*; rt/README.md "The neighbour state check"): K at ~20x
// what honest copies show in clean runs; P off (0): copies that legitimately diverged (an outage, an
// isolation) would trip it on honest neighbours. kSuggestedStateCheckDisagreementM: ~5x the honest
// disagreement of a clean run, for labs that turn P on.
inline constexpr double kDefaultStateCheckKinematicM = 2e-4;
inline constexpr double kDefaultStateCheckDisagreementM = 0;
inline constexpr double kSuggestedStateCheckDisagreementM = 5e-3;

// A neighbour's step bounds T_j^min <= T_k <= T_j^max (check K's fit; 0: the nominal period).
struct StepBox {
  double min_s = 0, max_s = 0;
};

class EdgeMonitor {
 public:
  // Start-up: edges (<= kMaxMonitoredEdges), dofs per state, the nominal step, the state every copy
  // starts from (x0, v0: the first packet is checked against it) and each edge's StepBox (empty: every
  // neighbour steps at period_s). Throws std::invalid_argument.
  void init(int edges, int dofs, double period_s, const EdgeMonitorParams& params, const double* x0, const double* v0,
            std::span<const StepBox> steps = {});
  // Tick k, edge j: its held packet (sequence seq, x_hat, v_hat, index delay N = k - seq) and this
  // copy's x(k). A packet seen before changes nothing. Returns true: edge isolated this tick. RT-safe.
  bool observe(int j, std::int64_t k, std::int64_t seq, const double* x_hat, const double* v_hat, std::int64_t index_delay,
               const double* own_x);

  const EdgeMonitorParams& params() const { return p_; }
  int edges() const { return edges_; }
  bool enabled() const { return p_.enabled(); }
  bool isolated(int j) const { return e(j).isolated; }
  StepBox step_box(int j) const { return {2 * e(j).h_lo, 2 * e(j).h_hi}; }  // edge j's neighbour step bounds, as used
  std::uint64_t isolations(int j) const { return e(j).isolations; }
  std::uint64_t isolations() const;  // over all edges
  std::uint64_t readmissions(int j) const { return e(j).readmissions; }
  std::uint64_t isolated_ticks(int j) const { return e(j).isolated_ticks; }
  std::uint64_t gap_checks(int j) const { return e(j).gap_checks; }  // packets after a gap in (max_gap_ticks, max_checked_gap_ticks]
  std::uint64_t unchecked_gaps(int j) const { return e(j).unchecked_gaps; }  // packets after a gap > max_checked_gap_ticks
  // The largest residual/gap_bound_m of a packet after a gap while admitted (honest: well below 1).
  double peak_gap_ratio(int j) const { return e(j).gap_peak; }
  // The last isolation: its reason, tick, the node and value (m) that tripped it; the last re-admission's tick (-1: none).
  EdgeLie last_reason(int j) const { return e(j).reason; }
  std::int64_t last_isolated_k(int j) const { return e(j).isolated_k; }
  std::int64_t last_readmitted_k(int j) const { return e(j).readmitted_k; }
  int trip_node(int j) const { return e(j).trip_node; }
  double trip_value_m(int j) const { return e(j).trip_value_m; }
  // Now, and the peaks while the edge was admitted: max over nodes of |U| and of the filtered disagreement.
  double kinematic_m(int j) const { return e(j).u_max; }
  double disagreement_m(int j) const { return e(j).y_max; }
  double peak_kinematic_m(int j) const { return e(j).u_peak; }
  double peak_disagreement_m(int j) const { return e(j).y_peak; }  // 0 with P off (not filtered while admitted)

 private:
  struct Edge {
    std::vector<double> x_prev, v_prev, u;  // the last packet (dofs each), unexplained displacement (dofs)
    std::vector<double> y;                  // filtered disagreement per node
    std::int64_t seq = -1;
    double h_lo = 0, h_hi = 0;  // half the neighbour's step bounds (StepBox)
    bool y_live = false;        // P's filter ran on the last packet (else it restarts at the next)
    bool isolated = false;
    EdgeLie reason = EdgeLie::kNone;
    std::int64_t isolated_k = -1, readmitted_k = -1, truthful_since = -1;
    int trip_node = -1;
    double trip_value_m = 0;
    double u_max = 0, y_max = 0, r_max = 0, u_peak = 0, y_peak = 0;
    double gap_ratio = 0, gap_peak = 0, gap_residual_m = 0;  // after a gap: residual / gap_bound_m (0: no gap), its peak, the residual
    std::uint64_t isolations = 0, readmissions = 0, isolated_ticks = 0, gap_checks = 0, unchecked_gaps = 0;
    int u_node = -1, y_node = -1, gap_node = -1;
  };
  const Edge& e(int j) const { return ed_[static_cast<std::size_t>(j)]; }
  // The new packet's checks: U and one packet's residual (K), the filtered disagreement (P).
  void kinematic(Edge& ed, std::int64_t gap, const double* x, const double* v);
  // The weights (a, b) of v_hat(s0) and v_hat(s) in [lo, hi] that explain x_hat(s) - x_hat(s0) best.
  void fit_steps(const Edge& ed, double lo, double hi, const double* x, const double* v, double& a, double& b) const;
  void disagreement(Edge& ed, std::int64_t gap, const double* x, const double* v, std::int64_t delay, const double* own_x);
  void decide(Edge& ed, std::int64_t k);  // latch, re-admission
  int edges_ = 0, dofs_ = 0;
  double T_ = 0;
  EdgeMonitorParams p_{};
  std::vector<Edge> ed_;
};

}  // namespace haptic::rt
