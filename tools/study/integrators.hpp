#pragma once
// Reference integrators for the linear VO model of eq. (10) driven by a prescribed load, for the
// speed-against-accuracy study (tools/study):
//     M a + B v + K u = g s(t),   u = x - x_d,   M = m I_3n,  B = b I_3n,  K = S (x) I3,
// with S node-level n x n (isotropic, as every matrix of the paper's scene). The methods:
// explicit Euler, semi-implicit (symplectic) Euler, backward Euler, classical RK4, and NPMI =
// the implicit midpoint rule of eq. (9). The real-time station keeps its own NPMI
// (rt/station.cpp); these are the study's allocation-free stand-ins of the bare VO step, with
// the implicit methods solved by the same precomputed SparseLdlt (width 3) the station uses.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "rt/sparse_ldlt.hpp"
#include "rt/spatial_matrix.hpp"

namespace haptic::study {

enum class Integrator { kNpmi, kExplicitEuler, kSemiImplicitEuler, kBackwardEuler, kRk4 };

const char* integrator_name(Integrator method);  // "npmi", "explicit-euler", ...
// Throws std::invalid_argument listing the valid names.
Integrator parse_integrator(const std::string& name);
std::vector<Integrator> all_integrators();

// The smooth push profile s(t) = (1 - cos(Omega t)) / 2 (push in and release, C-infinity,
// s(0) = s'(0) = 0). The exact solution in tools/study/modal.hpp uses the same closed form.
struct PushProfile {
  double omega_rad_per_s = 6.283185307179586;  // 1 Hz push-release cycles
  double value(double t_s) const;
};

struct LinearModel {
  int nodes = 0;
  double node_mass_kg = 0.04;       // m
  double damping_Ns_per_m = 0.0;    // b
  rt::SparseRowMajor K;                 // node-level n x n stiffness S (symmetric, PSD)
  Eigen::VectorXd load;             // g: 3n interleaved force (N) at s = 1; empty or zero: free
  PushProfile profile;
  void validate() const;  // throws std::invalid_argument naming the field
};

// One integrator instance for one model and one step size. The constructor allocates and
// factors (start-up); step() does not allocate.
class LinearIntegrator {
 public:
  LinearIntegrator(const LinearModel& model, Integrator method, double step_s);

  void set_state(const Eigen::VectorXd& u, const Eigen::VectorXd& v);  // start-up
  // Back to rest at t = 0. RT-safe.
  void reset() {
    u_.setZero();
    v_.setZero();
    t_ = 0;
  }
  // Advance from t to t + h. RT-safe: no allocation, bounded work
  // (explicit: 1 product with K; RK4: 4; implicit: 1 product + 1 width-3 LDL^T solve).
  void step();
  double time_s() const { return t_; }
  double step_s() const { return h_; }
  Integrator method() const { return method_; }
  const Eigen::VectorXd& u() const { return u_; }
  const Eigen::VectorXd& v() const { return v_; }
  // 1/2 m v.v + 1/2 u.K u. RT-safe (uses internal scratch).
  double energy();
  // w . u for an output functional w (3n). RT-safe.
  double output(const Eigen::VectorXd& w) const { return w.dot(u_); }

 private:
  void force(double t, double* f) const;                       // f = g s(t)
  void acceleration(const double* u, const double* v, double t, double* a) const;  // RT-safe

  Integrator method_;
  double h_, t_ = 0, m_, b_;
  rt::SpatialMatrix K_;
  Eigen::VectorXd g_;
  bool driven_ = false;
  PushProfile profile_;
  rt::SparseLdlt ldlt_;
  Eigen::VectorXd u_, v_, r_, s_, scratch_;
  Eigen::VectorXd k1u_, k1v_, k2u_, k2v_, k3u_, k3v_, k4u_, k4v_, us_, vs_;
};

}  // namespace haptic::study
