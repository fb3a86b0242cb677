#pragma once
// Modal analysis of the isotropic linear VO model (tools/study/integrators.hpp): the generalized
// eigenproblem S phi = omega^2 m phi on the node-level n x n matrix (dense, start-up only), the
// EXACT response to the push profile s(t) = (1 - cos Omega t)/2 in closed form (mode by mode), and
// the modally truncated reduced model (r modes, optionally with a static correction of the
// truncated modes' quasi-static response) stepped with NPMI in modal coordinates.
#include <Eigen/Core>

#include "tools/study/integrators.hpp"

namespace haptic::study {

struct ModalBasis {
  double node_mass_kg = 0;
  double damping_Ns_per_m = 0;
  Eigen::VectorXd omega2;  // eigenvalues omega_k^2 (1/s^2), ascending
  Eigen::MatrixXd phi;     // n x n node-level, mass-orthonormal: phi^T (m I) phi = I
  int modes() const { return static_cast<int>(omega2.size()); }
};

// Dense SelfAdjointEigenSolver on S / m: O(n^3), start-up / analysis only (3000 nodes: ~1 min).
ModalBasis compute_modes(const LinearModel& model);

// Scalar mode q'' + c q' + w2 q = s(t) from rest (q(0) = q'(0) = 0), closed form, and the free
// response q'' + c q' + w2 q = 0 from (q0, qd0). Throw std::domain_error at undamped resonance.
double forced_mode_response(double w2, double c, const PushProfile& p, double t);
double free_mode_response(double w2, double c, double q0, double qd0, double t);

// The exact solution of the full linear model (3n) from u(0) = u0, v(0) = v0.
class ExactResponse {
 public:
  ExactResponse(const ModalBasis& basis, const LinearModel& model, const Eigen::VectorXd& u0,
                const Eigen::VectorXd& v0);
  // u(t) into `u` (3n interleaved). Analysis only: O(n^2).
  void displacement(double t, Eigen::VectorXd& u) const;
  // w . u(t) for an output functional w (3n) set once with set_output (O(n^2)); then O(n).
  void set_output(const Eigen::VectorXd& w);
  double output(double t) const;

 private:
  void modal_coordinates(double t, Eigen::MatrixXd& q) const;
  const ModalBasis* basis_;
  PushProfile profile_;
  double c_;
  Eigen::MatrixXd gamma_, q0_, qd0_, w_modal_;  // modes x 3
};

// The reduced model: the r lowest modes, each stepped with NPMI (eq. 9) in modal coordinates
// (exactly what NPMI on the full model does to that mode), plus optionally the static correction
// u_sc(t) = sum_{k > r} phi_k gamma_k / omega_k^2 s(t). Starts from rest.
class ModalReducedModel {
 public:
  ModalReducedModel(const ModalBasis& basis, const LinearModel& model, int modes, double step_s,
                    bool static_correction, const Eigen::VectorXd& output_w);
  // One step, then the output w . u (RT-safe: no allocation, O(r) work).
  void step();
  double output() const;  // w . u at the current time (includes the static correction)
  double time_s() const { return t_; }
  int modes() const { return r_; }
  // Full displacement at the current time (analysis only: O(n r)).
  void displacement(Eigen::VectorXd& u) const;

 private:
  const ModalBasis* basis_;
  PushProfile profile_;
  int r_;
  double h_, t_ = 0, c_;
  bool sc_;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> q_, qd_, gamma_, w_, sc_shape_;
  Eigen::VectorXd inv_diag_, w2_;
  double sc_output_ = 0;  // w . (static-correction shape)
};

}  // namespace haptic::study
