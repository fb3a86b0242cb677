#pragma once
// The tight case, where eq. (18) nearly decides stability: the paper's star with every
// one-way delay 1.33 ms (Nbar_ij = 1), no loss, no duplication, no loss allowance, D_ij = 0, user 1
// perturbing at 2.5 s, and the per-edge energy bound off (its tripped edges act as dampers and keep
// even 0.45 x eq. (18) from diverging, so eq. (18) alone decides here). B_i = factor x eq. (18)
// (unset: the scenario's default, eq. 18 + margin). One definition for every test that uses it.
#include <Eigen/Dense>
#include <optional>
#include <vector>

#include "firmware/scenario.hpp"

namespace haptic::test {

inline firmware::ScenarioSpec tight_case_spec(std::optional<double> factor_of_eq18, double delay_correlation = 0.0,
                                              std::optional<double> duration_s = std::nullopt) {
  firmware::ScenarioSpec s = firmware::make_scenario("paper-unstable");
  s.delay_ms = Eigen::MatrixXd::Constant(4, 4, 1.33);
  s.delay_ms.diagonal().setZero();
  s.loss_probability = 0;
  s.duplicate_probability = 0;
  s.loss_allowance_ticks = 0;
  s.d_gain_Ns_per_m = 0;
  s.edge_energy_bound_J = 0;
  s.delay_correlation = delay_correlation;
  if (duration_s) s.duration_s = *duration_s;
  s.damping_Ns_per_m.reset();
  if (factor_of_eq18) {
    const firmware::BuiltScenario b = firmware::build_scenario(s);
    std::vector<double> d;
    for (double m : b.damping_min) d.push_back(*factor_of_eq18 * m);
    s.damping_Ns_per_m = d;
  }
  return s;
}

}  // namespace haptic::test
