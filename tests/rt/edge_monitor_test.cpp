// The neighbour state check (rt/edge_monitor.hpp): an authenticated insider that lies about its
// state. Unit properties of the monitor on synthetic packets, then a star of four real StationCores
// (hub 0, leaves 1-3, 2-tick delay both ways) whose hub reports its state with a lie added (x_hat
// only: its velocities stay its copy's): a constant offset, an oscillation in the object's lowest
// elastic mode, a slow ramp. Honest copies must move less than the stated bound (rt/README.md, "The
// neighbour state check") against the same run without the lie, every leaf must isolate the hub
// and name it, and the clean run (with a user pushing) isolates no one.
#include <CppUTest/TestHarness.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "rt/edge_monitor.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

namespace {

constexpr double kT = 0.002;
constexpr int kDelay = 2;  // the star's one-way delay, ticks

EdgeMonitorParams check_params() {
  EdgeMonitorParams p;
  p.kinematic_bound_m = kDefaultStateCheckKinematicM;  // the station's defaults: P off
  return p;
}

// One edge, 2 nodes, a rigid motion at velocity u reported consistently; lie(s) added to x from tick s.
struct OneEdge {
  EdgeMonitor m;
  std::vector<double> x0 = std::vector<double>(6, 0.0), v0 = std::vector<double>(6, 0.0), own = std::vector<double>(6, 0.0);
  explicit OneEdge(const EdgeMonitorParams& p) { m.init(1, 6, kT, p, x0.data(), v0.data()); }
  // packet of tick s: x = u s T + lie, v = u (consistent); own copy at the true x. Returns isolated.
  bool feed(std::int64_t s, double u, double lie_x, double lie_v = 0) {
    std::vector<double> x(6), v(6);
    for (int i = 0; i < 6; ++i) {
      const double truth = (i % 3 == 0) ? u * (static_cast<double>(s) + 0.5) * kT : 0.0;
      own[static_cast<std::size_t>(i)] = truth;
      x[static_cast<std::size_t>(i)] = truth + (i % 3 == 0 ? lie_x : 0.0);
      v[static_cast<std::size_t>(i)] = (i % 3 == 0) ? u + lie_v : 0.0;
    }
    return m.observe(0, s, s, x.data(), v.data(), 0, own.data());
  }
};

}  // namespace

TEST_GROUP(EdgeMonitor){};

TEST(EdgeMonitor, consistent_states_are_never_isolated_and_a_jump_above_the_kinematic_bound_isolates_at_that_packet) {
  OneEdge e(check_params());
  const double dK = check_params().kinematic_bound_m;
  for (int s = 0; s < 2000; ++s) CHECK_FALSE(e.feed(s, 0.05, 0.0));
  CHECK_FALSE(e.feed(2000, 0.05, 0.9 * dK));  // below the bound: not yet
  CHECK_TRUE(e.feed(2001, 0.05, 1.2 * dK));   // the lie now changed by more than the bound: this packet
  CHECK_EQUAL(1u, e.m.isolations(0));
  CHECK_TRUE(e.m.last_reason(0) == EdgeLie::kKinematic);
  CHECK_EQUAL(2001, e.m.last_isolated_k(0));
  DOUBLES_EQUAL(1.2 * dK, e.m.trip_value_m(0), 1e-3 * dK);
}

TEST(EdgeMonitor, a_lie_consistent_with_its_velocities_but_far_from_this_copy_is_isolated_within_the_window) {
  auto with_p = check_params();
  with_p.disagreement_bound_m = kSuggestedStateCheckDisagreementM;
  OneEdge e(with_p);
  // a consistent ramp (x and v both lie) at 0.1 m/s: K sees nothing; P when the filtered gap passes its bound
  const double dP = with_p.disagreement_bound_m, tau = with_p.disagreement_window_s;
  std::int64_t s = 0;
  bool iso = false;
  for (; s < 2000 && !iso; ++s) iso = e.feed(s, 0.0, 0.1 * static_cast<double>(s) * kT + 0.05 * kT, 0.1);
  CHECK_TRUE(iso);
  CHECK_TRUE(e.m.last_reason(0) == EdgeLie::kDisagreement);
  // the lie reached the bound at dP / 0.1 s; the filter lags a ramp by its time constant tau
  const double t = static_cast<double>(s) * kT;
  CHECK_TRUE(t > dP / 0.1 && t < dP / 0.1 + tau + 0.02);
  DOUBLES_EQUAL(0.0, e.m.peak_kinematic_m(0), 1e-9);
}

