#pragma once
// Dense reference for one station step: assembles the whole coupled VO + VP system of eqs. (9),
// (15), (21), (22) and the virtual coupling as one dense (3n+3) x (3n+3) matrix every tick and
// solves it with a dense LDL^T. It exists to check StationCore's precomputed sparse factorization
// and Schur complement (tests) and as the baseline the benchmark compares against. It follows
// the same contact switching rule. Not RT-safe: O(n^3) work and temporaries every tick.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "rt/station.hpp"

namespace haptic::test {

class DenseStationReference {
 public:
  explicit DenseStationReference(const rt::StationConfig& config);
  rt::RxLink& rx(int n) { return rx_[static_cast<std::size_t>(n)]; }
  rt::Vec3 tick(const rt::Vec3& device_position_m);  // returns the device force
  const Eigen::VectorXd& x() const { return x_; }
  const Eigen::VectorXd& v() const { return v_; }
  const rt::Vec3& vp_position_m() const { return y_; }
  bool in_contact() const { return in_contact_; }
  void set_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
    x_ = x;
    v_ = v;
  }

 private:
  rt::StationConfig cfg_;
  double T_;
  int dofs_;
  Eigen::MatrixXd Mfull_, Bfull_, Kfull_;
  std::vector<Eigen::MatrixXd> Pfull_, Dfull_;
  std::vector<rt::RxLink> rx_;
  Eigen::VectorXd x_, v_, xd_;
  rt::Vec3 y_, w_ = rt::Vec3::Zero(), w_hat_prev_ = rt::Vec3::Zero(), q_prev_, f_vp_ = rt::Vec3::Zero();
  std::vector<rt::Vec3> anchor_;
  bool in_contact_ = false;
  double normal_sign_ = 1;
  std::int64_t k_ = 0;
  Eigen::MatrixXd A_;
  Eigen::VectorXd b_, sol_;
  Eigen::LDLT<Eigen::MatrixXd> ldlt_;
};

}  // namespace haptic::test
