// The device-VP virtual coupling (Section III-C) is passive, eq. (25), at every gain set eq. (26)
// accepts, under any hand motion. Per hold interval, with a = q_{k+1} - q_k (the hand, linear within
// the interval), b = y_{k+1} - y_k (the VP, implicit midpoint) and S = K_vc |q - y|^2 / 2, the energy
// the coupling and the device's damping b_d put into the hand and the VP is
//   -dS + (K_vc/2 - b_d/T) |a|^2 - K_vc a.b - (b_v/T) |b|^2      (B_vc = 0),
// a form that is negative semidefinite exactly when (b_d/T - K_vc/2)(b_v/T) >= K_vc^2/4, which
// eq. (26) (b_d >= K_vc T, b_v >= K_vc T/2) meets with equality when both bounds are tight. So at
// the largest K_vc eq. (26) accepts the left side of (25) plus the VP's kinetic energy change never
// exceeds zero, while at twice that K_vc a hand that moves against the VP's last step (a = -gamma b)
// draws energy out. The hand here is prescribed: sinusoids of 2 to 20 ticks and that adversary.
#include <CppUTest/TestHarness.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "rt/gains.hpp"
#include "rt/station.hpp"
#include "tests/rt/fixtures.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

namespace {

constexpr double kT = 0.002;

// Left side of (25) plus the VP's kinetic energy change (c^2 = 0: VP at the device, at rest),
// maximised over the run, and the device damping's dissipation b_d sum |dq|^2 / T.
struct CouplingRun {
  double worst_J = 0;
  double dissipated_J = 0;
};

// gamma = 0: q = q0 + A sin(2 pi k / period) e; gamma > 0: the adversary q_{k+1} = q_k - gamma (y_{k+1}
// - y_k) plus a small sinusoid (period `period`) that starts it, kept within 5 mm of q0.
CouplingRun drive_coupling(const VirtualCouplingGains& g, double b_d, bool checked, double period, double gamma) {
  const auto& w = PaperWorld::get();
  StationConfig c = w.station(0, 1, {}, 0.0, test::tetra_dirs()[0]);
  const Eigen::Vector3d q0(5, 5, 5), e = Eigen::Vector3d(1, 0.3, -0.2).normalized();
  c.vp_initial_position_m = q0;  // at the device, far from the object: no contact
  c.vp.coupling = g;
  c.device_damping_Ns_per_m = b_d;
  c.device_force_feedback = checked;  // false: the core does not check eq. (26) (the "can fail" runs)
  c.max_device_force_N = 1e9;
  StationCore st(c);
  const double m = c.vp.mass_kg;
  CouplingRun r;
  Eigen::Vector3d q = q0, q_prev = q0, y_prev = st.vp_position_m(), wv = Eigen::Vector3d::Zero();
  for (int k = 0; k < 600; ++k) {
    r.dissipated_J += b_d * (q - q_prev).squaredNorm() / kT;  // the hold interval [k-1, k]
    st.tick(k, q, kT);
    const Eigen::Vector3d y = st.vp_position_m();
    wv = 2 * (y - y_prev) / kT - wv;  // w(k+1) = 2 w_hat - w(k)
    // device_port_J: sum F(k'-1) . (q_k' - q_k'-1) up to this tick: (25)'s device integral without b_d
    r.worst_J = std::max(r.worst_J, st.energy().device_port_J - r.dissipated_J + 0.5 * m * wv.squaredNorm());
    q_prev = q;
    const double s = std::sin(2 * M_PI * (k + 1) / period);
    if (gamma == 0) {
      q = q0 + 1e-3 * s * e;
    } else {
      q = q - gamma * (y - y_prev) + 1e-5 * s * e;
      if ((q - q0).norm() > 5e-3) q = q0 + 5e-3 * (q - q0).normalized();
    }
    y_prev = y;
  }
  return r;
}

// Worst of the run's generated energy over its dissipation, over every hand motion.
double worst_over_hands(const VirtualCouplingGains& g, double b_d, bool checked) {
  double worst = -1;
  for (double period : {2.0, 2.5, 3.0, 4.0, 6.0, 10.0, 20.0})
    for (double gamma : {0.0, 0.5, 1.0, 2.0, 4.0}) {
      const CouplingRun r = drive_coupling(g, b_d, checked, period, gamma);
      worst = std::max(worst, r.worst_J / std::max(r.dissipated_J, 1e-300));
    }
  return worst;
}

// The largest K_vc that rt::check_eq26 accepts with the other gains as given (bisection on the
// production check itself, not on a formula).
double largest_accepted_K_vc(VirtualCouplingGains g, double b_d) {
  auto accepted = [&](double K) {
    g.K_vc_N_per_m = K;
    try {
      check_eq26(g, b_d, kT);
      return true;
    } catch (const std::invalid_argument&) {
      return false;
    }
  };
  double lo = 1e-3, hi = 1e7;
  CHECK_TRUE(accepted(lo));
  CHECK_FALSE(accepted(hi));
  for (int i = 0; i < 100; ++i) {
    const double mid = std::sqrt(lo * hi);
    (accepted(mid) ? lo : hi) = mid;
  }
  return lo;
}

// b_d = 0.5 N s/m (the default device) with b_v = 0.1 (eq. 26's b_v bound binds), b_v = b_d / 2 (both
// bounds tight together) and the paper's b_v = 2 (its b_d bound binds).
const double kBv[] = {0.1, 0.25, 2.0};

}  // namespace

TEST_GROUP(VirtualCoupling){};

TEST(VirtualCoupling, passive_eq25_at_the_largest_gains_eq26_accepts_under_adversarial_hand_motion) {
  for (double b_v : kBv) {
    VirtualCouplingGains g;
    g.b_v_Ns_per_m = b_v;
    g.K_vc_N_per_m = largest_accepted_K_vc(g, 0.5);
    CHECK_TRUE(g.K_vc_N_per_m > 50);  // eq. (26) accepts a usable coupling (100 or 250 N/m here)
    const double worst = worst_over_hands(g, 0.5, true);
    CHECK_TEXT(worst <= 1e-9, ("b_v " + std::to_string(b_v) + ", K_vc " + std::to_string(g.K_vc_N_per_m) + ": generated " +
                               std::to_string(worst) + " of the dissipation").c_str());
  }
}

TEST(VirtualCoupling, at_twice_the_K_vc_eq26_accepts_the_same_hands_draw_energy_so_the_test_can_fail) {
  // measured: 0.17, 1.72 and 0.25 of the device damping's dissipation for b_v = 0.1, 0.25 and 2
  // (K_vc = 200, 500, 500 N/m; eq. 26 accepts 100, 250, 250)
  for (double b_v : kBv) {
    VirtualCouplingGains g;
    g.b_v_Ns_per_m = b_v;
    g.K_vc_N_per_m = 2 * largest_accepted_K_vc(g, 0.5);
    const double worst = worst_over_hands(g, 0.5, false);
    CHECK_TEXT(worst > 0.05, ("b_v " + std::to_string(b_v) + ": generated " + std::to_string(worst) + " of the dissipation").c_str());
  }
}