TEST(EdgeMonitor, an_isolated_edge_is_readmitted_only_after_readmit_s_of_truthful_packets) {
  auto p = check_params();
  OneEdge e(p);
  std::int64_t s = 0;
  for (; s < 100; ++s) e.feed(s, 0.01, 0.0);
  CHECK_TRUE(e.feed(s++, 0.01, 0.02));  // +2 cm: isolated
  const std::int64_t lying_until = s + 1000;
  for (; s < lying_until; ++s) CHECK_TRUE(e.feed(s, 0.01, 0.02));  // it keeps the offset: stays isolated
  const std::int64_t truth_from = s;
  bool iso = true;
  for (; s < truth_from + 5000 && iso; ++s) iso = e.feed(s, 0.01, 0.0);
  CHECK_FALSE(iso);
  const double truthful_s = static_cast<double>(s - truth_from) * kT;
  // the disagreement filter must first fall from 20 mm to the re-admission level (0.2 s x ln(20 mm / level)), then readmit_s
  const double fall_s = 0.2 * std::log(0.02 / p.readmit_disagreement_m());
  CHECK_TRUE(truthful_s >= p.readmit_s + fall_s - 0.01);
  CHECK_TRUE(truthful_s <= p.readmit_s + fall_s + 0.05);
  CHECK_EQUAL(1u, e.m.readmissions(0));
  for (int i = 0; i < 1000; ++i) CHECK_FALSE(e.feed(s++, 0.01, 0.0));
  // it lies again: the second re-admission needs twice the truthful time
  CHECK_TRUE(e.feed(s++, 0.01, 0.02));
  for (int i = 0; i < 1000; ++i) CHECK_TRUE(e.feed(s++, 0.01, 0.02));
  const std::int64_t again_from = s;
  for (iso = true; s < again_from + 10000 && iso; ++s) iso = e.feed(s, 0.01, 0.0);
  CHECK_FALSE(iso);
  const double again_s = static_cast<double>(s - again_from) * kT;
  CHECK_TRUE(again_s >= 2 * p.readmit_s + fall_s - 0.01 && again_s <= 2 * p.readmit_s + fall_s + 0.05);
  CHECK_EQUAL(2u, e.m.readmissions(0));
}

TEST(EdgeMonitor, a_jump_inside_a_packet_gap_is_isolated_at_the_packet_after_it_against_a_bound_growing_with_the_gap) {
  const auto p = check_params();
  for (const std::int64_t g : {5, 10, 20, 32}) {
    const double bound = p.gap_bound_m(g);
    CHECK_TRUE(bound > p.kinematic_bound_m);
    OneEdge below(p), above(p);
    for (std::int64_t s = 0; s < 100; ++s) {
      CHECK_FALSE(below.feed(s, 0.05, 0.0));
      CHECK_FALSE(above.feed(s, 0.05, 0.0));
    }
    CHECK_FALSE(below.feed(99 + g, 0.05, 0.9 * bound));  // g sequences later, 0.9 of the bound off: let through
    CHECK_TRUE(above.feed(99 + g, 0.05, 1.1 * bound));   // 1.1 of it: isolated at this packet
    CHECK_EQUAL(1u, above.m.gap_checks(0));
    CHECK_EQUAL(0u, above.m.unchecked_gaps(0));
    CHECK_TRUE(above.m.last_reason(0) == EdgeLie::kKinematic);
    DOUBLES_EQUAL(1.1 * bound, above.m.trip_value_m(0), 1e-3 * bound);
    DOUBLES_EQUAL(0.9, below.m.peak_gap_ratio(0), 1e-3);
    // the gap's residual does not add up: the next consistent packets after the tolerated one stay admitted
    for (std::int64_t s = 100 + g; s < 200 + g; ++s) CHECK_FALSE(below.feed(s, 0.05, 0.9 * bound));
  }
}

