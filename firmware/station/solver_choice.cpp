#include "firmware/station/solver_choice.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include "rt/tick_driver.hpp"

namespace haptic::firmware {

namespace {

// One tick of `core` with every neighbour sending the rest shape stretched by s(k) about its
// centroid (s small and smooth in k) and the device held at the proxy's start. Returns seconds.
double timed_tick(rt::StationCore& core, std::int64_t k, double T, const Eigen::VectorXd& xd, const Eigen::VectorXd& dir, const Eigen::Vector3d& device,
                  std::vector<double>& x, std::vector<double>& v) {
  const double w = 2.0 * M_PI / 50.0, s = 1e-3 * std::sin(w * static_cast<double>(k)), ds = 1e-3 * w * std::cos(w * static_cast<double>(k)) / T;
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] = xd[static_cast<long>(i)] + s * dir[static_cast<long>(i)];
    v[i] = ds * dir[static_cast<long>(i)];
  }
  const int dofs = static_cast<int>(x.size());
  const auto t0 = std::chrono::steady_clock::now();
  rt::drive_tick(core, rt::TickDrive{k, 0, device, core.config().period_s}, [&](auto&& offer) {
    for (int n = 0; n < core.neighbor_count(); ++n) offer(rt::ReceivedState{n, k, 0, x.data(), v.data(), dofs});
  });
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> a) {
  std::sort(a.begin(), a.end());
  return a.empty() ? 0.0 : a[a.size() / 2];
}

}  // namespace

SolverChoice measure_solver_choice(const rt::StationConfig& config, int ticks) {
  SolverChoice c;
  const rt::Scene& scene = *config.scene;
  bool iso = scene.M.is_isotropic() && scene.B.is_isotropic() && scene.K.is_isotropic();
  for (const auto& nb : config.neighbors) iso = iso && nb.gains->P.is_isotropic() && nb.gains->D.is_isotropic();
  const int rows = iso ? scene.nodes : scene.dofs;
  const int from = config.solver.iterative_from_rows;
  if (config.solver.kind != rt::StepSolverKind::kAuto) {
    c.kind = config.solver.kind;
    c.note = "solver forced";
    return c;
  }
  if (4L * rows < from || rows > 4L * from) {
    c.kind = rows >= from ? rt::StepSolverKind::kIterative : rt::StepSolverKind::kDirect;
    c.note = "fixed rule: " + std::to_string(rows) + " factor rows, outside the measured window [" + std::to_string(from / 4) + ", " +
             std::to_string(4 * from) + "]";
    if (c.kind == rt::StepSolverKind::kIterative) c.kind = rt::StepSolverKind::kAuto;  // kAuto falls back to direct if the cap is too high
    return c;
  }
  rt::StationConfig dc = config, ic = config;
  dc.solver.kind = rt::StepSolverKind::kDirect;
  ic.solver.kind = rt::StepSolverKind::kIterative;
  std::unique_ptr<rt::StationCore> direct = std::make_unique<rt::StationCore>(dc), iterative;
  try {
    iterative = std::make_unique<rt::StationCore>(ic);
  } catch (const std::invalid_argument& e) {
    c.kind = rt::StepSolverKind::kDirect;
    c.note = std::string("the iterative solver cannot be built: ") + e.what();
    return c;
  }
  Eigen::VectorXd dir(scene.dofs);
  const Eigen::Vector3d centroid = scene.mesh.centroid();
  for (int p = 0; p < scene.nodes; ++p) dir.segment<3>(3 * p) = scene.x_d.segment<3>(3 * p) - centroid;
  std::vector<double> x(static_cast<std::size_t>(scene.dofs)), v(x.size());
  std::vector<double> td, ti;
  for (int k = 0; k < ticks + 10; ++k) {
    const double a = timed_tick(*direct, k, config.period_s, scene.x_d, dir, config.vp_initial_position_m, x, v);
    const double b = timed_tick(*iterative, k, config.period_s, scene.x_d, dir, config.vp_initial_position_m, x, v);
    if (k >= 10) {
      td.push_back(a);
      ti.push_back(b);
    }
  }
  c.measured = true;
  c.timed_ticks = ticks;
  c.direct_tick_us = 1e6 * median(td);
  c.iterative_tick_us = 1e6 * median(ti);
  c.kind = c.iterative_tick_us < c.direct_tick_us ? rt::StepSolverKind::kIterative : rt::StepSolverKind::kDirect;
  c.note = "measured: median tick " + std::to_string(c.direct_tick_us) + " us direct, " + std::to_string(c.iterative_tick_us) + " us iterative";
  return c;
}

}  // namespace haptic::firmware
