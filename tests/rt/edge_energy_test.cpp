// The per-edge energy account (rt/edge_energy.hpp): eq. (14)'s controller energy split per edge.
// Each edge's tick energy equals an independent evaluation of its eq. (15) term from the state
// change (v_hat = (x(k+1) - x(k))/T, dense P_ij, D_ij, the receiver's own copy of the packets),
// the accounts add up to the station's eq. (14) total, and with B = 0 the VO's energy change is
// the port energy plus the accounts (eq. 12) - through lost, swapped and over-bound packets.
#include <CppUTest/TestHarness.h>

#include <Eigen/Sparse>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "rt/edge_energy.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(EdgeEnergy){};

TEST(EdgeEnergy, shares_split_the_local_damping_and_accounts_add_up) {
  EdgeEnergyAccount a;
  const std::vector<double> shares = {3.0, 1.0};
  a.init(2, shares);
  DOUBLES_EQUAL(0.75, a.share(0), 1e-15);
  const std::vector<double> c = {0.5, -0.25};
  a.record_tick(c, -1.0);
  DOUBLES_EQUAL(0.5 - 0.75, a.edge_J(0), 1e-15);
  DOUBLES_EQUAL(-0.25 - 0.25, a.edge_J(1), 1e-15);
  DOUBLES_EQUAL(-1.0 + 0.25, a.total_J(), 1e-15);
  DOUBLES_EQUAL(0.0, a.peak_J(0), 0.0);  // the account never went positive
  const std::vector<double> c2 = {2.0, 0.0};
  a.record_tick(c2, 0.0);
  DOUBLES_EQUAL(1.75, a.peak_J(0), 1e-15);
  a.init(0);
  a.record_tick({}, -2.0);  // no edge: B_i's energy is unshared
  DOUBLES_EQUAL(-2.0, a.total_J(), 0.0);
  const std::vector<double> bad = {1.0, -1.0};
  CHECK_THROWS(std::invalid_argument, a.init(2, bad));
  CHECK_THROWS(std::invalid_argument, a.init(kMaxEdgeAccounts + 1));
}

TEST(EdgeEnergy, each_edge_account_is_its_eq15_term_and_they_sum_to_the_eq14_total) {
  const auto& w = PaperWorld::get();
  const auto dir = test::tetra_dirs()[1];
  // Three neighbours with bound 2: the over-bound action happens; unequal damping shares.
  auto cfg = w.station(0, 4, {1, 2, 3}, 15.0, dir, 2);
  cfg.neighbors[0].damping_share = 2.0;
  cfg.neighbors[1].damping_share = 1.0;
  cfg.neighbors[2].damping_share = 1.0;
  StationCore st(cfg);
  const int dofs = w.scene.dofs, nn = 3;
  const double T = cfg.period_s;
  std::vector<RxLink> mine(nn);  // the test's own copy of the receive bookkeeping
  for (auto& r : mine) r.init(dofs, w.scene.x_d.data(), Eigen::VectorXd::Zero(dofs).eval().data());
  const Eigen::MatrixXd P = Eigen::MatrixXd(w.gains.P.as_full()), D = Eigen::MatrixXd(w.gains.D.as_full());
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd xj(dofs), vj(dofs);
  const Eigen::Vector3d p0 = cfg.vp_initial_position_m, in = w.face_inward(dir);
  const double E0 = w.scene.energy(st.x(), st.v()) / cfg.users;
  std::vector<double> own(nn, 0.0);
  double own_damping = 0, worst = 0;
  std::int64_t seq[3] = {0, 0, 0};
  int over_bound = 0;
  for (int k = 0; k < 3000; ++k) {
    for (int n = 0; n < nn; ++n) {
      if (u(rng) < -0.2) continue;  // ~40 % of ticks without a packet
      for (int i = 0; i < dofs; ++i) {
        xj[i] = w.scene.x_d[i] + 2e-3 * u(rng);
        vj[i] = 0.05 * u(rng);
      }
      const std::int64_t s = std::max<std::int64_t>(0, seq[n] + (u(rng) > 0.7 ? -2 : 1));  // some swapped
      seq[n] = std::max(seq[n], s);
      st.rx(n).offer(s, 0, xj.data(), vj.data(), dofs);
      mine[static_cast<std::size_t>(n)].offer(s, 0, xj.data(), vj.data(), dofs);
    }
    const Eigen::VectorXd x0 = st.x();
    const Eigen::Vector3d q = p0 + (0.01 + 0.01 * u(rng)) * in;
    st.tick(q);
    const Eigen::VectorXd vh = (st.x() - x0) / T, xh = x0 + (T / 2) * vh;
    own_damping += -cfg.damping_Ns_per_m * vh.squaredNorm() * T;
    for (int n = 0; n < nn; ++n) {
      const auto view = mine[static_cast<std::size_t>(n)].begin_tick(k);
      const bool ok = view.index_delay <= 2;
      over_bound += ok ? 0 : 1;
      const Eigen::Map<const Eigen::VectorXd> xr(view.x_hat, dofs), vr(view.v_hat, dofs);
      const Eigen::VectorXd xo = ok ? Eigen::VectorXd(xr) : x0;
      const double delta = (ok && view.fresh) ? 1.0 : 0.0;
      const double e = -T * vh.dot(D * (vh - delta * vr) + P * (xh - xo));
      own[static_cast<std::size_t>(n)] += e;
      const double share = (n == 0 ? 0.5 : 0.25) * own_damping;
      worst = std::max(worst, std::abs(own[static_cast<std::size_t>(n)] + share - st.edge_energy().edge_J(n)));
    }
  }
  CHECK_TRUE(over_bound > 100);  // the over-bound action was exercised
  CHECK_TRUE(std::abs(own[0]) > 1e-4 && std::abs(own[1]) > 1e-4);
  CHECK_TRUE(worst < 1e-12);
  DOUBLES_EQUAL(st.energy().controller_J, st.edge_energy().total_J(), 1e-12);
  // eq. (12) with B = 0: E(k) - E(0) = port + controller, the controller energy being the accounts
  const double E = w.scene.energy(st.x(), st.v()) / cfg.users;
  DOUBLES_EQUAL(E - E0, st.energy().port_J + st.edge_energy().total_J(), 1e-9 * std::max(1.0, std::abs(E - E0)));
}