TEST(EdgeMonitor, a_gap_longer_than_max_checked_gap_ticks_re_anchors_without_a_check) {
  const auto p = check_params();
  OneEdge e(p);
  CHECK_FALSE(e.feed(0, 0.0, 0.0));
  const std::int64_t g = p.max_checked_gap_ticks + 1;
  const double jump = 2 * p.gap_bound_m(g);  // far above any bound
  CHECK_FALSE(e.feed(g, 0.0, jump));  // not compared (disagreement still filtered)
  CHECK_EQUAL(1u, e.m.unchecked_gaps(0));
  CHECK_EQUAL(0u, e.m.gap_checks(0));
  CHECK_TRUE(e.feed(g + 1, 0.0, 0.0));  // the next packet is checked against it: a jump back
}

// An honest neighbour's NPMI trajectory (x(s+1) - x(s) = T/2 (v(s) + v(s+1)) exactly) whose velocity
// curves hard: the object's lowest elastic mode (11.9 Hz) at 1 mm on a 50 mm/s drift, three axes,
// received after every gap from 1 to max_checked_gap_ticks sequences: never isolated.
TEST(EdgeMonitor, honest_motion_curving_at_the_lowest_mode_is_never_isolated_after_any_checked_gap) {
  const auto p = check_params();
  const double w = 2 * M_PI * 11.9, a = 1e-3, drift = 0.05;
  auto vel = [&](std::int64_t s, int d) { return drift + a * w * std::cos(w * static_cast<double>(s) * kT + d); };
  EdgeMonitor m;
  std::vector<double> x(6, 0.0), v(6, 0.0), own(6, 0.0);
  for (int i = 0; i < 6; ++i) v[static_cast<std::size_t>(i)] = vel(0, i % 3);
  m.init(1, 6, kT, p, x.data(), v.data());
  std::int64_t next = 1, gap = 1;
  for (std::int64_t s = 1; s < 20000; ++s) {
    for (int i = 0; i < 6; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const double vn = vel(s, i % 3);
      x[u] += 0.5 * kT * (v[u] + vn);
      v[u] = vn;
      own[u] = x[u];
    }
    if (s != next) continue;  // lost
    CHECK_FALSE(m.observe(0, s, s, x.data(), v.data(), 0, own.data()));
    gap = gap % p.max_checked_gap_ticks + 1;  // 1, 2, ..., 32, 1, ...
    next = s + gap;
  }
  CHECK_TRUE(m.gap_checks(0) > 100);
  CHECK_EQUAL(0u, m.unchecked_gaps(0));
  CHECK_TRUE(m.peak_gap_ratio(0) > 0.01);  // the gaps did curve: the check saw something, below its bound
  std::printf("honest lowest-mode motion: peak gap residual %.3f of its bound over %llu gap checks\n", m.peak_gap_ratio(0),
              static_cast<unsigned long long>(m.gap_checks(0)));
}

