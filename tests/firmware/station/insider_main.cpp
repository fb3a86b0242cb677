// haptic-insider: a TEST-ONLY build of haptic-station (never installed, never an option of the
// shipped station) whose `run` sends a lie: the state it reports has a lie added to x_hat (its
// velocities stay its copy's), from run time HAPTIC_INSIDER_FROM_S on (default 1 s):
//   HAPTIC_INSIDER_LIE = offset  a constant offset of HAPTIC_INSIDER_AMPLITUDE m along (1, 0.5, -0.3)
//                        mode    an oscillation of amplitude HAPTIC_INSIDER_AMPLITUDE m (largest node) at the
//                                object's lowest elastic mode, in its shape
//                        ramp    a translation growing at HAPTIC_INSIDER_AMPLITUDE m/s along (1, 0.5, -0.3)
//                        consistent  the same ramp, and the reported velocities say so (v_hat + the ramp's
//                                rate): a lie consistent with its velocities, which the kinematic check
//                                cannot see (rt/README.md "What bounds a consistent lie")
// Everything else is haptic-station's main, unchanged (the station file and keys of an honest one).
// Used by insider_check.sh (the neighbour state check, rt/edge_monitor.hpp).
#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "firmware/station/tick.hpp"

#define main haptic_station_main
#include "firmware/station_main.cpp"
#undef main

namespace {

enum class Lie { kNone, kOffset, kMode, kRamp, kConsistent };
Lie g_lie = Lie::kNone;
double g_amplitude = 0, g_from_s = 1.0;
std::vector<double> g_out, g_vout, g_shape;
double g_mode_hz = 0;

// The lowest elastic mode of the copy's object (shape scaled to 1 at its largest node). Start-up of
// the lie (the first rewritten tick); a test binary.
void lowest_mode(const haptic::rt::Scene& s) {
  const Eigen::MatrixXd K(s.K_int.as_full()), M(s.M.as_full());
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(K, M);
  for (int i = 0; i < es.eigenvalues().size(); ++i)
    if (es.eigenvalues()[i] > 1e-6 * es.eigenvalues().maxCoeff()) {
      const Eigen::VectorXd v = es.eigenvectors().col(i);
      double big = 0;
      for (int n = 0; n < s.nodes; ++n) big = std::max(big, v.segment<3>(3 * n).norm());
      g_shape.assign(v.data(), v.data() + v.size());
      for (double& x : g_shape) x /= big;
      g_mode_hz = std::sqrt(es.eigenvalues()[i]) / (2 * M_PI);
      std::fprintf(stderr, "haptic-insider: lowest elastic mode %.2f Hz\n", g_mode_hz);
      return;
    }
}

haptic::firmware::OutgoingState rewrite(const haptic::rt::StationCore& core, std::int64_t kr) {
  const double T = core.config().period_s;
  const double t = (static_cast<double>(kr) + 0.5) * T - g_from_s;
  if (t < 0) return {};
  const int dofs = core.config().scene->dofs;
  if (g_out.empty()) {
    g_out.assign(static_cast<std::size_t>(dofs), 0.0);
    g_vout.assign(static_cast<std::size_t>(dofs), 0.0);
    if (g_lie == Lie::kMode) lowest_mode(*core.config().scene);
  }
  const double e[3] = {0.8111071056538127, 0.40555355282690636, -0.2433321316961438};  // (1, 0.5, -0.3) normalized
  const double* x = core.x_hat();
  const double* v = core.v_hat();
  for (int i = 0; i < dofs; ++i) {
    double lie = 0;
    if (g_lie == Lie::kOffset) lie = g_amplitude * e[i % 3];
    if (g_lie == Lie::kRamp || g_lie == Lie::kConsistent) lie = g_amplitude * t * e[i % 3];
    if (g_lie == Lie::kMode) lie = g_amplitude * std::sin(2 * M_PI * g_mode_hz * t) * g_shape[static_cast<std::size_t>(i)];
    g_out[static_cast<std::size_t>(i)] = x[i] + lie;
    g_vout[static_cast<std::size_t>(i)] = v[i] + (g_lie == Lie::kConsistent ? g_amplitude * e[i % 3] : 0.0);
  }
  return {g_out.data(), g_lie == Lie::kConsistent ? g_vout.data() : nullptr};
}

}  // namespace

int main(int argc, char** argv) {
  const char* lie = std::getenv("HAPTIC_INSIDER_LIE");
  const char* amp = std::getenv("HAPTIC_INSIDER_AMPLITUDE");
  const char* from = std::getenv("HAPTIC_INSIDER_FROM_S");
  if (lie && std::strcmp(lie, "offset") == 0) g_lie = Lie::kOffset;
  else if (lie && std::strcmp(lie, "mode") == 0) g_lie = Lie::kMode;
  else if (lie && std::strcmp(lie, "ramp") == 0) g_lie = Lie::kRamp;
  else if (lie && std::strcmp(lie, "consistent") == 0) g_lie = Lie::kConsistent;
  else if (lie) {
    std::fprintf(stderr, "haptic-insider: HAPTIC_INSIDER_LIE must be offset, mode, ramp or consistent, not '%s'\n", lie);
    return 2;
  }
  if (amp) g_amplitude = std::atof(amp);
  if (from) g_from_s = std::atof(from);
  if (g_lie != Lie::kNone) {
    std::fprintf(stderr, "haptic-insider: lying (%s, %g) from run time %g s\n", lie, g_amplitude, g_from_s);
    haptic::firmware::set_outgoing_state_rewrite(&rewrite);
  }
  return haptic_station_main(argc, argv);
}
