#pragma once
// Simulated user: a passive haptic device (mass m_d, damping b_d) held by a hand modeled as a
// spring-damper towards a scripted goal. Continuous-time plant, integrated with sub-steps
// while the commanded device force is held (zero-order hold over one tick).
// Pure computation, no allocation after construction: RT-safe.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>

namespace haptic::rt {

using Vec3 = Eigen::Vector3d;

struct DeviceModelParams {
  double mass_kg = 0.05;            // apparent device mass (Phantom Omni class)
  double damping_Ns_per_m = 0.5;    // b_d: the device's own (minimum) damping, eq. (26)
};

struct HandParams {
  double stiffness_N_per_m = 300.0; // hand grip stiffness towards the goal
  double damping_Ns_per_m = 5.0;    // hand damping (passive)
};

// Goal of the hand as keyframes (time, position); cosine-smoothed between keyframes,
// held after the last one. Fixed capacity: no allocation.
class GoalScript {
 public:
  static constexpr std::size_t kMaxKeys = 16;
  GoalScript() = default;
  explicit GoalScript(const Vec3& hold_at) { add(0.0, hold_at); }
  // Keys must be added in increasing time; throws std::invalid_argument otherwise or when full.
  void add(double time_s, const Vec3& goal_m);
  Vec3 goal_at(double time_s) const;  // RT-safe
  std::size_t size() const { return count_; }

 private:
  std::array<double, kMaxKeys> t_{};
  std::array<Vec3, kMaxKeys> g_{};
  std::size_t count_ = 0;
};

class SimulatedUser {
 public:
  SimulatedUser() = default;
  SimulatedUser(const DeviceModelParams& device, const HandParams& hand, const GoalScript& script,
                int substeps_per_tick = 20);
  void reset(const Vec3& position_m);
  // Advances device + hand over [t_s, t_s + dt_s) with the commanded device force held. RT-safe.
  void advance(double t_s, double dt_s, const Vec3& commanded_force_N);
  const Vec3& position_m() const { return q_; }
  const Vec3& velocity_m_per_s() const { return qd_; }
  Vec3 goal_m(double t_s) const { return script_.goal_at(t_s); }
  // Force the hand applied on the device during the last advance (mean), for telemetry.
  const Vec3& hand_force_N() const { return hand_force_; }
  const DeviceModelParams& device() const { return device_; }

 private:
  DeviceModelParams device_{};
  HandParams hand_{};
  GoalScript script_{};
  int substeps_ = 20;
  Vec3 q_ = Vec3::Zero();
  Vec3 qd_ = Vec3::Zero();
  Vec3 hand_force_ = Vec3::Zero();
};

}  // namespace haptic::rt
