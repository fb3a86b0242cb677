// The fade of a dropped edge (rt/drop_fade.hpp): an edge whose data ages out is released over
// drop_fade_s (a frozen anchor, stiffness falling to 0), not at once; an isolated or gated edge
// drops at once; an edge back during the fade hands over to the return ramp without a step.
#include <CppUTest/TestHarness.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "rt/drop_fade.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(DropFade){};

TEST(DropFade, the_anchor_is_frozen_and_its_stiffness_falls_as_the_square_to_zero_over_the_fade) {
  DropFade f;
  f.init(2, 3, 4);  // 4 ticks
  const double last[3] = {1.0, 2.0, 3.0}, x[3] = {0.0, 0.5, 1.0};
  double a[3] = {1.0, 2.0, 3.0};
  f.start(0, 10, a);
  a[0] = 99;  // the caller's buffer changes (the link reuses it): the anchor does not
  haptic::test::AllocationCounter none;
  for (int h = 0; h < 4; ++h) {
    const double* t = f.target(0, 10 + h, x);
    CHECK_TRUE(t != nullptr);
    const double w = (1.0 - h / 4.0) * (1.0 - h / 4.0);
    for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(x[i] + w * (last[i] - x[i]), t[i], 1e-15);
  }
  CHECK_EQUAL(0u, none.allocations());
  CHECK_TRUE(f.target(0, 14, x) == nullptr);  // h = H: dropped
  CHECK_FALSE(f.fading(0));
  CHECK_EQUAL(1u, f.fades(0));
  // handover: the target at the return tick, then the fade is over
  f.start(1, 20, last);
  const double* t = f.handover(1, 22, x);
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(x[i] + 0.25 * (last[i] - x[i]), t[i], 1e-15);
  CHECK_FALSE(f.fading(1));
  CHECK_TRUE(f.handover(1, 23, x) == nullptr);
  // stop: at once; off: never fades
  f.start(1, 30, last);
  f.stop(1);
  CHECK_TRUE(f.target(1, 30, x) == nullptr);
  DropFade off;
  off.init(1, 3, 0);
  off.start(0, 0, last);
  CHECK_FALSE(off.fading(0));
  CHECK_TRUE(off.target(0, 0, x) == nullptr);
}

namespace {
// Station 0 of a pair (no contact: the device far away; N-bar = 2 ticks) fed its neighbour's copy:
// the rest state deformed by ~1 mm, a packet every tick except in [silent_from, silent_to), and from
// `lie_at` on 1 cm further (a jump the state check calls a lie). Per tick: the edge's spring force
// on the copy, P (coupled - x(k)) (0 when it acts as the damper), and whether it was gated/isolated.
struct EdgeRun {
  std::vector<Eigen::VectorXd> force;
  std::vector<char> distrusted;
  std::uint64_t fades = 0;
  std::uint64_t allocations = 0;  // in the ticks
};
struct PairSetup {
  double fade_s = 0, ramp_s = 0;
  int silent_from = 1 << 30, silent_to = 1 << 30, lie_at = 1 << 30, ticks = 0;
  double energy_bound_J = EdgeEnergyGate::kOff, kinematic_bound_m = EdgeMonitorParams::kOff;
};
EdgeRun run_pair(const PairSetup& p) {
  const auto& w = PaperWorld::get();
  auto c = w.station(0, 2, {1}, 20.0, test::tetra_dirs()[0], 2);
  c.vp_initial_position_m = Eigen::Vector3d(5, 5, 5);
  c.drop_fade_s = p.fade_s;
  c.return_ramp_s = p.ramp_s;
  c.neighbors[0].energy_bound_J = p.energy_bound_J;
  c.neighbors[0].energy_release_J = 0;
  c.state_check.kinematic_bound_m = p.kinematic_bound_m;
  StationCore s(c);
  const int n = w.scene.dofs;
  // the neighbour's copy 2 % larger than the rest shape (~1 mm): a deformation, which this copy's
  // stiffness resists, so the edge's spring stays stretched while it pulls
  Eigen::VectorXd xj = w.scene.x_d, vj = Eigen::VectorXd::Zero(n), stretch(n);
  for (int a = 0; a < 3; ++a) {
    const double mid = w.scene.x_d(Eigen::seqN(a, n / 3, 3)).mean();
    for (int i = a; i < n; i += 3) xj[i] += 0.02 * (w.scene.x_d[i] - mid);
  }
  EdgeRun r;
  for (int k = 0; k < p.ticks; ++k) {
    if (k == p.lie_at) xj.array() += 1e-2;
    if (k < p.silent_from || k >= p.silent_to) s.rx(0).offer(k, 0, xj.data(), vj.data(), n);
    const Eigen::VectorXd x = s.x();
    std::uint32_t flags = 0;
    {
      haptic::test::AllocationCounter tick_allocs;
      flags = s.tick(k, Eigen::Vector3d(5, 5, 5)).flags;
      r.allocations += tick_allocs.allocations();
    }
    Eigen::VectorXd f = Eigen::VectorXd::Zero(n);
    if (const double* cs = s.coupled_state(0)) {
      stretch = Eigen::Map<const Eigen::VectorXd>(cs, n) - x;
      w.gains.P.multiply_add(1.0, stretch.data(), f.data());
    }
    r.force.push_back(f);
    r.distrusted.push_back((flags & (kEdgeEnergyGated | kEdgeIsolated)) != 0);
  }
  r.fades = s.drop_fade().fades(0);
  return r;
}
// The largest change of the edge's force from one tick to the next over [from, to).
double largest_step(const EdgeRun& r, int from, int to) {
  double m = 0;
  for (int k = from; k < to; ++k) m = std::max(m, (r.force[static_cast<std::size_t>(k)] - r.force[static_cast<std::size_t>(k - 1)]).norm());
  return m;
}
double norm_at(const EdgeRun& r, int k) { return r.force[static_cast<std::size_t>(k)].norm(); }
}  // namespace