// Motion integrated as NPMI does with variable steps (x_hat = x + T_k/2 v_hat, x += T_k v_hat, T_k in
// T -+ 0.4 ms, 35 % of them clamped long as on a loaded host): the lowest mode at 0.3 mm on a 50 mm/s
// drift, received after every gap from 1 to max_checked_gap_ticks. With the sender's step bounds it
// is never isolated and its unexplained motion stays below a quarter of the bound; a check assuming
// T on the same packets isolates it. (After a gap of 1 the fit explains a packet to roundoff; after
// a longer one what is left is the motion's curvature across the gap, which the fit, unlike the
// fixed-step trapezoid, does not average out: at 1 mm in the mode, 0.6 g, U reaches the bound.)
TEST(EdgeMonitor, honest_motion_with_variable_steps_is_never_isolated_after_any_checked_gap) {
  const auto p = check_params();
  const double w = 2 * M_PI * 11.9, a = 3e-4, drift = 0.05, jitter = 0.0004;
  auto vel = [&](double t, int d) { return drift + a * w * std::cos(w * t + d); };
  const StepBox box{kT - jitter, kT + jitter};
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  EdgeMonitor with_box, assuming_T;
  std::vector<double> x(6, 0.0), xh(6, 0.0), vh(6, 0.0), own(6, 0.0);
  for (int i = 0; i < 6; ++i) vh[static_cast<std::size_t>(i)] = vel(0, i % 3);
  with_box.init(1, 6, kT, p, xh.data(), vh.data(), std::span<const StepBox>(&box, 1));
  assuming_T.init(1, 6, kT, p, xh.data(), vh.data());
  std::int64_t next = 1, gap = 1;
  double t = 0;
  bool fixed_isolated = false;
  for (std::int64_t s = 1; s < 20000; ++s) {
    const double Tk = u(gen) < 0.35 ? kT + jitter : kT + jitter * (2 * u(gen) - 1);
    for (int i = 0; i < 6; ++i) {
      const auto n = static_cast<std::size_t>(i);
      vh[n] = vel(t + 0.5 * Tk, i % 3);           // the tick's mid-step velocity
      xh[n] = x[n] + 0.5 * Tk * vh[n];
      x[n] += Tk * vh[n];
      own[n] = xh[n];
    }
    t += Tk;
    if (s != next) continue;  // lost
    CHECK_FALSE(with_box.observe(0, s, s, xh.data(), vh.data(), 0, own.data()));
    fixed_isolated = assuming_T.observe(0, s, s, xh.data(), vh.data(), 0, own.data()) || fixed_isolated;
    gap = gap % p.max_checked_gap_ticks + 1;
    next = s + gap;
  }
  std::printf("variable steps: peak |U| %.2e m, peak gap residual %.3f of its bound\n", with_box.peak_kinematic_m(0), with_box.peak_gap_ratio(0));
  CHECK_TRUE(with_box.gap_checks(0) > 100);
  CHECK_TRUE(fixed_isolated);
  CHECK_TRUE(with_box.peak_kinematic_m(0) < 0.25 * p.kinematic_bound_m);
}

