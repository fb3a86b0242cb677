#include "rt/edge_monitor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace haptic::rt {

const char* edge_lie_name(EdgeLie lie) {
  switch (lie) {
    case EdgeLie::kKinematic: return "inconsistent_with_its_velocities";
    case EdgeLie::kDisagreement: return "far_from_this_copy";
    case EdgeLie::kNone: break;
  }
  return "none";
}

void EdgeMonitorParams::validate() const {
  auto bad = [](const char* what) { throw std::invalid_argument(std::string("neighbour state check: ") + what); };
  if (!(kinematic_bound_m > 0)) bad("the kinematic bound must be > 0 m (+inf: off)");
  if (!(disagreement_bound_m > 0)) bad("the disagreement bound must be > 0 m (+inf: off)");
  if (!(kinematic_window_s > 0 && std::isfinite(kinematic_window_s))) bad("the kinematic window must be finite and > 0 s");
  if (!(disagreement_window_s > 0 && std::isfinite(disagreement_window_s))) bad("the disagreement window must be finite and > 0 s");
  if (!(readmit_s >= 0 && std::isfinite(readmit_s))) bad("the re-admission time must be finite and >= 0 s");
  if (max_gap_ticks < 1) bad("the largest integrated gap must be >= 1 tick");
  if (max_checked_gap_ticks < max_gap_ticks) bad("the largest checked gap must be >= the largest integrated gap");
}

void EdgeMonitor::init(int edges, int dofs, double period_s, const EdgeMonitorParams& params, const double* x0, const double* v0,
                       std::span<const StepBox> steps) {
  if (edges < 0 || edges > kMaxMonitoredEdges)
    throw std::invalid_argument("neighbour state check: edges must be in [0, " + std::to_string(kMaxMonitoredEdges) + "]");
  if (dofs <= 0 || dofs % 3 != 0 || !(period_s > 0)) throw std::invalid_argument("neighbour state check: bad state size or period");
  if (!steps.empty() && steps.size() != static_cast<std::size_t>(edges))
    throw std::invalid_argument("neighbour state check: one step box per edge (or none)");
  params.validate();
  edges_ = edges;
  dofs_ = dofs;
  T_ = period_s;
  p_ = params;
  ed_.assign(static_cast<std::size_t>(edges), Edge{});
  for (std::size_t j = 0; j < ed_.size(); ++j) {
    Edge& ed = ed_[j];
    const double lo = steps.empty() || steps[j].min_s == 0 ? period_s : steps[j].min_s;
    const double hi = steps.empty() || steps[j].max_s == 0 ? period_s : steps[j].max_s;
    if (!(lo > 0 && lo <= hi && std::isfinite(hi)))
      throw std::invalid_argument("neighbour state check: edge " + std::to_string(j) + "'s step bounds must satisfy 0 < T^min <= T^max");
    ed.h_lo = 0.5 * lo;
    ed.h_hi = 0.5 * hi;
    ed.x_prev.assign(x0, x0 + dofs);
    ed.v_prev.assign(v0, v0 + dofs);
    ed.u.assign(static_cast<std::size_t>(dofs), 0.0);
    ed.y.assign(static_cast<std::size_t>(dofs / 3), 0.0);
  }
}

