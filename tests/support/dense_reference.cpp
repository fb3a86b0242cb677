#include "tests/support/dense_reference.hpp"

namespace haptic::test {

using namespace haptic::rt;  // the oracle is written in the core's own terms

DenseStationReference::DenseStationReference(const StationConfig& c) : cfg_(c), T_(c.period_s) {
  c.validate();
  const Scene& s = *c.scene;
  dofs_ = s.dofs;
  Mfull_ = Eigen::MatrixXd(s.M.as_full());
  Bfull_ = Eigen::MatrixXd(s.B.as_full());
  Kfull_ = Eigen::MatrixXd(s.K.as_full());
  for (const auto& nb : c.neighbors) {
    Pfull_.emplace_back(Eigen::MatrixXd(nb.gains->P.as_full()));
    Dfull_.emplace_back(Eigen::MatrixXd(nb.gains->D.as_full()));
  }
  xd_ = s.x_d;
  x_ = xd_;
  v_ = Eigen::VectorXd::Zero(dofs_);
  rx_.resize(c.neighbors.size());
  for (auto& r : rx_) r.init(dofs_, x_.data(), v_.data());
  y_ = c.vp_initial_position_m;
  q_prev_ = y_;
  anchor_.assign(c.contact_nodes.size(), Vec3::Zero());
  A_.resize(dofs_ + 3, dofs_ + 3);
  b_.resize(dofs_ + 3);
  sol_.resize(dofs_ + 3);
  ldlt_ = Eigen::LDLT<Eigen::MatrixXd>(dofs_ + 3);
  const ContactFace rest = contact_face(x_, c.contact_nodes);
  normal_sign_ = rest.normal.dot(rest.centroid - s.mesh.centroid()) >= 0 ? 1.0 : -1.0;
}

Vec3 DenseStationReference::tick(const Vec3& q) {
  const double N = cfg_.users, T = T_;
  const auto& g = cfg_.vp.coupling;
  const double kc = cfg_.vp.contact_stiffness_N_per_m, bc = cfg_.vp.contact_damping_Ns_per_m, c = bc + kc * T / 2;
  const auto& cn = cfg_.contact_nodes;
  const Vec3 vq = k_ == 0 ? Vec3::Zero() : Vec3((q - q_prev_) / T);
  Vec3 f_dev = -g.B_vc_Ns_per_m * (vq - w_hat_prev_) - g.K_vc_N_per_m * (q - y_);
  if (f_dev.norm() > cfg_.max_device_force_N) f_dev *= cfg_.max_device_force_N / f_dev.norm();
  // contact switching (same rule as StationCore)
  const ContactFace face = contact_face(x_, cn);
  const Vec3& xc = face.centroid;
  Vec3 nrm = normal_sign_ * face.normal;
  if (nrm.norm() > 0) nrm.normalize();
  if (in_contact_) {
    if (f_vp_.dot(nrm) < 0) in_contact_ = false;
  } else if (nrm.dot(y_ - xc) <= 0) {
    for (std::size_t a = 0; a < cn.size(); ++a) anchor_[a] = x_.segment<3>(3 * cn[a]) - y_;
    in_contact_ = true;
  }
  // assemble
  A_.setZero();
  b_.setZero();
  auto Avv = A_.topLeftCorner(dofs_, dofs_);
  Avv = (2.0 / (N * T)) * Mfull_ + Bfull_ / N + (T / (2 * N)) * Kfull_;
  Avv.diagonal().array() += cfg_.damping_Ns_per_m;
  auto bv = b_.head(dofs_);
  bv = (2.0 / (N * T)) * (Mfull_ * v_) - (Kfull_ * (x_ - xd_)) / N;
  for (std::size_t j = 0; j < rx_.size(); ++j) {
    const auto view = rx_[j].begin_tick(k_);
    Avv += Dfull_[j] + (T / 2) * Pfull_[j];
    // over the bound: x_hat_j := x(k), delta_ij = 0 -> nothing in b (the edge is a damper)
    if (view.index_delay > cfg_.neighbors[j].index_delay_bound_ticks) continue;
    const Eigen::Map<const Eigen::VectorXd> xj(view.x_hat, dofs_), vj(view.v_hat, dofs_);
    if (view.fresh) bv += Dfull_[j] * vj;
    bv -= Pfull_[j] * (x_ - xj);
  }
  const double aw = 2 * cfg_.vp.mass_kg / T + g.b_v_Ns_per_m + g.B_vc_Ns_per_m + g.K_vc_N_per_m * T / 2;
  A_.bottomRightCorner(3, 3) = aw * Eigen::Matrix3d::Identity();
  Vec3 bw = (2 * cfg_.vp.mass_kg / T) * w_ + g.B_vc_Ns_per_m * vq - g.K_vc_N_per_m * (y_ - q);
  if (in_contact_) {
    for (std::size_t a = 0; a < cn.size(); ++a) {
      const int r = 3 * cn[a];
      for (int d = 0; d < 3; ++d) {
        A_(r + d, r + d) += c;
        A_(r + d, dofs_ + d) -= c;
        A_(dofs_ + d, r + d) -= c;
        A_(dofs_ + d, dofs_ + d) += c;
      }
      const Vec3 s = kc * (y_ + anchor_[a] - x_.segment<3>(r));
      b_.segment<3>(r) += s;
      bw -= s;
    }
  }
  b_.tail<3>() = bw;
  ldlt_.compute(A_);
  sol_ = ldlt_.solve(b_);
  const Eigen::VectorXd vhat = sol_.head(dofs_);
  const Vec3 what = sol_.tail<3>();
  f_vp_.setZero();
  if (in_contact_) {
    const Vec3 yhat = y_ + T / 2 * what;
    for (std::size_t a = 0; a < cn.size(); ++a) {
      const int r = 3 * cn[a];
      const Vec3 xh = x_.segment<3>(r) + T / 2 * vhat.segment<3>(r);
      f_vp_ -= kc * (yhat + anchor_[a] - xh) + bc * (what - vhat.segment<3>(r));
    }
  }
  x_ += T * vhat;
  v_ = 2 * vhat - v_;
  y_ += T * what;
  w_ = 2 * what - w_;
  w_hat_prev_ = what;
  q_prev_ = q;
  ++k_;
  return f_dev;
}

}  // namespace haptic::test
