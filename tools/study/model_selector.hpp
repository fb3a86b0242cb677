#pragma once
// "No more model than a scene needs": the study's test problem on a family of meshes of the
// same physical ball, and the selector that picks the cheapest model meeting a requested
// accuracy of the felt contact force. Start-up / analysis only (allocates).
//
// Test problem (documented in tools/study/README.md): the ball (radius R, total mass fixed,
// node mass = total / n, edge stiffness scaled with the mean edge length so the spring lattice
// keeps its elastic modulus across resolutions) is squeezed between
//   - a VP held by a stiff spring: the surface nodes of a cap (radius cap_radius_m around the
//     pole in `direction`) are tied by springs of total stiffness contact_stiffness_N_per_m to
//     anchors that move inward by push_depth_m * s(t), s(t) = (1 - cos Omega t)/2, and
//   - a second user holding still: the antipodal cap tied by support_stiffness_N_per_m to fixed
//     anchors.
// Felt force (what the user feels, along the push direction):
//   F(t) = contact_stiffness * push_depth * s(t) - felt_w . u(t).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "tools/study/integrators.hpp"
#include "rt/mesh.hpp"

namespace haptic::study {

struct PushProblemParams {
  double radius_m = 0.05;
  double total_mass_kg = 1.32;                   // 33 nodes x 0.04 kg (paper)
  double reference_edge_stiffness_N_per_m = 100.0;  // on the paper ball (K_rs); scaled by edge length
  double damping_per_s = 0.0;                    // b / m (paper: B = 0)
  double contact_stiffness_N_per_m = 600.0;      // paper k_c = 200 N/m on 3 contact nodes
  double support_stiffness_N_per_m = 600.0;
  double cap_radius_m = 0.02;
  double push_depth_m = 0.01;
  double push_frequency_Hz = 1.0;
  Eigen::Vector3d direction{1.0, 0.35, 0.2};     // outward normal of the pushed cap
  void validate() const;  // throws std::invalid_argument naming the key
};

struct PushProblem {
  PushProblemParams params;
  rt::TetMesh mesh;
  LinearModel model;
  Eigen::VectorXd felt_w;  // 3n: F = contact_stiffness * depth * s(t) - felt_w . u
  std::vector<int> contact_nodes, support_nodes;
  double edge_stiffness_N_per_m = 0;
  double felt_force(double t_s, double felt_w_dot_u) const;
};

// The mesh the station uses for --nodes N: 33 = the paper ball, otherwise a lattice ball.
rt::TetMesh make_ball_mesh(int nodes, double radius_m);
PushProblem make_push_problem(const rt::TetMesh& mesh, const PushProblemParams& params);

struct ModelCandidate {
  std::string kind;          // "mesh" (full model of a mesh), "modal", "modal+sc" (static correction)
  int nodes = 0;             // mesh nodes (of the mesh the modes come from, for modal kinds)
  int modes = 0;             // modal kinds: r; 0 otherwise
  double step_s = 0.002;
  double force_error = 0;    // max |F - F_ref| / max |F_ref| over the run, against the reference
  double cost_s_per_tick = 0;  // measured (tools) or any monotone cost proxy (tests)
};

struct Selection {
  bool found = false;
  ModelCandidate chosen;
  ModelCandidate reference;   // the most costly candidate of the family (the "finest model")
  double cost_saving_factor = 0;  // reference cost / chosen cost
};

// The cheapest candidate whose force_error <= accuracy, among kinds listed in `kinds`
// (empty: all). `accuracy` must be > 0 (std::invalid_argument otherwise).
Selection select_model(const std::vector<ModelCandidate>& candidates, double accuracy,
                       const std::vector<std::string>& kinds = {});

}  // namespace haptic::study