TEST(DropFade, a_dropped_edge_s_force_fades_continuously_and_monotonically_to_zero_over_the_fade) {
  // silent from tick 400: the data ages out (N-bar = 2) at k_d = 402; fade 0.2 s = 100 ticks
  PairSetup p;
  p.silent_from = 400;
  p.ticks = 700;
  const int kd = 402, H = 100;
  const EdgeRun at_once = run_pair(p);
  p.fade_s = 0.2;
  const EdgeRun fade = run_pair(p);
  const double f0 = norm_at(fade, kd - 1);
  CHECK_TRUE(f0 > 1e-3);  // the edge pulled before the drop
  DOUBLES_EQUAL(0.0, norm_at(at_once, kd), 0.0);  // the paper's drop: the whole force in one tick
  DOUBLES_EQUAL(f0, largest_step(at_once, kd, kd + 1), 1e-9);
  CHECK_EQUAL(1u, fade.fades);
  CHECK_EQUAL(0u, fade.allocations);  // the tick stays allocation-free with a fade running
  for (int k = kd; k < kd + H; ++k) CHECK_TRUE(norm_at(fade, k) <= norm_at(fade, k - 1));  // never grows
  CHECK_TRUE(norm_at(fade, kd + H - 1) > 0);
  for (int k = kd + H; k < p.ticks; ++k) DOUBLES_EQUAL(0.0, norm_at(fade, k), 0.0);  // over: the damper
  // continuous: no tick changes the force by more than a few times the fade's share f0 / H (measured
  // 2.0 f0 / H)
  CHECK_TRUE(largest_step(fade, kd, p.ticks) < 3.0 * f0 / H);
}

TEST(DropFade, an_isolated_or_gated_edge_drops_at_once) {
  PairSetup gate;  // the account over a small bound: gated while the data is within the delay bound
  gate.fade_s = 0.2;
  gate.energy_bound_J = 1e-6;
  gate.ticks = 600;
  PairSetup lie;  // a 1 cm jump in the reported state: isolated by the state check
  lie.fade_s = 0.2;
  lie.kinematic_bound_m = 1e-4;
  lie.lie_at = 300;
  lie.ticks = 600;
  for (const PairSetup& p : {gate, lie}) {
    const EdgeRun r = run_pair(p);
    int distrusted = 0;
    for (int k = 1; k < p.ticks; ++k) {
      if (!r.distrusted[static_cast<std::size_t>(k)]) continue;
      ++distrusted;
      DOUBLES_EQUAL(0.0, norm_at(r, k), 0.0);  // the damper from the first such tick on, no fade
    }
    CHECK_TRUE(distrusted > 0);
    CHECK_EQUAL(0u, r.fades);
  }
}

TEST(DropFade, an_edge_back_during_the_fade_hands_over_to_the_ramp_without_a_step) {
  // silent over [400, 500): aged out at 402, back at 500 halfway through a 0.4 s (200-tick) fade
  PairSetup p;
  p.silent_from = 400;
  p.silent_to = 500;
  p.ticks = 1000;
  p.ramp_s = 0.5;
  const int kd = 402, H = 200;
  p.fade_s = 0.4;
  const EdgeRun r = run_pair(p);
  const double f0 = norm_at(r, kd - 1);
  CHECK_TRUE(norm_at(r, 499) > 0.3 * f0 && norm_at(r, 499) < 0.9 * f0);  // partly faded (measured 0.47 f0)
  // the fade itself: within a few times f0 / H per tick
  CHECK_TRUE(largest_step(r, kd, 500) < 3.0 * f0 / H);
  // from the return on the ramp starts at the fade's target: no step, only the spring re-engaging on
  // a moving copy (measured 1.8 % of f0 per tick; starting at the own copy instead drops the pull at once)
  CHECK_TRUE(largest_step(r, 500, p.ticks) < 0.05 * f0);
}
