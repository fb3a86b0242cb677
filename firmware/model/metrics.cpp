#include "firmware/model/metrics.hpp"

#include <algorithm>
#include <cmath>

namespace haptic::model {

double max_node_distance_m(const double* x, const double* y, int nodes) {
  double m = 0;
  for (int p = 0; p < nodes; ++p) m = std::max(m, (Eigen::Map<const Eigen::Vector3d>(x + 3 * p) - Eigen::Map<const Eigen::Vector3d>(y + 3 * p)).norm());
  return m;
}

double consensus_error_m(std::span<const double* const> x, int nodes) {
  double err = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j) err = std::max(err, max_node_distance_m(x[i], x[j], nodes));
  return std::isfinite(err) ? err : INFINITY;
}

namespace {
Eigen::VectorXd mean_copy(std::span<const double* const> x, Eigen::Index dofs) {
  Eigen::VectorXd xbar = Eigen::VectorXd::Zero(dofs);
  for (const double* xi : x) xbar += Eigen::Map<const Eigen::VectorXd>(xi, dofs);
  xbar /= static_cast<double>(x.size());
  return xbar;
}
}  // namespace

double deformation_m(std::span<const double* const> x, const Eigen::VectorXd& x_d) {
  const auto dofs = x_d.size();
  const auto n = static_cast<int>(dofs / 3);
  const Eigen::VectorXd xbar = mean_copy(x, dofs);
  Eigen::Vector3d mean_disp = Eigen::Vector3d::Zero();
  for (int p = 0; p < n; ++p) mean_disp += xbar.segment<3>(3 * p) - x_d.segment<3>(3 * p);
  mean_disp /= n;
  double def2 = 0;
  for (int p = 0; p < n; ++p) def2 += (xbar.segment<3>(3 * p) - x_d.segment<3>(3 * p) - mean_disp).squaredNorm();
  return std::sqrt(def2 / n);
}

Eigen::Vector3d mean_node_position_m(std::span<const double* const> x, int node) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (const double* xi : x) m += Eigen::Map<const Eigen::Vector3d>(xi + 3 * node);
  return m / static_cast<double>(x.size());
}

std::vector<std::vector<double>> distance_from_mean_shape_m(std::span<const double* const> x, int nodes) {
  const Eigen::VectorXd xbar = mean_copy(x, 3 * static_cast<Eigen::Index>(nodes));
  std::vector<std::vector<double>> d;
  for (const double* xi : x) {
    d.emplace_back();
    for (int p = 0; p < nodes; ++p) d.back().push_back((Eigen::Map<const Eigen::Vector3d>(xi + 3 * p) - xbar.segment<3>(3 * p)).norm());
  }
  return d;
}

ForceBalance force_balance(std::span<const Eigen::Vector3d> forces) {
  ForceBalance b;
  const auto N = static_cast<double>(forces.size());
  for (const auto& f : forces) {
    b.sum_N += f;
    b.mean_norm_N += f.norm() / N;
  }
  b.sum_norm_N = b.sum_N.norm();
  return b;
}

double force_balance_ratio(double sum_norm_N, double mean_norm_N) { return mean_norm_N > 0 ? sum_norm_N / mean_norm_N : NAN; }

}  // namespace haptic::model
