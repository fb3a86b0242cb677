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

}  // namespace haptic::rt
