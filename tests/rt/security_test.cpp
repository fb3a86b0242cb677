// Attacks that reach the receive links, checked against an unattacked twin: station A
// and its twin A' see the same genuine neighbour stream; A also gets the attack. The attack is
// harmless when A's state, VP and device force stay bit-identical to A''s at every tick.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic::rt;
using haptic::test::PaperWorld;

namespace {

struct Twins {
  const PaperWorld& w = PaperWorld::get();
  std::unique_ptr<StationCore> a, twin, nb;  // nb: the genuine neighbour (station 1)
  int dofs;
  std::vector<std::vector<double>> sent;  // nb's x_hat ++ v_hat per tick
  Twins() : dofs(PaperWorld::get().scene.dofs) {
    const Eigen::Vector3d d0 = haptic::test::tetra_dirs()[0], d1 = haptic::test::tetra_dirs()[1];
    a = std::make_unique<StationCore>(w.station(0, 2, {1}, 30, d0, 5));
    twin = std::make_unique<StationCore>(w.station(0, 2, {1}, 30, d0, 5));
    nb = std::make_unique<StationCore>(w.station(1, 2, {0}, 30, d1, 5));
  }
  // Runs `ticks` ticks, packets delayed by 2 ticks each way, A pushing into its face; before A's
  // tick k, attack(k, A's link) may offer whatever it likes. Returns the first tick where A and
  // its twin differ (state, VP or force), or -1.
  int run(int ticks, const std::function<void(std::int64_t, RxLink&)>& attack) {
    const Eigen::Vector3d d0 = haptic::test::tetra_dirs()[0], d1 = haptic::test::tetra_dirs()[1];
    std::vector<std::vector<double>> from_a;
    int first_diff = -1;
    for (std::int64_t k = 0; k < ticks; ++k) {
      if (k >= 2) {
        const auto& p = sent[static_cast<std::size_t>(k - 2)];
        a->rx(0).offer(k - 2, 0, p.data(), p.data() + dofs, dofs);
        twin->rx(0).offer(k - 2, 0, p.data(), p.data() + dofs, dofs);
        const auto& q = from_a[static_cast<std::size_t>(k - 2)];
        nb->rx(0).offer(k - 2, 0, q.data(), q.data() + dofs, dofs);
      }
      attack(k, a->rx(0));
      const double depth = 0.01 * std::min(1.0, static_cast<double>(k) / 100.0);
      const auto fa = a->tick(k, w.face_center(d0) + depth * w.face_inward(d0));
      const auto ft = twin->tick(k, w.face_center(d0) + depth * w.face_inward(d0));
      nb->tick(k, w.face_center(d1));
      std::vector<double> pa(a->x_hat(), a->x_hat() + dofs), pn(nb->x_hat(), nb->x_hat() + dofs);
      pa.insert(pa.end(), a->v_hat(), a->v_hat() + dofs);
      pn.insert(pn.end(), nb->v_hat(), nb->v_hat() + dofs);
      from_a.push_back(pa);
      sent.push_back(pn);
      const bool same = a->x() == twin->x() && a->v() == twin->v() && a->vp_position_m() == twin->vp_position_m() &&
                        fa.device_force_N == ft.device_force_N && fa.flags == ft.flags;
      if (!same && first_diff < 0) first_diff = static_cast<int>(k);
    }
    return first_diff;
  }
};

}  // namespace

TEST_GROUP(RxAttack){};

TEST(RxAttack, NonFinitePayloadIsRefusedAndChangesNothing) {
  Twins t;
  std::vector<double> bad;
  const int diff = t.run(300, [&](std::int64_t k, RxLink& rx) {
    if (k != 80 && k != 81) return;
    // The next genuine sequence, one value NaN (k = 80) or +inf in a velocity (k = 81).
    bad.assign(t.sent[static_cast<std::size_t>(k - 1)].begin(), t.sent[static_cast<std::size_t>(k - 1)].end());
    bad[static_cast<std::size_t>(k == 80 ? 7 : t.dofs + 3)] =
        k == 80 ? std::numeric_limits<double>::quiet_NaN() : std::numeric_limits<double>::infinity();
    CHECK(rx.offer(k - 1, 0, bad.data(), bad.data() + t.dofs, t.dofs) == RxVerdict::kNonFinite);
  });
  CHECK_EQUAL(-1, diff);
  CHECK_EQUAL(2u, t.a->rx(0).counters().non_finite);
  CHECK_EQUAL(0u, t.a->safe_state_ticks());
}

TEST(RxAttack, DataStampedSlightlyAheadGivesIndexDelayZeroNeverNegative) {
  RxLink rx;
  const double z[3] = {0, 0, 0};
  rx.init(3, z, z);
  rx.begin_tick(10);
  const double x[3] = {1, 2, 3};
  // 4 ahead of our tick 10 (within the sender's slack: the decoder refuses beyond it, future_sequence)
  CHECK(rx.offer(14, 0, x, x, 3) == RxVerdict::kAccepted);
  const auto v = rx.begin_tick(11);
  CHECK_EQUAL(0, v.index_delay);
  CHECK_EQUAL(1u, rx.counters().ahead_ticks);
}