namespace {

enum class Lie { kNone, kOffset, kMode, kRamp };

// The object's lowest elastic mode (M-normalized shape scaled to 1 m at its largest node) and frequency.
struct LowestMode {
  Eigen::VectorXd shape;
  double hz = 0;
};
const LowestMode& lowest_mode() {
  static const LowestMode m = [] {
    const auto& s = PaperWorld::get().scene;
    const Eigen::MatrixXd K(s.K_int.as_full()), M(s.M.as_full());
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(K, M);
    LowestMode r;
    for (int i = 0; i < es.eigenvalues().size(); ++i)
      if (es.eigenvalues()[i] > 1e-6 * es.eigenvalues().maxCoeff()) {  // the first after the six rigid modes
        r.shape = es.eigenvectors().col(i);
        r.hz = std::sqrt(es.eigenvalues()[i]) / (2 * M_PI);
        break;
      }
    double big = 0;
    for (int n = 0; n < s.nodes; ++n) big = std::max(big, r.shape.segment<3>(3 * n).norm());
    r.shape /= big;
    return r;
  }();
  return m;
}

struct StarResult {
  std::vector<Eigen::VectorXd> leaf_x;  // per tick, the three leaves' x stacked
  std::int64_t isolated_k[4] = {-1, -1, -1, -1};  // per leaf, first tick its hub edge was isolated
  std::uint64_t isolations = 0;       // all edges of all stations
  std::uint64_t hub_isolations = 0;   // the hub's edges (to its honest leaves)
  EdgeLie reason[4] = {};
  double peak_kinematic_m = 0;        // the largest |U| any admitted edge showed
};

// Loaded hosts: with StarSteps::jitter_s > 0 every station steps T_k in [T - jitter, T + jitter] as a
// loaded host does: a share of the ticks overran and were clamped to T^max, the others anywhere in
// the bounds; with missed_share > 0 a share of the periods is skipped (no tick, no packet: the next
// sequence is the next period's, and the tick after a skip steps T^max). A fixed seed per station.
// boxes: the neighbours' step bounds reach the state check.
struct StarSteps {
  double jitter_s = 0;
  bool boxes = true;
  double overrun_share = 0.35;
  double missed_share = 0;
  double push_m = 0.005, push_s = 0.5;  // leaf 1's push: this deep in this long
  bool any() const { return jitter_s > 0 || missed_share > 0; }
};

// Per tick: the step, or 0 for a skipped period.
std::vector<double> loaded_host_steps(int station, int ticks, const StarSteps& steps) {
  std::mt19937 gen(static_cast<unsigned>(1234 + station));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> T_k;
  bool after_skip = false;
  for (int k = 0; k < ticks; ++k) {
    if (k > 0 && u(gen) < steps.missed_share) {
      T_k.push_back(0);
      after_skip = true;
      continue;
    }
    const bool long_step = after_skip || u(gen) < steps.overrun_share;
    T_k.push_back(long_step ? kT + steps.jitter_s : kT + steps.jitter_s * (2 * u(gen) - 1));
    after_skip = false;
  }
  return T_k;
}

// Hub 0 (neighbours 1, 2, 3), leaves 1-3 (neighbour 0); 2-tick delay both ways. Leaf 1's user pushes
// 5 mm into the object from 0.2 s to 0.7 s and holds. The hub lies from lie_t0 s on.
StarResult run_star(Lie lie, double amplitude, int ticks, bool check = true, double lie_t0 = 1.0, const StarSteps& steps = {}) {
  const auto& w = PaperWorld::get();
  const auto& dirs = test::tetra_dirs();
  std::vector<StationConfig> cfg;
  cfg.push_back(w.station(0, 4, {1, 2, 3}, 30, dirs[0]));
  for (int l = 1; l <= 3; ++l) cfg.push_back(w.station(l, 4, {0}, 30, dirs[static_cast<std::size_t>(l)]));
  if (check)
    for (auto& c : cfg) c.state_check = check_params();
  std::vector<std::vector<double>> T_k(4);
  for (int i = 0; i < 4 && steps.any(); ++i) {
    auto& c = cfg[static_cast<std::size_t>(i)];
    if (steps.jitter_s > 0) {
      c.period_min_s = kT - steps.jitter_s;
      c.period_max_s = kT + steps.jitter_s;
      c.step_resolution_s = steps.jitter_s / 16;
      if (steps.boxes)
        for (auto& nb : c.neighbors) {
          nb.step_min_s = c.period_min_s;
          nb.step_max_s = c.period_max_s;
        }
    }
    T_k[static_cast<std::size_t>(i)] = loaded_host_steps(i, ticks, steps);
  }
  // whether station i ran tick k (and so sent its packet k)
  auto ran = [&](int i, int k) { return T_k[static_cast<std::size_t>(i)].empty() || T_k[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)] > 0; };
  std::vector<std::unique_ptr<StationCore>> st;
  for (auto& c : cfg) st.push_back(std::make_unique<StationCore>(c));
  const int dofs = w.scene.dofs;
  std::vector<std::vector<Eigen::VectorXd>> sx(4, std::vector<Eigen::VectorXd>(kDelay + 1, w.scene.x_d));
  std::vector<std::vector<Eigen::VectorXd>> sv(4, std::vector<Eigen::VectorXd>(kDelay + 1, Eigen::VectorXd::Zero(dofs)));
  const Eigen::Vector3d e = Eigen::Vector3d(1, 0.5, -0.3).normalized();
  const LowestMode& mode = lowest_mode();
  StarResult r;
  for (int k = 0; k < ticks; ++k) {
    if (k >= kDelay) {
      const auto s = static_cast<std::size_t>((k - kDelay) % (kDelay + 1));
      for (int l = 1; l <= 3; ++l) {
        if (ran(l, k - kDelay))
          st[0]->rx(l - 1).offer(k - kDelay, 0, sx[static_cast<std::size_t>(l)][s].data(), sv[static_cast<std::size_t>(l)][s].data(), dofs);
        if (ran(0, k - kDelay)) st[static_cast<std::size_t>(l)]->rx(0).offer(k - kDelay, 0, sx[0][s].data(), sv[0][s].data(), dofs);
      }
    }
    const double t = k * kT;
    for (int i = 0; i < 4; ++i) {
      Eigen::Vector3d q = w.face_center(dirs[static_cast<std::size_t>(i)]);
      if (i == 1) q += steps.push_m * std::clamp((t - 0.2) / steps.push_s, 0.0, 1.0) * w.face_inward(dirs[1]);
      const auto& Ti = T_k[static_cast<std::size_t>(i)];
      if (Ti.empty() || steps.jitter_s == 0) {
        if (ran(i, k)) st[static_cast<std::size_t>(i)]->tick(k, q);
      } else if (ran(i, k)) {
        st[static_cast<std::size_t>(i)]->tick(k, q, Ti[static_cast<std::size_t>(k)]);
      }
    }
    const auto s = static_cast<std::size_t>(k % (kDelay + 1));
    for (int i = 0; i < 4; ++i) {
      sx[static_cast<std::size_t>(i)][s] = Eigen::Map<const Eigen::VectorXd>(st[static_cast<std::size_t>(i)]->x_hat(), dofs);
      sv[static_cast<std::size_t>(i)][s] = Eigen::Map<const Eigen::VectorXd>(st[static_cast<std::size_t>(i)]->v_hat(), dofs);
    }
    // the insider: its reported x_hat with the lie added, its velocities its copy's
    const double tl = t + 0.5 * kT - lie_t0;
    if (tl >= 0) {
      if (lie == Lie::kOffset)
        for (int n = 0; n < w.scene.nodes; ++n) sx[0][s].segment<3>(3 * n) += amplitude * e;
      if (lie == Lie::kMode) sx[0][s] += amplitude * std::sin(2 * M_PI * mode.hz * tl) * mode.shape;
      if (lie == Lie::kRamp)
        for (int n = 0; n < w.scene.nodes; ++n) sx[0][s].segment<3>(3 * n) += amplitude * tl * e;
    }
    Eigen::VectorXd lx(3 * dofs);
    for (int l = 1; l <= 3; ++l) {
      lx.segment((l - 1) * dofs, dofs) = st[static_cast<std::size_t>(l)]->x();
      const auto& mon = st[static_cast<std::size_t>(l)]->edge_monitor();
      if (r.isolated_k[l] < 0 && mon.isolated(0)) {
        r.isolated_k[l] = k;
        r.reason[l] = mon.last_reason(0);
      }
    }
    r.leaf_x.push_back(std::move(lx));
  }
  for (const auto& c : st) {
    r.isolations += c->edge_monitor().isolations();
    for (int j = 0; j < c->neighbor_count(); ++j) r.peak_kinematic_m = std::max(r.peak_kinematic_m, c->edge_monitor().peak_kinematic_m(j));
  }
  r.hub_isolations = st[0]->edge_monitor().isolations();
  return r;
}

