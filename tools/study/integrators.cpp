#include "tools/study/integrators.hpp"

#include <cmath>
#include <stdexcept>

namespace haptic::study {

namespace {
struct Named {
  Integrator method;
  const char* name;
};
constexpr Named kNames[] = {{Integrator::kNpmi, "npmi"},
                            {Integrator::kExplicitEuler, "explicit-euler"},
                            {Integrator::kSemiImplicitEuler, "semi-implicit-euler"},
                            {Integrator::kBackwardEuler, "backward-euler"},
                            {Integrator::kRk4, "rk4"}};
}  // namespace

const char* integrator_name(Integrator method) {
  for (const auto& n : kNames)
    if (n.method == method) return n.name;
  return "?";
}

Integrator parse_integrator(const std::string& name) {
  std::string valid;
  for (const auto& n : kNames) {
    if (name == n.name) return n.method;
    valid += std::string(valid.empty() ? "" : ", ") + n.name;
  }
  throw std::invalid_argument("integrator '" + name + "' unknown; valid: " + valid);
}

std::vector<Integrator> all_integrators() {
  std::vector<Integrator> v;
  for (const auto& n : kNames) v.push_back(n.method);
  return v;
}

double PushProfile::value(double t_s) const { return 0.5 * (1.0 - std::cos(omega_rad_per_s * t_s)); }

void LinearModel::validate() const {
  if (nodes < 1) throw std::invalid_argument("model.nodes must be >= 1");
  if (!(node_mass_kg > 0) || !std::isfinite(node_mass_kg)) throw std::invalid_argument("model.node_mass_kg must be > 0");
  if (!(damping_Ns_per_m >= 0) || !std::isfinite(damping_Ns_per_m))
    throw std::invalid_argument("model.damping_Ns_per_m must be >= 0");
  if (K.rows() != nodes || K.cols() != nodes) throw std::invalid_argument("model.K must be nodes x nodes (node-level)");
  if (load.size() != 0 && load.size() != 3 * nodes) throw std::invalid_argument("model.load must be empty or 3*nodes long");
}

LinearIntegrator::LinearIntegrator(const LinearModel& model, Integrator method, double step_s)
    : method_(method), h_(step_s), m_(model.node_mass_kg), b_(model.damping_Ns_per_m), profile_(model.profile) {
  model.validate();
  if (!(step_s > 0) || !std::isfinite(step_s)) throw std::invalid_argument("integrator step_s must be > 0");
  K_ = rt::SpatialMatrix::isotropic(model.K);
  const int dofs = 3 * model.nodes;
  g_ = model.load.size() ? model.load : Eigen::VectorXd::Zero(dofs);
  driven_ = g_.squaredNorm() > 0;
  for (auto* vec : {&u_, &v_, &r_, &s_, &scratch_}) vec->setZero(dofs);
  if (method == Integrator::kRk4)
    for (auto* vec : {&k1u_, &k1v_, &k2u_, &k2v_, &k3u_, &k3v_, &k4u_, &k4v_, &us_, &vs_}) vec->setZero(dofs);
  if (method == Integrator::kBackwardEuler || method == Integrator::kNpmi) {
    // Backward Euler: (m + h b) I + h^2 S;  NPMI (eq. 9): (2m/h + b) I + (h/2) S.
    const double diag = method == Integrator::kNpmi ? 2.0 * m_ / h_ + b_ : m_ + h_ * b_;
    const double kscale = method == Integrator::kNpmi ? 0.5 * h_ : h_ * h_;
    rt::SparseRowMajor I(model.nodes, model.nodes);
    I.setIdentity();
    rt::SparseRowMajor A = diag * I + kscale * model.K;
    ldlt_ = rt::SparseLdlt(rt::SparseColMajor(A));
  }
}

void LinearIntegrator::set_state(const Eigen::VectorXd& u, const Eigen::VectorXd& v) {
  if (u.size() != u_.size() || v.size() != v_.size()) throw std::invalid_argument("set_state: wrong vector size");
  u_ = u;
  v_ = v;
  t_ = 0;
}

void LinearIntegrator::force(double t, double* f) const {
  const double s = driven_ ? profile_.value(t) : 0.0;
  const long n = g_.size();
  for (long i = 0; i < n; ++i) f[i] = s * g_[i];
}

void LinearIntegrator::acceleration(const double* u, const double* v, double t, double* a) const {
  force(t, a);
  const long n = g_.size();
  for (long i = 0; i < n; ++i) a[i] -= b_ * v[i];
  K_.multiply_add(-1.0, u, a);
  const double inv_m = 1.0 / m_;
  for (long i = 0; i < n; ++i) a[i] *= inv_m;
}

void LinearIntegrator::step() {
  const long n = u_.size();
  double* u = u_.data();
  double* v = v_.data();
  double* r = r_.data();
  const double h = h_;
  switch (method_) {
    case Integrator::kExplicitEuler:
      acceleration(u, v, t_, r);
      for (long i = 0; i < n; ++i) {
        u[i] += h * v[i];
        v[i] += h * r[i];
      }
      break;
    case Integrator::kSemiImplicitEuler:
      acceleration(u, v, t_, r);
      for (long i = 0; i < n; ++i) {
        v[i] += h * r[i];
        u[i] += h * v[i];
      }
      break;
    case Integrator::kBackwardEuler:
      // (M + hB + h^2 K) v1 = M v - h K u + h f(t + h);  u1 = u + h v1
      force(t_ + h, r);
      for (long i = 0; i < n; ++i) r[i] = m_ * v[i] + h * r[i];
      K_.multiply_add(-h, u, r);
      ldlt_.solve_in_place(r, 3, scratch_.data());
      for (long i = 0; i < n; ++i) {
        v[i] = r[i];
        u[i] += h * r[i];
      }
      break;
    case Integrator::kNpmi:
      // eq. (9): (2M/h + B + h/2 K) v_hat = 2M/h v - K u + f(t + h/2); v1 = 2 v_hat - v; u1 = u + h v_hat
      force(t_ + 0.5 * h, r);
      for (long i = 0; i < n; ++i) r[i] += 2.0 * m_ / h * v[i];
      K_.multiply_add(-1.0, u, r);
      ldlt_.solve_in_place(r, 3, scratch_.data());
      for (long i = 0; i < n; ++i) {
        v[i] = 2.0 * r[i] - v[i];
        u[i] += h * r[i];
      }
      break;
    case Integrator::kRk4: {
      double *us = us_.data(), *vs = vs_.data();
      double* ku[4] = {k1u_.data(), k2u_.data(), k3u_.data(), k4u_.data()};
      double* kv[4] = {k1v_.data(), k2v_.data(), k3v_.data(), k4v_.data()};
      for (long i = 0; i < n; ++i) ku[0][i] = v[i];
      acceleration(u, v, t_, kv[0]);
      const double c[3] = {0.5 * h, 0.5 * h, h};
      for (int s = 1; s < 4; ++s) {
        for (long i = 0; i < n; ++i) {
          us[i] = u[i] + c[s - 1] * ku[s - 1][i];
          vs[i] = v[i] + c[s - 1] * kv[s - 1][i];
          ku[s][i] = vs[i];
        }
        acceleration(us, vs, t_ + c[s - 1], kv[s]);
      }
      for (long i = 0; i < n; ++i) {
        u[i] += h / 6.0 * (ku[0][i] + 2 * ku[1][i] + 2 * ku[2][i] + ku[3][i]);
        v[i] += h / 6.0 * (kv[0][i] + 2 * kv[1][i] + 2 * kv[2][i] + kv[3][i]);
      }
      break;
    }
  }
  t_ += h;
}

double LinearIntegrator::energy() {
  s_.setZero();
  K_.multiply_add(1.0, u_.data(), s_.data());
  return 0.5 * m_ * v_.squaredNorm() + 0.5 * u_.dot(s_);
}

}  // namespace haptic::study
