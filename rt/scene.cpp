#include "rt/scene.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace haptic::rt {

void SceneParams::validate() const {
  auto need = [](bool ok, const char* key, const char* range) {
    if (!ok) throw std::invalid_argument(std::string("scene.") + key + " must be " + range);
  };
  need(node_mass_kg > 0 && std::isfinite(node_mass_kg), "node_mass_kg", "> 0");
  need(damping_Ns_per_m >= 0 && std::isfinite(damping_Ns_per_m), "damping_Ns_per_m", ">= 0");
  need(edge_stiffness_N_per_m > 0 && std::isfinite(edge_stiffness_N_per_m), "edge_stiffness_N_per_m", "> 0");
  need(ground_stiffness_N_per_m >= 0 && std::isfinite(ground_stiffness_N_per_m), "ground_stiffness_N_per_m", ">= 0");
}

Scene build_scene(const TetMesh& mesh, const SceneParams& params) {
  params.validate();
  if (mesh.node_count() < 2 || mesh.edges.empty()) throw std::invalid_argument("scene: mesh has no edges");
  Scene s;
  s.mesh = mesh;
  s.params = params;
  s.nodes = mesh.node_count();
  s.dofs = 3 * s.nodes;
  std::vector<Eigen::Triplet<double>> t;
  const double k = params.edge_stiffness_N_per_m;
  for (const auto& e : mesh.edges) {
    t.emplace_back(e[0], e[0], k);
    t.emplace_back(e[1], e[1], k);
    t.emplace_back(e[0], e[1], -k);
    t.emplace_back(e[1], e[0], -k);
  }
  SparseRowMajor Kint(s.nodes, s.nodes);
  Kint.setFromTriplets(t.begin(), t.end());
  s.K_int = SpatialMatrix::isotropic(Kint);
  const SpatialMatrix I = SpatialMatrix::identity(s.nodes);
  s.K = linear_combination({{1.0, &s.K_int}, {params.ground_stiffness_N_per_m, &I}});
  s.M = SpatialMatrix::identity(s.nodes, params.node_mass_kg);
  s.B = SpatialMatrix::identity(s.nodes, params.damping_Ns_per_m);
  s.x_d.resize(s.dofs);
  for (int i = 0; i < s.nodes; ++i) s.x_d.segment<3>(3 * i) = mesh.nodes[static_cast<std::size_t>(i)];
  s.lambda_max_K_int = lambda_max(s.K_int);
  return s;
}

double Scene::energy(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
  Eigen::VectorXd Mv = Eigen::VectorXd::Zero(dofs), Kd = Eigen::VectorXd::Zero(dofs);
  const Eigen::VectorXd d = x - x_d;
  M.multiply_add(1.0, v.data(), Mv.data());
  K.multiply_add(1.0, d.data(), Kd.data());
  return 0.5 * v.dot(Mv) + 0.5 * d.dot(Kd);
}

}  // namespace haptic::rt