// max over ticks, leaves and nodes of |x_lie - x_clean|
double damage_m(const StarResult& a, const StarResult& b) {
  double d = 0;
  for (std::size_t k = 0; k < a.leaf_x.size(); ++k)
    for (Eigen::Index n = 0; n < a.leaf_x[k].size() / 3; ++n) d = std::max(d, (a.leaf_x[k].segment<3>(3 * n) - b.leaf_x[k].segment<3>(3 * n)).norm());
  return d;
}

constexpr int kStarTicks = 2500;  // 5 s; the lie starts at 1 s

const StarResult& clean_star() {
  static const StarResult r = run_star(Lie::kNone, 0, kStarTicks);
  return r;
}

// The reference: the same run with every leaf isolating the hub at the lie's first packet (a 1 m
// jump), so the lie is never applied; honest copies are compared with it (isolation itself ends
// the consensus, which the clean run keeps).
const StarResult& isolated_at_onset() {
  static const StarResult r = run_star(Lie::kOffset, 1.0, kStarTicks);
  return r;
}

// The star's ratchet rate c (1/s): the speed at which an unchecked constant offset L drags the
// copies is c L (rt/README.md); measured from the drift of an unchecked 2 cm lie over its 4 s.
double ratchet_rate_per_s() {
  static const double c = [] {
    const double L = 0.02;
    return damage_m(run_star(Lie::kOffset, L, kStarTicks, false), clean_star()) / (L * (kStarTicks * kT - 1.0));
  }();
  return c;
}

