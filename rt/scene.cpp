#include "rt/scene.hpp"

#include <algorithm>
#include <array>
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

void Material::validate() const {
  if (!(density_kg_per_m3 > 0 && std::isfinite(density_kg_per_m3)))
    throw std::invalid_argument("scene.density_kg_per_m3 must be > 0 (kg/m^3)");
  if (!(youngs_modulus_Pa > 0 && std::isfinite(youngs_modulus_Pa)))
    throw std::invalid_argument("scene.youngs_modulus_Pa must be > 0 (Pa)");
}

namespace {
// Index of each tetrahedron edge (6 per tet, a < b) in mesh.edges; throws if one is missing.
std::vector<int> tet_edge_index(const TetMesh& mesh) {
  std::vector<std::pair<std::array<int, 2>, int>> sorted;
  sorted.reserve(mesh.edges.size());
  for (std::size_t i = 0; i < mesh.edges.size(); ++i) sorted.push_back({mesh.edges[i], static_cast<int>(i)});
  std::sort(sorted.begin(), sorted.end());
  std::vector<int> index;
  index.reserve(mesh.tets.size() * 6);
  for (const auto& q : mesh.tets)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const std::array<int, 2> e{std::min(q[a], q[b]), std::max(q[a], q[b])};
        const auto it = std::lower_bound(sorted.begin(), sorted.end(), std::make_pair(e, -1));
        if (it == sorted.end() || it->first != e) throw std::out_of_range("scene: a tetrahedron edge is not in the mesh's edges");
        index.push_back(it->second);
      }
  return index;
}
}  // namespace

LumpedModel lump_material(const TetMesh& mesh, const Material& material) {
  material.validate();
  LumpedModel out;
  out.node_mass_kg.assign(mesh.nodes.size(), 0.0);
  const std::vector<int> edge_of = tet_edge_index(mesh);
  std::vector<double> edge_volume(mesh.edges.size(), 0.0);
  for (int t = 0; t < static_cast<int>(mesh.tets.size()); ++t) {
    const double v = std::abs(mesh.tet_volume(t));  // orientation is the readers' check (scene/mesh_check)
    if (!(v > 0)) throw std::invalid_argument("scene: tetrahedron " + std::to_string(t) + " has no volume");
    out.volume_m3 += v;
    const auto& q = mesh.tets[static_cast<std::size_t>(t)];
    const int* e = edge_of.data() + 6 * static_cast<std::size_t>(t);
    for (int a = 0; a < 4; ++a) {
      out.node_mass_kg[static_cast<std::size_t>(q[a])] += material.density_kg_per_m3 * v / 4.0;
      for (int b = a + 1; b < 4; ++b) edge_volume[static_cast<std::size_t>(*e++)] += v;
    }
  }
  out.edge_stiffness_N_per_m.reserve(mesh.edges.size());
  for (std::size_t i = 0; i < mesh.edges.size(); ++i) {
    const auto& e = mesh.edges[i];
    const double len2 = (mesh.nodes[static_cast<std::size_t>(e[0])] - mesh.nodes[static_cast<std::size_t>(e[1])]).squaredNorm();
    out.edge_stiffness_N_per_m.push_back(material.youngs_modulus_Pa * edge_volume[i] / len2);
  }
  return out;
}

Material paper_ball_material() {
  const TetMesh ball = make_paper_ball(0.05);
  const LumpedModel unit = lump_material(ball, Material{1.0, 1.0});
  double k = 0;
  for (double ke : unit.edge_stiffness_N_per_m) k += ke;
  k /= static_cast<double>(unit.edge_stiffness_N_per_m.size());
  return Material{33 * 0.04 / unit.volume_m3, 100.0 / k};
}

namespace {
Scene assemble(const TetMesh& mesh, const SceneParams& params, const std::vector<double>& mass, const std::vector<double>& stiffness) {
  params.validate();
  if (mesh.node_count() < 2 || mesh.edges.empty()) throw std::invalid_argument("scene: mesh has no edges");
  Scene s;
  s.mesh = mesh;
  s.params = params;
  s.nodes = mesh.node_count();
  s.dofs = 3 * s.nodes;
  std::vector<Eigen::Triplet<double>> t;
  for (std::size_t i = 0; i < mesh.edges.size(); ++i) {
    const auto& e = mesh.edges[i];
    const double k = stiffness[i];
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
  std::vector<Eigen::Triplet<double>> m;
  for (int i = 0; i < s.nodes; ++i) m.emplace_back(i, i, mass[static_cast<std::size_t>(i)]);
  SparseRowMajor Mn(s.nodes, s.nodes);
  Mn.setFromTriplets(m.begin(), m.end());
  s.M = SpatialMatrix::isotropic(Mn);
  s.B = SpatialMatrix::identity(s.nodes, params.damping_Ns_per_m);
  s.x_d.resize(s.dofs);
  for (int i = 0; i < s.nodes; ++i) s.x_d.segment<3>(3 * i) = mesh.nodes[static_cast<std::size_t>(i)];
  s.lambda_max_K_int = lambda_max(s.K_int);
  return s;
}
}  // namespace

Scene build_scene(const TetMesh& mesh, const SceneParams& params) {
  params.validate();
  return assemble(mesh, params, std::vector<double>(mesh.nodes.size(), params.node_mass_kg),
                  std::vector<double>(mesh.edges.size(), params.edge_stiffness_N_per_m));
}

Scene build_scene(const TetMesh& mesh, const SceneParams& params, const LumpedModel& lumped) {
  if (lumped.node_mass_kg.size() != mesh.nodes.size() || lumped.edge_stiffness_N_per_m.size() != mesh.edges.size())
    throw std::invalid_argument("scene: lumped model does not match the mesh");
  SceneParams p = params;
  double m = 0, k = 0;
  for (double x : lumped.node_mass_kg) m += x;
  for (double x : lumped.edge_stiffness_N_per_m) k += x;
  p.node_mass_kg = m / static_cast<double>(mesh.nodes.size());
  p.edge_stiffness_N_per_m = k / static_cast<double>(mesh.edges.size());
  return assemble(mesh, p, lumped.node_mass_kg, lumped.edge_stiffness_N_per_m);
}

double Scene::energy(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
  Eigen::VectorXd Mv = Eigen::VectorXd::Zero(dofs), Kd = Eigen::VectorXd::Zero(dofs);
  const Eigen::VectorXd d = x - x_d;
  M.multiply_add(1.0, v.data(), Mv.data());
  K.multiply_add(1.0, d.data(), Kd.data());
  return 0.5 * v.dot(Mv) + 0.5 * d.dot(Kd);
}

}  // namespace haptic::rt
