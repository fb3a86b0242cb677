// Reference integrators (tools/study/integrators.hpp): order of convergence against the exact modal
// solution, NPMI energy conservation, explicit Euler energy growth (passivity failure), no heap
// allocation in step().
#include <CppUTest/TestHarness.h>

#include <cmath>

#include "tools/study/integrators.hpp"
#include "tools/study/modal.hpp"
#include "tools/study/model_selector.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic::rt;
using namespace haptic::study;

namespace {
// A small undamped spring system: a 4-node chain tied to ground at node 0, pushed at node 3.
LinearModel chain(double damping = 0.0) {
  LinearModel m;
  m.nodes = 4;
  m.node_mass_kg = 0.04;
  m.damping_Ns_per_m = damping;
  std::vector<Eigen::Triplet<double>> t;
  auto spring = [&](int i, int j, double k) {
    t.emplace_back(i, i, k);
    t.emplace_back(j, j, k);
    t.emplace_back(i, j, -k);
    t.emplace_back(j, i, -k);
  };
  spring(0, 1, 100);
  spring(1, 2, 100);
  spring(2, 3, 100);
  t.emplace_back(0, 0, 200.0);  // ground
  m.K.resize(4, 4);
  m.K.setFromTriplets(t.begin(), t.end());
  m.load = Eigen::VectorXd::Zero(12);
  m.load.segment<3>(9) = Eigen::Vector3d(1.0, -0.5, 0.25);
  m.profile.omega_rad_per_s = 2 * M_PI * 2.0;
  return m;
}

double error_at(const LinearModel& m, Integrator method, double h, double T) {
  LinearIntegrator integ(m, method, h);
  const long steps = std::lround(T / h);
  for (long s = 0; s < steps; ++s) integ.step();
  const ModalBasis b = compute_modes(m);
  const Eigen::VectorXd z = Eigen::VectorXd::Zero(12);
  ExactResponse ex(b, m, z, z);
  Eigen::VectorXd u;
  ex.displacement(integ.time_s(), u);
  return (integ.u() - u).norm() / u.norm();
}

double observed_order(Integrator method, double h) {
  const LinearModel m = chain(0.5);
  const double e1 = error_at(m, method, h, 0.5), e2 = error_at(m, method, h / 2, 0.5);
  return std::log2(e1 / e2);
}

double energy_ratio(Integrator method, double h, double T) {
  LinearModel m = chain();
  m.load.resize(0);
  LinearIntegrator integ(m, method, h);
  Eigen::VectorXd u0 = Eigen::VectorXd::Zero(12);
  u0[9] = 0.01;
  u0[4] = -0.004;
  integ.set_state(u0, Eigen::VectorXd::Zero(12));
  const double E0 = integ.energy();
  const long steps = std::lround(T / h);
  for (long s = 0; s < steps; ++s) integ.step();
  return integ.energy() / E0;
}
}  // namespace

TEST_GROUP(Integrators){};

TEST(Integrators, npmi_and_backward_euler_converge_with_orders_two_and_one) {
  const double p_npmi = observed_order(Integrator::kNpmi, 1e-3);
  const double p_be = observed_order(Integrator::kBackwardEuler, 1e-3);
  CHECK_TRUE(p_npmi > 1.9 && p_npmi < 2.1);
  CHECK_TRUE(p_be > 0.9 && p_be < 1.2);
}

TEST(Integrators, rk4_converges_with_order_four) {
  const double p = observed_order(Integrator::kRk4, 2e-3);
  CHECK_TRUE(p > 3.8 && p < 4.3);
}

TEST(Integrators, explicit_and_semi_implicit_euler_converge_with_order_one) {
  const double pe = observed_order(Integrator::kExplicitEuler, 1e-4);
  const double ps = observed_order(Integrator::kSemiImplicitEuler, 1e-4);
  CHECK_TRUE(pe > 0.9 && pe < 1.2);
  CHECK_TRUE(ps > 0.9 && ps < 1.2);
}

TEST(Integrators, npmi_conserves_energy_of_an_undamped_spring_system) {
  DOUBLES_EQUAL(1.0, energy_ratio(Integrator::kNpmi, 2e-3, 20.0), 1e-10);
  DOUBLES_EQUAL(1.0, energy_ratio(Integrator::kNpmi, 8e-3, 20.0), 1e-10);  // any step size
}

TEST(Integrators, explicit_euler_generates_energy_passivity_failure) {
  const double r = energy_ratio(Integrator::kExplicitEuler, 2e-3, 5.0);
  CHECK_TRUE(r > 10.0);
  // ... and backward Euler removes it (numerical dissipation), semi-implicit stays bounded.
  CHECK_TRUE(energy_ratio(Integrator::kBackwardEuler, 2e-3, 5.0) < 0.9);
  const double si = energy_ratio(Integrator::kSemiImplicitEuler, 2e-3, 5.0);
  CHECK_TRUE(si > 0.8 && si < 1.25);
}

TEST(Integrators, exact_solution_matches_a_tiny_step_npmi_run) {
  const LinearModel m = chain();  // undamped, driven
  CHECK_TRUE(error_at(m, Integrator::kNpmi, 2.5e-5, 1.0) < 1e-5);
}

TEST(Integrators, step_does_not_allocate) {
  const LinearModel m = chain();
  for (auto method : all_integrators()) {
    LinearIntegrator integ(m, method, 1e-3);
    haptic::test::AllocationCounter count;
    for (int s = 0; s < 100; ++s) integ.step();
    (void)integ.energy();
    LONGS_EQUAL(0, count.allocations());
  }
}

TEST(Integrators, names_round_trip_and_bad_names_are_refused) {
  for (auto m : all_integrators()) CHECK_TRUE(parse_integrator(integrator_name(m)) == m);
  CHECK_THROWS(std::invalid_argument, parse_integrator("leapfrog"));
  CHECK_THROWS(std::invalid_argument, LinearIntegrator(chain(), Integrator::kNpmi, 0.0));
}
