#include "tools/study/modal.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>

namespace haptic::study {

namespace {
using NodeMat = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
Eigen::Map<const NodeMat> node_view(const Eigen::VectorXd& v) { return {v.data(), v.size() / 3, 3}; }
}  // namespace

ModalBasis compute_modes(const LinearModel& model) {
  model.validate();
  ModalBasis b;
  b.node_mass_kg = model.node_mass_kg;
  b.damping_Ns_per_m = model.damping_Ns_per_m;
  const Eigen::MatrixXd S = Eigen::MatrixXd(model.K) / model.node_mass_kg;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  if (es.info() != Eigen::Success) throw std::runtime_error("compute_modes: eigen-decomposition failed");
  b.omega2 = es.eigenvalues();
  const double top = b.omega2.cwiseAbs().maxCoeff();
  for (Eigen::Index k = 0; k < b.omega2.size(); ++k)
    if (std::abs(b.omega2[k]) <= 1e-11 * top) b.omega2[k] = 0.0;  // rigid-body modes of a floating scene
  b.phi = es.eigenvectors() / std::sqrt(model.node_mass_kg);
  return b;
}

double free_mode_response(double w2, double c, double q0, double qd0, double t) {
  const double disc = c * c - 4.0 * w2;
  const double scale = std::max({c * c, 4.0 * w2, 1e-300});
  if (std::abs(disc) <= 1e-12 * scale) {  // repeated root (includes w2 = c = 0)
    const double r = -0.5 * c;
    return (q0 + (qd0 - r * q0) * t) * std::exp(r * t);
  }
  if (disc < 0) {
    const double wd = 0.5 * std::sqrt(-disc), sigma = -0.5 * c;
    return std::exp(sigma * t) * (q0 * std::cos(wd * t) + (qd0 - sigma * q0) / wd * std::sin(wd * t));
  }
  const double sq = std::sqrt(disc);
  const double r1 = 0.5 * (-c + sq), r2 = 0.5 * (-c - sq);
  const double B = (qd0 - r1 * q0) / (r2 - r1), A = q0 - B;
  return A * std::exp(r1 * t) + B * std::exp(r2 * t);
}

double forced_mode_response(double w2, double c, const PushProfile& p, double t) {
  // s(t) = 1/2 - 1/2 cos(Omega t): particular solution of each part, then the free response
  // that cancels its initial value and slope (start from rest).
  const double W = p.omega_rad_per_s;
  double qc = 0, qc0 = 0, qcd0 = 0;
  if (w2 > 0) {
    qc = qc0 = 0.5 / w2;
  } else if (c > 0) {
    qc = 0.5 * t / c;
    qcd0 = 0.5 / c;
  } else {
    qc = 0.25 * t * t;
  }
  const std::complex<double> Z(w2 - W * W, c * W);
  if (std::abs(Z) <= 1e-12 * (std::abs(w2) + W * W)) throw std::domain_error("forced_mode_response: undamped resonance");
  const std::complex<double> I(0.0, 1.0);
  const double qp = -0.5 * std::real(std::exp(I * (W * t)) / Z);
  const double qp0 = -0.5 * std::real(1.0 / Z);
  const double qpd0 = -0.5 * std::real(I * W / Z);
  return qc + qp + free_mode_response(w2, c, -(qc0 + qp0), -(qcd0 + qpd0), t);
}

ExactResponse::ExactResponse(const ModalBasis& basis, const LinearModel& model, const Eigen::VectorXd& u0,
                             const Eigen::VectorXd& v0)
    : basis_(&basis), profile_(model.profile), c_(model.damping_Ns_per_m / model.node_mass_kg) {
  const int n = model.nodes;
  if (basis.phi.rows() != n) throw std::invalid_argument("ExactResponse: basis and model sizes differ");
  const Eigen::MatrixXd PhiT = basis.phi.transpose();
  gamma_ = model.load.size() ? Eigen::MatrixXd(PhiT * node_view(model.load)) : Eigen::MatrixXd::Zero(n, 3);
  q0_ = model.node_mass_kg * (PhiT * node_view(u0));
  qd0_ = model.node_mass_kg * (PhiT * node_view(v0));
}

void ExactResponse::modal_coordinates(double t, Eigen::MatrixXd& q) const {
  const int r = basis_->modes();
  q.resize(r, 3);
  for (int k = 0; k < r; ++k) {
    const double w2 = basis_->omega2[k];
    const double f = forced_mode_response(w2, c_, profile_, t);
    for (int d = 0; d < 3; ++d)
      q(k, d) = gamma_(k, d) * f + free_mode_response(w2, c_, q0_(k, d), qd0_(k, d), t);
  }
}

void ExactResponse::displacement(double t, Eigen::VectorXd& u) const {
  Eigen::MatrixXd q;
  modal_coordinates(t, q);
  const NodeMat U = basis_->phi * q;
  u = Eigen::Map<const Eigen::VectorXd>(U.data(), U.size());
}

void ExactResponse::set_output(const Eigen::VectorXd& w) { w_modal_ = basis_->phi.transpose() * node_view(w); }

double ExactResponse::output(double t) const {
  Eigen::MatrixXd q;
  modal_coordinates(t, q);
  return (w_modal_.array() * q.array()).sum();
}

ModalReducedModel::ModalReducedModel(const ModalBasis& basis, const LinearModel& model, int modes, double step_s,
                                     bool static_correction, const Eigen::VectorXd& output_w)
    : basis_(&basis), profile_(model.profile), r_(modes), h_(step_s),
      c_(model.damping_Ns_per_m / model.node_mass_kg), sc_(static_correction) {
  const int n = basis.modes();
  if (modes < 1 || modes > n) throw std::invalid_argument("modal model: modes must be in [1, nodes]");
  if (!(step_s > 0)) throw std::invalid_argument("modal model: step_s must be > 0");
  const Eigen::MatrixXd gamma_all = model.load.size()
                                        ? Eigen::MatrixXd(basis.phi.transpose() * node_view(model.load))
                                        : Eigen::MatrixXd::Zero(n, 3);
  gamma_ = gamma_all.topRows(modes);
  w_ = basis.phi.leftCols(modes).transpose() * node_view(output_w);
  w2_ = basis.omega2.head(modes);
  inv_diag_.resize(modes);
  for (int k = 0; k < modes; ++k) inv_diag_[k] = 1.0 / (2.0 / h_ + c_ + 0.5 * h_ * w2_[k]);
  q_ = NodeMat::Zero(modes, 3);
  qd_ = NodeMat::Zero(modes, 3);
  sc_shape_ = NodeMat::Zero(n, 3);
  if (sc_) {
    for (int k = modes; k < n; ++k)
      if (basis.omega2[k] > 0) sc_shape_ += basis.phi.col(k) * (gamma_all.row(k) / basis.omega2[k]);
    sc_output_ = (node_view(output_w).array() * sc_shape_.array()).sum();
  }
}

void ModalReducedModel::step() {
  const double s = profile_.value(t_ + 0.5 * h_);
  for (int k = 0; k < r_; ++k) {
    for (int d = 0; d < 3; ++d) {
      // eq. (9) on mode k: (2/h + c + h/2 w2) qd_hat = 2/h qd - w2 q + gamma s(t + h/2)
      const double qh = inv_diag_[k] * (2.0 / h_ * qd_(k, d) - w2_[k] * q_(k, d) + gamma_(k, d) * s);
      qd_(k, d) = 2.0 * qh - qd_(k, d);
      q_(k, d) += h_ * qh;
    }
  }
  t_ += h_;
}

double ModalReducedModel::output() const {
  double y = 0;
  for (int k = 0; k < r_; ++k) y += w_(k, 0) * q_(k, 0) + w_(k, 1) * q_(k, 1) + w_(k, 2) * q_(k, 2);
  return sc_ ? y + sc_output_ * profile_.value(t_) : y;
}

void ModalReducedModel::displacement(Eigen::VectorXd& u) const {
  NodeMat U = basis_->phi.leftCols(r_) * q_;
  if (sc_) U += sc_shape_ * profile_.value(t_);
  u = Eigen::Map<const Eigen::VectorXd>(U.data(), U.size());
}

}  // namespace haptic::study
