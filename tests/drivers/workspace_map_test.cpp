// The device -> object transform (drivers/workspace_map): positions, forces back with the same
// power, the workspace clamp, and the offset the guided set-up solves for.
#include "drivers/workspace_map.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
WorkspaceMapConfig some_map() {
  WorkspaceMapConfig c;
  c.offset_m[0] = 0.01;
  c.offset_m[1] = -0.02;
  c.offset_m[2] = 0.15;
  c.rotation_deg[0] = 90;
  c.rotation_deg[1] = 10;
  c.rotation_deg[2] = -30;
  c.scale = 0.5;
  c.workspace_radius_m = 0.11;
  return c;
}
}  // namespace

TEST_GROUP(WorkspaceMap){};

TEST(WorkspaceMap, ForcesGoBackWithTheSamePowerAsInTheObjectFrame) {
  const WorkspaceMap m(some_map());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d v_dev(u(rng), u(rng), u(rng)), f_obj(u(rng), u(rng), u(rng));
    // a velocity maps like a position difference: v_obj = scale R v_dev
    const double zero[3] = {0, 0, 0}, p[3] = {v_dev.x() * 1e-3, v_dev.y() * 1e-3, v_dev.z() * 1e-3};
    const Eigen::Vector3d v_obj = (m.to_object(p, nullptr) - m.to_object(zero, nullptr)) / 1e-3;
    double f_dev[3];
    m.force_to_device(f_obj, f_dev);
    const double p_dev = f_dev[0] * v_dev.x() + f_dev[1] * v_dev.y() + f_dev[2] * v_dev.z();
    DOUBLES_EQUAL(f_obj.dot(v_obj), p_dev, 1e-9);
  }
}

TEST(WorkspaceMap, ToDeviceInvertsToObjectAndRotationIsAboutFixedXThenYThenZ) {
  const WorkspaceMap m(some_map());
  const double p[3] = {0.03, -0.04, 0.05};
  bool clamped = true;
  const Eigen::Vector3d o = m.to_object(p, &clamped);
  CHECK_FALSE(clamped);
  const Eigen::Vector3d back = m.to_device(o);
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(p[i], back[i], 1e-12);
  WorkspaceMapConfig rz;
  rz.rotation_deg[2] = 90;  // device +x -> object +y
  const double x[3] = {0.01, 0, 0};
  const Eigen::Vector3d y = WorkspaceMap(rz).to_object(x, nullptr);
  DOUBLES_EQUAL(0.0, y.x(), 1e-12);
  DOUBLES_EQUAL(0.01, y.y(), 1e-12);
}

TEST(WorkspaceMap, APositionBeyondTheWorkspaceIsClampedOntoItAndFlagged) {
  WorkspaceMapConfig c;
  c.workspace_radius_m = 0.1;
  const WorkspaceMap m(c);
  const double far[3] = {0.3, 0.4, 0.0};  // |p| = 0.5 m
  bool clamped = false;
  const Eigen::Vector3d o = m.to_object(far, &clamped);
  CHECK(clamped);
  DOUBLES_EQUAL(0.1, o.norm(), 1e-12);
  DOUBLES_EQUAL(0.06, o.x(), 1e-12);
}

TEST(WorkspaceMap, SolvedOffsetMapsTheHeldPointOntoTheObjectPoint) {
  WorkspaceMapConfig c = some_map();
  const double held[3] = {0.012, -0.034, 0.056};
  const Eigen::Vector3d centre(0.0, 0.0, 0.0);
  solve_offset(c, held, centre);
  const Eigen::Vector3d o = WorkspaceMap(c).to_object(held, nullptr);
  CHECK(o.norm() < 1e-12);
}

TEST(WorkspaceMap, ABadScaleIsRefusedNamingTheKey) {
  WorkspaceMapConfig c;
  c.scale = 0;
  try {
    WorkspaceMap m(c);
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("device.map_scale") != std::string::npos);
  }
}
