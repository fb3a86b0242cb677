#pragma once
// The linear deformable virtual object of eq. (10): M, B = B_int + B_gnd, K = K_int + K_gnd,
// x_d, built from a tetrahedral mesh with a spring K_rs = k I3 on every edge. Start-up only.
#include <Eigen/Core>
#include <vector>

#include "rt/mesh.hpp"
#include "rt/spatial_matrix.hpp"

namespace haptic::rt {

struct SceneParams {
  double node_mass_kg = 0.04;             // M = m I_3n (paper: 0.04)
  double damping_Ns_per_m = 0.0;          // B = b I_3n (paper: 0)
  double edge_stiffness_N_per_m = 100.0;  // K_rs = k I3 on each mesh edge (paper: 100)
  double ground_stiffness_N_per_m = 0.0;  // K_gnd = k_gnd I on every node (paper: 0, floating)
  void validate() const;                  // throws std::invalid_argument naming the key
};

// A material: the same physical object at any resolution. Lumped masses
// m_i = rho sum_{t ni i} V_t / 4 (total mass rho V) and one spring per edge with van Gelder's
// stiffness k_e = E sum_{t ni e} V_t / |e|^2 (A. van Gelder, "Approximate simulation of elastic
// membranes by triangulated spring meshes", 1998, 3-D form): k_e scales like E h, the spring
// network's modulus like k / h, so refining a mesh keeps the object (the study's rule for balls).
struct Material {
  double density_kg_per_m3 = 0;
  double youngs_modulus_Pa = 0;
  void validate() const;  // throws std::invalid_argument naming scene.density_kg_per_m3 / scene.youngs_modulus_Pa
};

// The material that makes the paper's 33-node ball of radius 5 cm have the paper's total mass
// (33 x 0.04 kg) and mean edge stiffness (100 N/m): the default for scenes read from files.
Material paper_ball_material();

struct LumpedModel {
  std::vector<double> node_mass_kg;            // one per node
  std::vector<double> edge_stiffness_N_per_m;  // one per mesh.edges entry
  double volume_m3 = 0;
};
// Throws std::invalid_argument when a tetrahedron has zero volume. Start-up only.
LumpedModel lump_material(const TetMesh& mesh, const Material& material);

struct Scene {
  TetMesh mesh;
  SceneParams params;
  int nodes = 0;
  int dofs = 0;                 // 3n
  SpatialMatrix M, B, K_int, K;  // all isotropic
  Eigen::VectorXd x_d;           // rest configuration (3n, interleaved)
  double lambda_max_K_int = 0;   // for the paper's P_ij

  // Energy 1/2 v^T M v + 1/2 (x - x_d)^T K (x - x_d) (unscaled). Start-up / analysis only.
  double energy(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const;
};

Scene build_scene(const TetMesh& mesh, const SceneParams& params);
// M = diag(node masses) (x) I3, K_int from per-edge springs; params gives B and K_gnd (its node
// mass and edge stiffness are replaced by the lumped model's means, for reports).
Scene build_scene(const TetMesh& mesh, const SceneParams& params, const LumpedModel& lumped);

}  // namespace haptic::rt
