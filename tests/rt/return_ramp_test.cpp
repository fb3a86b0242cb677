// The return ramp of an edge (rt/return_ramp.hpp): a neighbour's data back after an outage pulls the
// copies together over the ramp instead of at once; a short drop, and a run without outages, are
// bit for bit what they were without it.
#include <CppUTest/TestHarness.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "rt/return_ramp.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(ReturnRamp){};

TEST(ReturnRamp, a_return_after_the_outage_starts_at_the_own_copy_and_ends_at_the_neighbours) {
  ReturnRamp r;
  r.init(2, 3, 10, 5);  // ramp 10 ticks, after an outage of 5
  const double xh[3] = {1.0, 2.0, 3.0}, x[3] = {0.0, 0.5, 1.0};
  // a drop of 4 ticks (< 5): the data is used as it is, no ramp
  for (int k = 0; k < 4; ++k) CHECK_TRUE(r.target(0, k, false, xh, x) == xh);
  CHECK_TRUE(r.target(0, 4, true, xh, x) == xh);
  CHECK_EQUAL(0u, r.ramps(0));
  // a drop of 5 ticks: at the return tick the target is the own copy, then x_hat - (1 - s) o
  for (int k = 10; k < 15; ++k) r.target(0, k, false, xh, x);
  const double* t = r.target(0, 15, true, xh, x);
  CHECK_TRUE(t != xh);
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(x[i], t[i], 1e-15);
  CHECK_EQUAL(1u, r.ramps(0));
  DOUBLES_EQUAL(2.0, r.last_offset_m(0), 0.0);
  haptic::test::AllocationCounter none;
  t = r.target(0, 19, true, xh, x);  // s = 0.4
  CHECK_EQUAL(0u, none.allocations());
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(xh[i] - 0.6 * (xh[i] - x[i]), t[i], 1e-15);
  CHECK_TRUE(r.ramping(0));
  CHECK_TRUE(r.target(0, 25, true, xh, x) == xh);  // s = 1: the neighbour's data itself
  CHECK_FALSE(r.ramping(0));
  // the other edge was not touched; arm_all makes its next data ramp without an outage
  CHECK_TRUE(r.target(1, 25, true, xh, x) == xh);
  r.arm_all();
  t = r.target(1, 26, true, xh, x);
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(x[i], t[i], 1e-15);
  // off: the data itself, whatever happens
  ReturnRamp off;
  off.init(1, 3, 0, 5);
  off.arm_all();
  for (int k = 0; k < 20; ++k) CHECK_TRUE(off.target(0, k, k > 10, xh, x) == xh);
}

namespace {
// Station 0 of a pair (no contact: the device far away) fed its neighbour's state: the rest state
// displaced by `offset` m (one coordinate moving a little), a packet every tick except in [gap_from, gap_to) (plus every 7th lost);
// returns x(k) after each tick.
std::vector<Eigen::VectorXd> run_pair(double ramp_s, int gap_from, int gap_to, double offset, int ticks) {
  const auto& w = PaperWorld::get();
  auto c = w.station(0, 2, {1}, 20.0, test::tetra_dirs()[0], 0);  // N̄ = 0: a lost packet drops the edge for a tick
  c.vp_initial_position_m = Eigen::Vector3d(5, 5, 5);
  c.return_ramp_s = ramp_s;
  StationCore s(c);
  Eigen::VectorXd xj = w.scene.x_d, vj = Eigen::VectorXd::Zero(w.scene.dofs);
  std::vector<Eigen::VectorXd> xs;
  for (int k = 0; k < ticks; ++k) {
    if (k == gap_to) xj.array() += offset;  // the neighbour's copy drifted while it was away
    xj[0] += 1e-7 * std::sin(0.05 * k);       // and moves a little: the copies are never equal
    if ((k < gap_from || k >= gap_to) && k % 7 != 3) s.rx(0).offer(k, 0, xj.data(), vj.data(), w.scene.dofs);
    s.tick(k, Eigen::Vector3d(5, 5, 5));
    xs.push_back(s.x());
  }
  return xs;
}
double largest_step(const std::vector<Eigen::VectorXd>& xs, int from) {
  double m = 0;
  for (std::size_t k = static_cast<std::size_t>(from) + 1; k < xs.size(); ++k) m = std::max(m, (xs[k] - xs[k - 1]).cwiseAbs().maxCoeff());
  return m;
}
}  // namespace

TEST(ReturnRamp, without_an_outage_the_station_is_bit_identical_to_no_ramp) {
  // every 7th packet lost: the edge drops for a tick (shorter than the outage that ramps): the same bits
  const auto a = run_pair(0.0, 0, 0, 0.0, 400), b = run_pair(0.5, 0, 0, 0.0, 400);
  for (std::size_t k = 0; k < a.size(); ++k) CHECK_TRUE(a[k] == b[k]);
}

TEST(ReturnRamp, a_neighbour_back_after_an_outage_pulls_the_copy_over_the_ramp_not_at_once) {
  // the neighbour silent for 0.2 s (100 ticks), back 1 mm away
  const int back = 300, ticks = 1200;
  const auto snap = run_pair(0.0, 200, back, 1e-3, ticks), ramp = run_pair(0.5, 200, back, 1e-3, ticks);
  const double s0 = largest_step(snap, back), s1 = largest_step(ramp, back);
  CHECK_TRUE(s1 < 0.5 * s0);  // measured: 10x smaller
  // both reach the neighbour's copy in the end (the ramp is 250 ticks)
  const Eigen::VectorXd target = PaperWorld::get().scene.x_d.array() + 1e-3;
  CHECK_TRUE((snap.back() - target).cwiseAbs().maxCoeff() < 1e-5);
  CHECK_TRUE((ramp.back() - target).cwiseAbs().maxCoeff() < 1e-5);
}