void EdgeMonitor::kinematic(Edge& ed, std::int64_t gap, const double* x, const double* v) {
  ed.u_max = ed.r_max = ed.gap_ratio = 0;
  if (gap > p_.max_checked_gap_ticks) {  // too far apart to say what honest motion did: re-anchor
    ++ed.unchecked_gaps;
    return;
  }
  const bool integrate = gap <= p_.max_gap_ticks;  // else this packet alone, against gap_bound_m (U only leaks)
  const double g = static_cast<double>(gap), h = 0.5 * g * T_;
  const double decay = std::exp(-2.0 * h / p_.kinematic_window_s);
  // The weights that explain the packet best, in [T^min/2, g T^max/2]: an honest sender took between
  // 1 and g steps over a gap of g sequences (its sequence is its loop's tick on the wall-clock grid:
  // a loaded host that skipped periods took one long step, clamped to T^max, for several sequences).
  const double lo = ed.h_lo, hi = g * ed.h_hi;
  const bool fit = hi > lo;  // variable steps, or a gap
  double a = h, b = h;
  if (fit) fit_steps(ed, lo, hi, x, v, a, b);
  int r_node = -1;
  for (int n = 0; n < dofs_ / 3; ++n) {
    double uu = 0, rr = 0;
    for (int d = 0; d < 3; ++d) {
      const auto i = static_cast<std::size_t>(3 * n + d);
      const double r = x[i] - ed.x_prev[i] - (fit ? a * ed.v_prev[i] + b * v[i] : h * (v[i] + ed.v_prev[i]));
      ed.u[i] = decay * ed.u[i] + (integrate ? r : 0.0);
      uu += ed.u[i] * ed.u[i];
      rr += r * r;
    }
    if (uu > ed.u_max) {
      ed.u_max = uu;
      ed.u_node = n;
    }
    if (rr > ed.r_max) {
      ed.r_max = rr;
      r_node = n;
    }
  }
  ed.u_max = std::sqrt(ed.u_max);
  ed.r_max = std::sqrt(ed.r_max);
  if (!integrate) {
    ++ed.gap_checks;
    ed.gap_ratio = ed.r_max / p_.gap_bound_m(gap);
    ed.gap_residual_m = ed.r_max;
    ed.gap_node = r_node;
    ed.r_max = ed.gap_ratio * p_.kinematic_bound_m;  // re-admission's "own step consistent", in the bound's units
  }
}

// min over (a, b) in [lo, hi]^2 of |d - a p - b q|^2, d = x - x_prev, p = v_prev, q = v: a convex
// quadratic, so the unconstrained optimum when it lies in the box, else the best of the four sides'
// one-dimensional optima (p parallel to q: a line of optima, which meets a side where it meets the box).
void EdgeMonitor::fit_steps(const Edge& ed, double lo, double hi, const double* x, const double* v, double& a, double& b) const {
  double pp = 0, pq = 0, qq = 0, pd = 0, qd = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(dofs_); ++i) {
    const double d = x[i] - ed.x_prev[i], p = ed.v_prev[i], q = v[i];
    pp += p * p;
    pq += p * q;
    qq += q * q;
    pd += p * d;
    qd += q * d;
  }
  const double det = pp * qq - pq * pq;
  if (det > 1e-9 * pp * qq) {
    const double A = (pd * qq - qd * pq) / det, B = (qd * pp - pd * pq) / det;
    if (A >= lo && A <= hi && B >= lo && B <= hi) {
      a = A;
      b = B;
      return;
    }
  }
  const double mid = 0.5 * (lo + hi);
  auto best_a = [&](double B) { return pp > 0 ? std::clamp((pd - B * pq) / pp, lo, hi) : mid; };  // the vertex, clamped
  auto best_b = [&](double A) { return qq > 0 ? std::clamp((qd - A * pq) / qq, lo, hi) : mid; };
  auto cost = [&](double A, double B) { return A * A * pp + 2 * A * B * pq + B * B * qq - 2 * (A * pd + B * qd); };  // |r|^2 - |d|^2
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](double A, double B) {
    const double c = cost(A, B);
    if (c < best) {
      best = c;
      a = A;
      b = B;
    }
  };
  for (const double side : {lo, hi}) {
    consider(best_a(side), side);
    consider(side, best_b(side));
  }
}

void EdgeMonitor::disagreement(Edge& ed, std::int64_t gap, const double* x, const double* v, std::int64_t delay, const double* own_x) {
  // a filter that did not run on the last packet starts at this packet's disagreement
  const double a = ed.y_live ? std::min(1.0, static_cast<double>(gap) * T_ / p_.disagreement_window_s) : 1.0;
  ed.y_live = true;
  const double lead = (static_cast<double>(delay) - 0.5) * T_;  // x_hat(s) is x at s + 1/2
  ed.y_max = 0;
  for (int n = 0; n < dofs_ / 3; ++n) {
    double dd = 0;
    for (int d = 0; d < 3; ++d) {
      const auto i = static_cast<std::size_t>(3 * n + d);
      const double diff = x[i] + lead * v[i] - own_x[i];
      dd += diff * diff;
    }
    double& y = ed.y[static_cast<std::size_t>(n)];
    y += a * (std::sqrt(dd) - y);
    if (y > ed.y_max) {
      ed.y_max = y;
      ed.y_node = n;
    }
  }
}

