#pragma once
// Shared scene and station configurations for the rt tests.
#include <Eigen/Core>
#include <memory>
#include <random>
#include <vector>

#include "rt/gains.hpp"
#include "rt/scene.hpp"
#include "rt/station.hpp"

namespace haptic::test {

struct PaperWorld {
  rt::Scene scene;
  rt::EdgeGains gains;
  PaperWorld() : scene(rt::build_scene(rt::make_paper_ball(0.05), rt::SceneParams{})), gains(rt::paper_edge_gains(scene)) {}
  static const PaperWorld& get() {
    static const PaperWorld w;
    return w;
  }
  // The contact mesh of a user: the boundary face towards `dir`.
  std::vector<int> face_nodes(const Eigen::Vector3d& dir) const {
    const auto& f = scene.mesh.surface[static_cast<std::size_t>(scene.mesh.face_towards(dir))];
    return {f[0], f[1], f[2]};
  }
  Eigen::Vector3d face_center(const Eigen::Vector3d& dir) const { return scene.mesh.face_center(scene.mesh.face_towards(dir)); }
  Eigen::Vector3d face_inward(const Eigen::Vector3d& dir) const { return -scene.mesh.face_normal(scene.mesh.face_towards(dir)); }

  rt::StationConfig station(int id, int users, const std::vector<int>& peers, double damping, const Eigen::Vector3d& dir,
                            std::int64_t bound = 1 << 30) const {
    rt::StationConfig c;
    c.station_id = id;
    c.users = users;
    c.scene = &scene;
    c.damping_Ns_per_m = damping;
    for (int p : peers) c.neighbors.push_back({p, &gains, bound});
    c.contact_nodes = face_nodes(dir);
    c.vp_initial_position_m = face_center(dir);
    return c;
  }
};

inline const std::vector<Eigen::Vector3d>& tetra_dirs() {
  static const std::vector<Eigen::Vector3d> d = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  return d;
}

}  // namespace haptic::test
