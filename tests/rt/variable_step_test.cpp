// Variable steps T_k (eq. 9, 21, 26; rt/README.md "Variable steps"): the core integrates over the
// step it is given (rounded to one of its prefactored steps), keeps NPMI's energy balance (12) with
// T_k in every term, clamps steps outside [T^min, T^max] and counts them, and checks eq. (26) at the
// worst step ratio T^max / T^min.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "rt/gains.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(VariableStep){};

TEST(VariableStep, prefactored_steps_are_the_nominal_grid_inside_the_bounds_plus_the_bounds) {
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 2, {1}, 10, test::tetra_dirs()[0]);
  CHECK_EQUAL(1u, step_levels(cfg).size());  // fixed step: one factorization, as before
  cfg.period_min_s = 0.0015;
  cfg.period_max_s = 0.0025;
  cfg.step_resolution_s = 0.0004;
  const std::vector<double> l = step_levels(cfg);
  const std::vector<double> want = {0.0015, 0.0016, 0.002, 0.0024, 0.0025};
  CHECK_EQUAL(want.size(), l.size());
  for (std::size_t i = 0; i < want.size(); ++i) DOUBLES_EQUAL(want[i], l[i], 1e-15);
  StationCore st(cfg);
  CHECK_EQUAL(5, st.step_level_count());
}

TEST(VariableStep, the_state_advances_by_the_steps_given_not_the_nominal_period) {
  // A very heavy VO moving at a constant velocity, no neighbours, no contact: x(k) - x(0) =
  // v sum_k T_k. A core that ignored T_k would advance by k T instead (differs by ~10 %).
  SceneParams sp;
  sp.node_mass_kg = 1e9;
  const Scene scene = build_scene(make_paper_ball(0.05), sp);
  StationConfig c;
  c.users = 1;
  c.scene = &scene;
  c.period_s = 0.002;
  c.period_min_s = 0.0016;
  c.period_max_s = 0.0024;
  c.step_resolution_s = 0.0002;
  c.contact_nodes = PaperWorld::get().face_nodes(Eigen::Vector3d(1, 1, 1));
  c.vp_initial_position_m = Eigen::Vector3d(5, 5, 5);
  StationCore st(c);
  const Eigen::VectorXd v = Eigen::VectorXd::Constant(scene.dofs, 0.01);
  st.set_state(scene.x_d, v);
  const std::vector<double> steps = {0.0024, 0.0022, 0.0024, 0.0018, 0.0024, 0.00231, 0.00239};  // on or near levels
  double sum = 0;
  for (int k = 0; k < 700; ++k) {
    const double want = steps[static_cast<std::size_t>(k) % steps.size()];
    st.tick(k, Eigen::Vector3d(5, 5, 5), want);
    const double level = std::round(want / 0.0002) * 0.0002;
    DOUBLES_EQUAL(level, st.last_step_s(), 1e-15);
    sum += st.last_step_s();
  }
  const double moved = (st.x() - scene.x_d).mean();
  DOUBLES_EQUAL(0.01 * sum, moved, 1e-9 * 0.01 * sum);
  CHECK_TRUE(std::abs(moved - 0.01 * 700 * 0.002) > 0.05 * moved);
  CHECK_EQUAL(0u, st.step_clamped_ticks());
}

TEST(VariableStep, steps_outside_the_bounds_are_clamped_and_counted) {
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 2, {1}, 10, test::tetra_dirs()[0]);
  cfg.period_min_s = 0.0018;
  cfg.period_max_s = 0.0025;
  StationCore st(cfg);
  st.tick(0, cfg.vp_initial_position_m, 0.010);  // an overrun: 5 periods
  DOUBLES_EQUAL(0.0025, st.last_step_s(), 1e-15);
  st.tick(1, cfg.vp_initial_position_m, 0.0001);
  DOUBLES_EQUAL(0.0018, st.last_step_s(), 1e-15);
  st.tick(2, cfg.vp_initial_position_m, std::nan(""));
  DOUBLES_EQUAL(0.002, st.last_step_s(), 1e-15);
  st.tick(3, cfg.vp_initial_position_m, 0.0021);
  CHECK_EQUAL(3u, st.step_clamped_ticks());
}

TEST(VariableStep, npmi_energy_balance_eq12_holds_with_a_different_step_every_tick) {
  // B = 0: E(k) - E(0) = sum_k (f + tau)^T v_hat T_k exactly (to roundoff), with contact, lost and
  // fresh neighbour data, and steps drawn at random in [T^min, T^max] every tick. Using T_k in one
  // term and the nominal T in another breaks it.
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 3, {1, 2}, 12.0, test::tetra_dirs()[1]);
  cfg.period_min_s = 0.0015;
  cfg.period_max_s = 0.0025;  // eq. (26): K_vc T^max = 0.5 = b_d
  StationCore st(cfg);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd xj(w.scene.dofs), vj(w.scene.dofs);
  const Eigen::Vector3d p0 = cfg.vp_initial_position_m, in = w.face_inward(test::tetra_dirs()[1]);
  bool contact = false;
  for (int k = 0; k < 4000; ++k) {
    for (int n = 0; n < 2; ++n) {
      if (u(rng) < 0) continue;
      for (int i = 0; i < w.scene.dofs; ++i) {
        xj[i] = w.scene.x_d[i] + 2e-3 * u(rng);
        vj[i] = 0.05 * u(rng);
      }
      st.rx(n).offer(k, 0, xj.data(), vj.data(), w.scene.dofs);
    }
    const Eigen::Vector3d q = p0 + (0.01 + 0.01 * u(rng)) * in + 0.003 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    st.tick(k, q, 0.002 + 0.0005 * u(rng));
    contact = contact || st.in_contact();
  }
  CHECK_TRUE(contact);
  const double Eend = w.scene.energy(st.x(), st.v()) / cfg.users;
  const double supplied = st.energy().port_J + st.energy().controller_J;
  CHECK_TRUE(std::abs(Eend - supplied) <= 1e-8 * std::abs(supplied));
}

TEST(VariableStep, eq26_is_checked_at_the_largest_step_and_step_ratio) {
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 2, {1}, 10, test::tetra_dirs()[0]);
  cfg.vp.coupling.B_vc_Ns_per_m = 0.05;
  cfg.vp.coupling.K_vc_N_per_m = 150;  // fixed T = 2 ms: b_d 0.5 >= 0.05 * 2 + 0.3 = 0.4
  cfg.device_damping_Ns_per_m = 0.5;
  cfg.validate();
  cfg.period_min_s = 0.0015;
  cfg.period_max_s = 0.0025;  // 0.05 * (1.67 + 1) + 150 * 0.0025 = 0.508 > 0.5
  CHECK_THROWS(std::invalid_argument, cfg.validate());
}
