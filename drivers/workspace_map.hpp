#pragma once
// The transform from a device's coordinates to the shared object's frame:
//   p_object = offset + scale R p_device,    F_device = scale R^T F_object,
// so the power the station exchanges with the hand is the same in both frames (F_d . v_d =
// F_o . v_o): a coupling of stiffness K_vc and damping B_vc in the object frame is one of
// scale^2 K_vc and scale^2 B_vc at the device, which is why eq. (26) is checked with the device's
// b_d expressed in the object frame, b_d / scale^2 (object_frame_damping), and the force limit
// becomes F_max / scale (object_frame_force_limit).
// R = Rz(rz) Ry(ry) Rx(rx): rotations about the object's fixed x, then y, then z axis.
// Positions beyond the device's workspace radius (device frame, around its origin) are clamped
// radially onto it before the transform and counted: the station never maps a point the device
// cannot reach into the scene. The transform itself is RT-safe (no allocation, no branches on I/O).
#include <Eigen/Core>
#include <cstdint>

namespace haptic::drivers {

// The device's figures in the object frame of a map with this scale (the station's eq. (26) check and
// force limit use these; the one implementation). RT-safe.
inline double object_frame_damping(double device_damping_Ns_per_m, double scale) { return device_damping_Ns_per_m / (scale * scale); }
inline double object_frame_force_limit(double device_force_limit_N, double scale) { return device_force_limit_N / scale; }

struct WorkspaceMapConfig {
  double offset_m[3] = {0.0, 0.0, 0.0};        // object-frame position of the device origin
  double rotation_deg[3] = {0.0, 0.0, 0.0};    // rx, ry, rz
  double scale = 1.0;                           // object metres per device metre, (0, 100]
  double workspace_radius_m = 0.0;              // clamp radius in the device frame; <= 0: none
};

class WorkspaceMap {
 public:
  WorkspaceMap() = default;
  explicit WorkspaceMap(const WorkspaceMapConfig& config);  // throws std::invalid_argument on a bad scale

  // RT-safe. Device position -> object frame; *clamped = true when it was beyond the workspace.
  Eigen::Vector3d to_object(const double device_position_m[3], bool* clamped) const;
  // RT-safe. Object-frame force -> device-frame force (scale R^T F).
  void force_to_device(const Eigen::Vector3d& force_object_N, double device_force_N[3]) const;
  // Non-RT: the inverse, object frame -> device frame (the guided set-up prints it).
  Eigen::Vector3d to_device(const Eigen::Vector3d& object_position_m) const;

  double scale() const { return scale_; }
  const Eigen::Matrix3d& rotation() const { return R_; }
  const Eigen::Vector3d& offset() const { return offset_; }

 private:
  Eigen::Matrix3d R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();
  double scale_ = 1.0;
  double radius_m_ = 0.0;
};

// The offset that maps the device point `device_point_m` onto the object point `object_point_m`
// with the rotation and scale of `config` (the guided set-up: stylus held at the object's centre).
// Non-RT.
void solve_offset(WorkspaceMapConfig& config, const double device_point_m[3], const Eigen::Vector3d& object_point_m);

}  // namespace haptic::drivers
