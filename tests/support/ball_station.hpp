#pragma once
// One station of a four-user session on a ball of about `nodes` nodes (the paper's 33-node ball for 33, a
// lattice ball otherwise): three neighbours, the contact face towards (1, 1, 1), and a push 1 cm into that
// face. The station the solver tests share (tests/rt/step_solver_test.cpp,
// tests/firmware/station/solver_choice_test.cpp). cfg points into scene and gains: not copyable.
#include <Eigen/Core>

#include "rt/gains.hpp"
#include "rt/mesh.hpp"
#include "rt/scene.hpp"
#include "rt/station.hpp"

namespace haptic::test {

struct BallStation {
  rt::Scene scene;
  rt::EdgeGains gains;
  rt::StationConfig cfg;
  Eigen::Vector3d push;
  explicit BallStation(int nodes)
      : scene(rt::build_scene(nodes == 33 ? rt::make_paper_ball(0.05) : rt::make_lattice_ball(nodes, 0.05), rt::SceneParams{})),
        gains(rt::paper_edge_gains(scene)) {
    cfg.users = 4;
    cfg.scene = &scene;
    cfg.damping_Ns_per_m = 30.45;
    for (int p = 1; p <= 3; ++p) cfg.neighbors.push_back({p, &gains, 1 << 30});
    const int f = scene.mesh.face_towards(Eigen::Vector3d(1, 1, 1));
    const auto& face = scene.mesh.surface[static_cast<std::size_t>(f)];
    cfg.contact_nodes = {face[0], face[1], face[2]};
    cfg.vp_initial_position_m = scene.mesh.face_center(f);
    push = cfg.vp_initial_position_m - 0.01 * scene.mesh.face_normal(f);
  }
  BallStation(const BallStation&) = delete;
  BallStation& operator=(const BallStation&) = delete;
};

}  // namespace haptic::test
