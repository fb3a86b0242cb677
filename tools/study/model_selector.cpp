#include "tools/study/model_selector.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>
#include <stdexcept>

namespace haptic::study {

void PushProblemParams::validate() const {
  auto need = [](bool ok, const char* key, const char* range) {
    if (!ok) throw std::invalid_argument(std::string("push problem: ") + key + " must be " + range);
  };
  need(radius_m > 0, "radius_m", "> 0");
  need(total_mass_kg > 0, "total_mass_kg", "> 0");
  need(reference_edge_stiffness_N_per_m > 0, "reference_edge_stiffness_N_per_m", "> 0");
  need(damping_per_s >= 0, "damping_per_s", ">= 0");
  need(contact_stiffness_N_per_m > 0, "contact_stiffness_N_per_m", "> 0");
  need(support_stiffness_N_per_m >= 0, "support_stiffness_N_per_m", ">= 0");
  need(cap_radius_m > 0 && cap_radius_m < radius_m, "cap_radius_m", "in (0, radius_m)");
  need(push_depth_m > 0 && push_depth_m < radius_m, "push_depth_m", "in (0, radius_m)");
  need(push_frequency_Hz > 0, "push_frequency_Hz", "> 0");
  need(direction.norm() > 0, "direction", "non-zero");
}

rt::TetMesh make_ball_mesh(int nodes, double radius_m) {
  return nodes == 33 ? rt::make_paper_ball(radius_m) : rt::make_lattice_ball(nodes, radius_m);
}

namespace {
double mean_edge_length(const rt::TetMesh& m) {
  double s = 0;
  for (const auto& e : m.edges) s += (m.nodes[static_cast<std::size_t>(e[0])] - m.nodes[static_cast<std::size_t>(e[1])]).norm();
  return s / static_cast<double>(m.edges.size());
}

// Surface nodes within `radius` of `pole`; at least the 3 nearest surface nodes.
std::vector<int> cap_nodes(const rt::TetMesh& m, const Eigen::Vector3d& pole, double radius) {
  std::set<int> surf;
  for (const auto& f : m.surface) surf.insert(f.begin(), f.end());
  std::vector<std::pair<double, int>> by_dist;
  for (int i : surf) by_dist.emplace_back((m.nodes[static_cast<std::size_t>(i)] - pole).norm(), i);
  std::sort(by_dist.begin(), by_dist.end());
  std::vector<int> out;
  for (std::size_t k = 0; k < by_dist.size(); ++k)
    if (by_dist[k].first <= radius || k < 3) out.push_back(by_dist[k].second);
  std::sort(out.begin(), out.end());
  return out;
}
}  // namespace

PushProblem make_push_problem(const rt::TetMesh& mesh, const PushProblemParams& params) {
  params.validate();
  if (mesh.edges.empty() || mesh.surface.empty()) throw std::invalid_argument("push problem: mesh has no edges/surface");
  static const double ref_len = mean_edge_length(rt::make_paper_ball(0.05)) / 0.05;  // per unit radius
  PushProblem p;
  p.params = params;
  p.mesh = mesh;
  const int n = mesh.node_count();
  const double m = params.total_mass_kg / n;
  p.edge_stiffness_N_per_m =
      params.reference_edge_stiffness_N_per_m * mean_edge_length(mesh) / (ref_len * params.radius_m);
  const Eigen::Vector3d e = params.direction.normalized();
  const Eigen::Vector3d c = mesh.centroid();
  p.contact_nodes = cap_nodes(mesh, c + params.radius_m * e, params.cap_radius_m);
  p.support_nodes = cap_nodes(mesh, c - params.radius_m * e, params.cap_radius_m);
  std::vector<Eigen::Triplet<double>> t;
  const double k = p.edge_stiffness_N_per_m;
  for (const auto& ed : mesh.edges) {
    t.emplace_back(ed[0], ed[0], k);
    t.emplace_back(ed[1], ed[1], k);
    t.emplace_back(ed[0], ed[1], -k);
    t.emplace_back(ed[1], ed[0], -k);
  }
  const double kc = params.contact_stiffness_N_per_m / static_cast<double>(p.contact_nodes.size());
  const double ks = params.support_stiffness_N_per_m / static_cast<double>(p.support_nodes.size());
  for (int i : p.contact_nodes) t.emplace_back(i, i, kc);
  for (int i : p.support_nodes) t.emplace_back(i, i, ks);
  p.model.nodes = n;
  p.model.node_mass_kg = m;
  p.model.damping_Ns_per_m = params.damping_per_s * m;
  p.model.K.resize(n, n);
  p.model.K.setFromTriplets(t.begin(), t.end());
  p.model.profile.omega_rad_per_s = 2.0 * std::numbers::pi * params.push_frequency_Hz;
  // Inward push: anchors move by -depth * e * s(t); force on contact node = kc (anchor - u).
  p.felt_w = Eigen::VectorXd::Zero(3 * n);
  for (int i : p.contact_nodes) p.felt_w.segment<3>(3 * i) = -kc * e;  // F along -e (into the ball)
  p.model.load = params.push_depth_m * p.felt_w;
  return p;
}

double PushProblem::felt_force(double t_s, double felt_w_dot_u) const {
  return params.contact_stiffness_N_per_m * params.push_depth_m * model.profile.value(t_s) - felt_w_dot_u;
}

Selection select_model(const std::vector<ModelCandidate>& candidates, double accuracy,
                       const std::vector<std::string>& kinds) {
  if (!(accuracy > 0)) throw std::invalid_argument("select: accuracy must be > 0 (a fraction, e.g. 0.05)");
  Selection s;
  bool have_ref = false;
  for (const auto& c : candidates) {
    if (!kinds.empty() && std::find(kinds.begin(), kinds.end(), c.kind) == kinds.end()) continue;
    if (!have_ref || c.cost_s_per_tick > s.reference.cost_s_per_tick) {
      s.reference = c;
      have_ref = true;
    }
    if (c.force_error <= accuracy && (!s.found || c.cost_s_per_tick < s.chosen.cost_s_per_tick)) {
      s.chosen = c;
      s.found = true;
    }
  }
  if (s.found && s.chosen.cost_s_per_tick > 0) s.cost_saving_factor = s.reference.cost_s_per_tick / s.chosen.cost_s_per_tick;
  return s;
}

}  // namespace haptic::study