struct Isolation {
  double t_d_s = 0;    // the latest leaf's isolation of the hub, after the lie's start
  double moved_m = 0;  // honest copies vs the run isolated at the onset
};

Isolation isolate(Lie lie, double amplitude) {
  const StarResult r = run_star(lie, amplitude, kStarTicks);
  Isolation iso;
  for (int l = 1; l <= 3; ++l) {
    CHECK_TRUE(r.isolated_k[l] >= 0);
    CHECK_TRUE(r.reason[l] == EdgeLie::kKinematic);
    iso.t_d_s = std::max(iso.t_d_s, static_cast<double>(r.isolated_k[l]) * kT - 1.0);
  }
  CHECK_EQUAL(0u, r.hub_isolations);  // the lying hub's honest leaves are never isolated
  iso.moved_m = damage_m(r, isolated_at_onset());
  std::printf("\n  lie %d, %.4g: isolated within %.3f s, honest copies moved %.4f mm", static_cast<int>(lie), amplitude, iso.t_d_s, 1e3 * iso.moved_m);
  return iso;
}

}  // namespace


TEST(EdgeMonitor, a_clean_star_with_a_user_pushing_isolates_no_one) {
  CHECK_EQUAL(0u, clean_star().isolations);
}

// The star on loaded hosts: every station steps T_k within T -+ 0.4 ms (eq. 9), 60 % of its ticks clamped
// long, and the user pushes 15 mm. NPMI moves x_hat by T_k/2 v_hat per half step, so a check that
// assumed T saw (T_k - T)/2 |v| per tick add up while the object moved (the run below without the
// step bounds: an honest neighbour isolated); with each neighbour's step bounds the fit explains
// every packet.
TEST(EdgeMonitor, a_clean_star_on_loaded_hosts_stepping_variable_T_k_isolates_no_one) {
  StarSteps steps;
  steps.jitter_s = 0.0004;
  steps.overrun_share = 0.6;
  steps.push_m = 0.015;
  const StarResult r = run_star(Lie::kNone, 0, kStarTicks, true, 1.0, steps);
  steps.boxes = false;
  const StarResult fixed = run_star(Lie::kNone, 0, kStarTicks, true, 1.0, steps);
  std::printf("\n  variable steps: peak |U| %.4f mm with the step bounds, %.4f mm assuming T (%llu isolations)", 1e3 * r.peak_kinematic_m,
              1e3 * fixed.peak_kinematic_m, static_cast<unsigned long long>(fixed.isolations));
  CHECK_TRUE(fixed.isolations > 0);  // the run is one where assuming the nominal step fails
  CHECK_EQUAL(0u, r.isolations);
  CHECK_TRUE(r.peak_kinematic_m < 0.05 * kDefaultStateCheckKinematicM);
}

