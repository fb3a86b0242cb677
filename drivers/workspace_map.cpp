#include "drivers/workspace_map.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

namespace haptic::drivers {

namespace {
Eigen::Matrix3d rotation_xyz_deg(const double deg[3]) {
  constexpr double kRad = 3.14159265358979323846 / 180.0;
  return (Eigen::AngleAxisd(deg[2] * kRad, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(deg[1] * kRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(deg[0] * kRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}
}  // namespace

WorkspaceMap::WorkspaceMap(const WorkspaceMapConfig& c)
    : R_(rotation_xyz_deg(c.rotation_deg)), offset_(c.offset_m[0], c.offset_m[1], c.offset_m[2]), scale_(c.scale), radius_m_(c.workspace_radius_m) {
  if (!(c.scale > 0.0 && c.scale <= 100.0)) throw std::invalid_argument("device.map_scale must be in (0, 100]");
  if (!offset_.allFinite() || !R_.allFinite()) throw std::invalid_argument("device.map_offset_m / map_rotation_deg must be finite");
}

Eigen::Vector3d WorkspaceMap::to_object(const double p[3], bool* clamped) const {
  Eigen::Vector3d d(p[0], p[1], p[2]);
  const double r = d.norm();
  const bool out = radius_m_ > 0.0 && r > radius_m_;
  if (out) d *= radius_m_ / r;
  if (clamped != nullptr) *clamped = out;
  return offset_ + scale_ * (R_ * d);
}

void WorkspaceMap::force_to_device(const Eigen::Vector3d& f, double out[3]) const {
  const Eigen::Vector3d d = scale_ * (R_.transpose() * f);
  for (int i = 0; i < 3; ++i) out[i] = d[i];
}

Eigen::Vector3d WorkspaceMap::to_device(const Eigen::Vector3d& o) const { return R_.transpose() * (o - offset_) / scale_; }

void solve_offset(WorkspaceMapConfig& c, const double device_point_m[3], const Eigen::Vector3d& object_point_m) {
  WorkspaceMapConfig no_offset = c;
  for (double& o : no_offset.offset_m) o = 0.0;
  no_offset.workspace_radius_m = 0.0;
  const Eigen::Vector3d mapped = WorkspaceMap(no_offset).to_object(device_point_m, nullptr);
  for (int i = 0; i < 3; ++i) c.offset_m[i] = object_point_m[i] - mapped[i];
}

}  // namespace haptic::drivers
