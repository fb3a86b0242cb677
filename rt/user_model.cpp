#include "rt/user_model.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace haptic::rt {

void GoalScript::add(double time_s, const Vec3& goal_m) {
  if (count_ >= kMaxKeys) throw std::invalid_argument("GoalScript: more than 16 keyframes");
  if (count_ > 0 && !(time_s > t_[count_ - 1]))
    throw std::invalid_argument("GoalScript: keyframe times must increase");
  if (!std::isfinite(time_s) || !goal_m.allFinite())
    throw std::invalid_argument("GoalScript: keyframe is not finite");
  t_[count_] = time_s;
  g_[count_] = goal_m;
  ++count_;
}

Vec3 GoalScript::goal_at(double time_s) const {
  if (count_ == 0) return Vec3::Zero();
  if (time_s <= t_[0]) return g_[0];
  for (std::size_t i = 1; i < count_; ++i) {
    if (time_s < t_[i]) {
      const double s = (time_s - t_[i - 1]) / (t_[i] - t_[i - 1]);
      const double w = 0.5 - 0.5 * std::cos(std::numbers::pi * s);  // smooth start and stop
      return (1.0 - w) * g_[i - 1] + w * g_[i];
    }
  }
  return g_[count_ - 1];
}

SimulatedUser::SimulatedUser(const DeviceModelParams& device, const HandParams& hand,
                             const GoalScript& script, int substeps_per_tick)
    : device_(device), hand_(hand), script_(script), substeps_(substeps_per_tick) {
  if (!(device.mass_kg > 0.0)) throw std::invalid_argument("device.mass_kg must be > 0");
  if (!(device.damping_Ns_per_m >= 0.0))
    throw std::invalid_argument("device.damping_Ns_per_m must be >= 0");
  if (!(hand.stiffness_N_per_m >= 0.0) || !(hand.damping_Ns_per_m >= 0.0))
    throw std::invalid_argument("hand stiffness and damping must be >= 0");
  if (substeps_per_tick < 1) throw std::invalid_argument("substeps_per_tick must be >= 1");
}

void SimulatedUser::reset(const Vec3& position_m) {
  q_ = position_m;
  qd_.setZero();
  hand_force_.setZero();
}

void SimulatedUser::advance(double t_s, double dt_s, const Vec3& commanded_force_N) {
  // m q'' = F_cmd - b_d q' + K_h (g - q) - B_h q'; semi-implicit (symplectic) Euler with the
  // damping taken implicitly, which is unconditionally stable for the damping part.
  const double h = dt_s / substeps_;
  const double b = device_.damping_Ns_per_m + hand_.damping_Ns_per_m;
  Vec3 hand_sum = Vec3::Zero();
  for (int s = 0; s < substeps_; ++s) {
    const Vec3 g = script_.goal_at(t_s + (s + 0.5) * h);
    const Vec3 f_hand = hand_.stiffness_N_per_m * (g - q_) - hand_.damping_Ns_per_m * qd_;
    hand_sum += f_hand;
    const Vec3 f_spring = commanded_force_N + hand_.stiffness_N_per_m * (g - q_);
    qd_ = (device_.mass_kg * qd_ + h * f_spring) / (device_.mass_kg + h * b);
    q_ += h * qd_;
  }
  hand_force_ = hand_sum / substeps_;
}

}  // namespace haptic::rt
