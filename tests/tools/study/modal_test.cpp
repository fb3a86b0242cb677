// Modal analysis (tools/study/modal.hpp): the basis diagonalizes the model, truncation to all modes equals
// the full model (stepped with the same NPMI), the closed-form mode response solves its ODE,
// and the reduced step does not allocate.
#include <CppUTest/TestHarness.h>

#include <cmath>

#include "tools/study/integrators.hpp"
#include "tools/study/modal.hpp"
#include "tools/study/model_selector.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic::rt;
using namespace haptic::study;

namespace {
const PushProblem& paper_problem() {
  static const PushProblem p = make_push_problem(make_ball_mesh(33, 0.05), PushProblemParams{});
  return p;
}
}  // namespace

TEST_GROUP(Modal){};

TEST(Modal, basis_is_mass_orthonormal_and_diagonalizes_the_stiffness) {
  const auto& p = paper_problem();
  const ModalBasis b = compute_modes(p.model);
  const Eigen::MatrixXd K = Eigen::MatrixXd(p.model.K);
  const int n = p.model.nodes;
  const Eigen::MatrixXd I = p.model.node_mass_kg * b.phi.transpose() * b.phi;
  CHECK_TRUE((I - Eigen::MatrixXd::Identity(n, n)).norm() < 1e-9);
  const Eigen::MatrixXd L = b.phi.transpose() * K * b.phi;
  CHECK_TRUE((L - Eigen::MatrixXd(b.omega2.asDiagonal())).norm() < 1e-8 * b.omega2.maxCoeff());
  CHECK_TRUE(b.omega2.minCoeff() > 0);  // the contact and support springs hold the floating ball
}

TEST(Modal, truncation_to_all_modes_equals_the_full_model) {
  auto params = PushProblemParams{};
  params.damping_per_s = 3.0;
  const PushProblem p = make_push_problem(make_ball_mesh(33, 0.05), params);
  const ModalBasis b = compute_modes(p.model);
  const int n = p.model.nodes;
  ModalReducedModel red(b, p.model, n, 2e-3, false, p.felt_w);
  LinearIntegrator full(p.model, Integrator::kNpmi, 2e-3);
  Eigen::VectorXd u;
  double worst = 0, scale = 0;
  for (int s = 0; s < 500; ++s) {
    red.step();
    full.step();
    red.displacement(u);
    worst = std::max(worst, (u - full.u()).norm());
    scale = std::max(scale, full.u().norm());
    DOUBLES_EQUAL(full.output(p.felt_w), red.output(), 1e-9 * (1 + std::abs(red.output())));
  }
  CHECK_TRUE(worst < 1e-9 * scale);
}

TEST(Modal, static_correction_makes_few_modes_accurate_for_a_slow_push) {
  const auto& p = paper_problem();
  const ModalBasis b = compute_modes(p.model);
  const Eigen::VectorXd z = Eigen::VectorXd::Zero(3 * p.model.nodes);
  ExactResponse ex(b, p.model, z, z);
  ex.set_output(p.felt_w);
  ModalReducedModel plain(b, p.model, 6, 1e-3, false, p.felt_w), sc(b, p.model, 6, 1e-3, true, p.felt_w);
  double e_plain = 0, e_sc = 0, scale = 0;
  for (int s = 0; s < 1000; ++s) {
    plain.step();
    sc.step();
    const double F = p.felt_force(sc.time_s(), ex.output(sc.time_s()));
    scale = std::max(scale, std::abs(F));
    e_plain = std::max(e_plain, std::abs(p.felt_force(plain.time_s(), plain.output()) - F));
    e_sc = std::max(e_sc, std::abs(p.felt_force(sc.time_s(), sc.output()) - F));
  }
  CHECK_TRUE(e_sc < 0.02 * scale);
  CHECK_TRUE(e_plain > 5 * e_sc);
}

TEST(Modal, closed_form_mode_response_solves_its_ode) {
  PushProfile prof;
  for (double c : {0.0, 2.0, 40.0, 400.0}) {
    for (double w2 : {0.0, 25.0, 1e4}) {
      if (w2 == 0.0 && c == 0.0) continue;
      const double t = 0.37, d = 1e-4;
      auto q = [&](double tt) { return forced_mode_response(w2, c, prof, tt); };
      const double acc = (q(t + d) - 2 * q(t) + q(t - d)) / (d * d), vel = (q(t + d) - q(t - d)) / (2 * d);
      DOUBLES_EQUAL(prof.value(t), acc + c * vel + w2 * q(t), 1e-4 * (1 + std::abs(prof.value(t))));
      DOUBLES_EQUAL(0.0, q(0.0), 1e-12);
    }
  }
  // The free response from (q0, qd0): value and slope at 0.
  DOUBLES_EQUAL(0.3, free_mode_response(100.0, 1.0, 0.3, -2.0, 0.0), 1e-12);
  const double d = 1e-6;
  DOUBLES_EQUAL(-2.0, (free_mode_response(100.0, 1.0, 0.3, -2.0, d) - free_mode_response(100.0, 1.0, 0.3, -2.0, -d)) / (2 * d), 1e-5);
}

TEST(Modal, reduced_step_does_not_allocate) {
  const auto& p = paper_problem();
  const ModalBasis b = compute_modes(p.model);
  ModalReducedModel red(b, p.model, 10, 2e-3, true, p.felt_w);
  haptic::test::AllocationCounter count;
  double y = 0;
  for (int s = 0; s < 100; ++s) {
    red.step();
    y += red.output();
  }
  LONGS_EQUAL(0, count.allocations());
  CHECK_TRUE(std::isfinite(y));
}