void EdgeMonitor::decide(Edge& ed, std::int64_t k) {
  if (!ed.isolated) {
    ed.u_peak = std::max(ed.u_peak, ed.u_max);
    ed.y_peak = std::max(ed.y_peak, ed.y_max);
    ed.gap_peak = std::max(ed.gap_peak, ed.gap_ratio);
    EdgeLie why = EdgeLie::kNone;
    if (ed.u_max > p_.kinematic_bound_m) {
      why = EdgeLie::kKinematic;
      ed.trip_node = ed.u_node;
      ed.trip_value_m = ed.u_max;
    } else if (ed.gap_ratio > 1) {
      why = EdgeLie::kKinematic;
      ed.trip_node = ed.gap_node;
      ed.trip_value_m = ed.gap_residual_m;
    } else if (ed.y_max > p_.disagreement_bound_m) {
      why = EdgeLie::kDisagreement;
      ed.trip_node = ed.y_node;
      ed.trip_value_m = ed.y_max;
    }
    if (why == EdgeLie::kNone) return;
    ed.isolated = true;
    ed.reason = why;
    ed.isolated_k = k;
    ed.truthful_since = -1;
    ++ed.isolations;
    return;
  }
  const bool truthful = ed.r_max <= 0.5 * p_.kinematic_bound_m && ed.y_max <= p_.readmit_disagreement_m();
  if (!truthful) {
    ed.truthful_since = -1;
    return;
  }
  if (ed.truthful_since < 0) ed.truthful_since = k;
  if (static_cast<double>(k - ed.truthful_since) * T_ < p_.readmit_after_s(ed.isolations)) return;
  ed.isolated = false;
  ed.readmitted_k = k;
  ++ed.readmissions;
  std::fill(ed.u.begin(), ed.u.end(), 0.0);
  ed.u_max = 0;
}

bool EdgeMonitor::observe(int j, std::int64_t k, std::int64_t seq, const double* x_hat, const double* v_hat, std::int64_t index_delay,
                          const double* own_x) {
  Edge& ed = ed_[static_cast<std::size_t>(j)];
  if (!p_.enabled()) return false;
  if (seq > ed.seq) {  // a new packet: check it, then it is the anchor of the next
    const std::int64_t gap = seq - ed.seq;
    // The first packet only anchors: a neighbour may start from other than this copy's rest state
    // (its clock ahead of ours, a rejoin), and a lie from its first packet on is a consistent one.
    if (p_.kinematic_bound_m < EdgeMonitorParams::kOff && ed.seq >= 0) kinematic(ed, gap, x_hat, v_hat);
    // P's filter: what trips with a finite bound, and what re-admission reads. With P off it runs only
    // while the edge is isolated (from the packet after the isolation on, started at that packet's
    // disagreement): it was ~45 % of the check's cost on every packet (tools/bench/results).
    if (p_.disagreement_bound_m < EdgeMonitorParams::kOff || ed.isolated) {
      disagreement(ed, gap, x_hat, v_hat, index_delay, own_x);
    } else {
      ed.y_live = false;
      ed.y_max = 0;
    }
    std::copy(x_hat, x_hat + dofs_, ed.x_prev.begin());
    std::copy(v_hat, v_hat + dofs_, ed.v_prev.begin());
    ed.seq = seq;
    decide(ed, k);
  }
  if (ed.isolated) ++ed.isolated_ticks;
  return ed.isolated;
}

std::uint64_t EdgeMonitor::isolations() const {
  std::uint64_t n = 0;
  for (const auto& ed : ed_) n += ed.isolations;
  return n;
}

}  // namespace haptic::rt