// Hosts that skip periods (10 % of them; a station's sequence is its loop's tick on the wall-clock
// grid, so a skip is a gap of 2 sequences over which the sender took one step, T^max): with fixed
// steps (T^min = T^max = T) and with variable ones, the fit over [T^min/2, g T^max/2] explains every
// packet. (Assuming the sender took g steps of T left -T/2 (v_hat(s0) + v_hat(s)) per skip: 0.2 mm
// after ~60 skips while the object moved at 10 mm/s.)
TEST(EdgeMonitor, a_clean_star_on_loaded_hosts_that_skip_periods_isolates_no_one) {
  for (const double jitter : {0.0, 0.0004}) {
    StarSteps steps;
    steps.jitter_s = jitter;
    steps.missed_share = 0.1;
    steps.push_m = 0.015;
    const StarResult r = run_star(Lie::kNone, 0, kStarTicks, true, 1.0, steps);
    std::printf("\n  skipped periods, jitter %.1f ms: peak |U| %.4f mm", 1e3 * jitter, 1e3 * r.peak_kinematic_m);
    CHECK_EQUAL(0u, r.isolations);
    CHECK_TRUE(r.peak_kinematic_m < 0.05 * kDefaultStateCheckKinematicM);
  }
}

// A lie that changes by more than kinematic_bound_m within one packet is caught at that packet,
// before the step uses it: the honest copies move as if the hub had been cut off at the onset.
TEST(EdgeMonitor, a_hub_lying_by_a_constant_offset_is_isolated_by_every_leaf_at_its_first_lying_packet) {
  for (double L : {0.02, 0.005}) {
    const Isolation iso = isolate(Lie::kOffset, L);
    CHECK_TRUE(iso.t_d_s <= (kDelay + 0.5) * kT);  // the first lying packet, when it arrives
    CHECK_TRUE(iso.moved_m < 1e-6);
  }
}

TEST(EdgeMonitor, a_hub_oscillating_in_the_lowest_mode_is_isolated_once_its_lie_passed_the_kinematic_bound) {
  DOUBLES_EQUAL(11.9, lowest_mode().hz, 0.1);  // the object's lowest elastic mode
  const Isolation iso = isolate(Lie::kMode, 0.01);
  // the lie 0.01 sin(w t) passes d_K at t = asin(d_K / 0.01) / w: the first packet after it
  const double dK = kDefaultStateCheckKinematicM;
  CHECK_TRUE(iso.t_d_s <= std::asin(dK / 0.01) / (2 * M_PI * lowest_mode().hz) + (kDelay + 1.5) * kT);
  // what the packets of at most d_K in the mode's shape moved: the stated bound for it is d_K
  CHECK_TRUE(iso.moved_m < dK);
}

// A ramp of rho m/s is caught when its leaky sum has grown to d_K: t_d = -tau_K ln(1 - d_K / (rho tau_K))
// (~ d_K / rho), plus the one-way delay; before that a leaf followed the lie at most at its own rate
// c_l L(t), c_l = 4/3 c (a leaf pulled by the whole lie; the steady ratchet's c sees 3/4 of it): the
// model says the copies moved rho t_d + c_l rho t_d^2 / 2 (~ d_K + c_l d_K^2 / (2 rho)); the stated
// bound is 1.25 x that (the node peaks carry the deformation's transient, up to ~20 % here).
TEST(EdgeMonitor, a_hub_lying_by_a_slow_ramp_is_isolated_when_it_reached_the_kinematic_bound_and_moved_copies_at_most_the_bound) {
  const double dK = kDefaultStateCheckKinematicM, c = ratchet_rate_per_s();
  CHECK_TRUE(c > 1.0);  // the unchecked lie does drag the copies
  for (double rho : {0.002, 0.0005}) {
    const Isolation iso = isolate(Lie::kRamp, rho);
    const double t_d = -check_params().kinematic_window_s * std::log(1 - dK / (rho * check_params().kinematic_window_s)) + (kDelay + 1.5) * kT;
    CHECK_TRUE(iso.t_d_s <= t_d);
    const double bound = 1.25 * (4.0 / 3.0 * c * rho * t_d * t_d / 2 + rho * t_d);
    std::printf(" (bound %.3f mm, c %.2f /s)", 1e3 * bound, c);
    CHECK_TRUE(iso.moved_m < bound);
  }
}

