#include "drivers/falcon_protocol.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace haptic::drivers::falcon {

namespace {
constexpr unsigned char kOffset = 0x41;  // 'A'

// Geometry (FalconGeometry.h, metres; R. E. Stamper's notation): leg base to knee a, shin
// parallelogram b, end-effector offsets c (u) and f (v), joint lengths d = e, leg base at (r, s)
// in each leg's (u, v) frame, legs at angles phi (15 degrees off the desk plane).
constexpr double kA = 0.060, kB = 0.1025, kC = 0.014, kD = 0.01125, kE = 0.01125, kF = -0.025;
constexpr double kR = 0.037233758, kS = -0.027330909;
constexpr double kPi = 3.14159265358979323846;
constexpr double kPhi[3] = {kPi / 2 + kPi / 12, -kPi / 6 + kPi / 12, -5 * kPi / 6 + kPi / 12};

// Encoder: 320 slots in quadrature (1280 counts per motor turn), 14.25 mm shaft, 110 mm arm, 35 degrees at 0.
constexpr double kSlots = 320.0, kShaftM = 0.01425, kArmM = 0.110, kThetaAtZeroDeg = 35.0;

// theta1 of one leg for the end-effector position p; false when unreachable.
bool leg_theta(const Eigen::Vector3d& p, double phi, double& theta1) {
  const double cu = std::cos(phi), su = std::sin(phi);
  const double u = cu * p.x() + su * p.y() - kR;   // position in the leg's frame, minus its base
  const double v = -su * p.x() + cu * p.y() - kS;
  const double w = p.z();
  const double cos3 = (v + kF) / kB;
  if (!(std::abs(cos3) <= 1.0)) return false;
  const double k = kD + kE + kB * std::sqrt(1.0 - cos3 * cos3);  // d + e + b sin(theta3), theta3 in [0, pi]
  // (u + c - a cos t1)^2 + (w - a sin t1)^2 = k^2, with t = tan(t1 / 2): l2 t^2 + l1 t + l0 = 0
  const double l0 = w * w + (u + kC - kA) * (u + kC - kA) - k * k;
  const double l1 = -4.0 * kA * w;
  const double l2 = w * w + (u + kC + kA) * (u + kC + kA) - k * k;
  const double disc = l1 * l1 - 4.0 * l0 * l2;
  if (!(disc >= 0.0) || l2 == 0.0) return false;
  theta1 = 2.0 * std::atan((-l1 - std::sqrt(disc)) / (2.0 * l2));  // the Falcon's branch (knee out)
  return std::isfinite(theta1);
}

unsigned char nibble(unsigned char byte) { return static_cast<unsigned char>(byte - kOffset); }
}  // namespace

void encode_command(const std::int16_t motor[3], std::uint8_t control, unsigned char out[kPacketSize]) {
  out[0] = '<';
  for (int m = 0; m < 3; ++m) {
    const auto bits = static_cast<std::uint16_t>(motor[m]);
    for (int n = 0; n < 4; ++n) out[1 + 4 * m + n] = static_cast<unsigned char>(((bits >> (4 * n)) & 0xF) + kOffset);
  }
  out[13] = static_cast<unsigned char>((control & 0x0F) + kOffset);
  out[14] = kOffset;
  out[15] = '>';
}

bool decode_status(const unsigned char packet[kPacketSize], Status& out) {
  if (packet[0] != '<' || packet[15] != '>') return false;
  for (int m = 0; m < 3; ++m) {
    std::uint16_t bits = 0;
    for (int n = 0; n < 4; ++n) {
      const unsigned char v = nibble(packet[1 + 4 * m + n]);
      if (v > 0xF) return false;
      bits = static_cast<std::uint16_t>(bits | (v << (4 * n)));
    }
    out.encoder[m] = static_cast<std::int16_t>(bits);
  }
  const unsigned char info = nibble(packet[13]);
  out.buttons = info & 0x0F;
  out.homed = (info >> 4) & kAllHomed;
  return true;
}

bool newest_status(const unsigned char* bytes, std::size_t n, Status& out) {
  for (std::size_t end = n; end >= kPacketSize; --end) {
    const unsigned char* p = bytes + end - kPacketSize;
    if (p[kPacketSize - 1] == '>' && p[0] == '<' && decode_status(p, out)) return true;
  }
  return false;
}

double encoder_to_theta(std::int16_t count) {
  const double deg_per_count = (kShaftM * kPi / (kSlots * 4.0)) / (kPi * kArmM / 360.0);
  return (count * deg_per_count + kThetaAtZeroDeg) * kPi / 180.0;
}

bool inverse_kinematics(const Eigen::Vector3d& p, Eigen::Vector3d& theta) {
  for (int i = 0; i < 3; ++i)
    if (!leg_theta(p, kPhi[i], theta[i])) return false;
  return true;
}

bool joint_jacobian(const Eigen::Vector3d& p, Eigen::Matrix3d& J) {
  constexpr double h = 1e-6;
  for (int j = 0; j < 3; ++j) {
    Eigen::Vector3d dp = Eigen::Vector3d::Zero();
    dp[j] = h;
    Eigen::Vector3d tp, tm;
    if (!inverse_kinematics(p + dp, tp) || !inverse_kinematics(p - dp, tm)) return false;
    J.col(j) = (tp - tm) / (2.0 * h);
  }
  return J.allFinite();
}

bool forward_kinematics(const Eigen::Vector3d& theta, const Eigen::Vector3d& guess, Eigen::Vector3d& p) {
  Eigen::Vector3d x = guess, t;
  for (int it = 0; it < 20; ++it) {
    Eigen::Matrix3d J;
    if (!inverse_kinematics(x, t) || !joint_jacobian(x, J)) return false;
    const Eigen::Vector3d err = t - theta;
    if (err.norm() < 1e-6) {
      p = x;
      return true;
    }
    Eigen::FullPivLU<Eigen::Matrix3d> lu(J);
    if (!lu.isInvertible()) return false;
    Eigen::Vector3d step = lu.solve(err);
    // Halve the step until the new point is reachable (never leaves the solution set).
    for (int h = 0; h < 10 && !inverse_kinematics(x - step, t); ++h) step *= 0.5;
    x -= step;
  }
  return false;
}

bool force_to_motor(const Eigen::Vector3d& p, const Eigen::Vector3d& force_N, std::int16_t motor[3]) {
  motor[0] = motor[1] = motor[2] = 0;
  Eigen::Matrix3d J;
  if (!joint_jacobian(p, J)) return false;
  Eigen::FullPivLU<Eigen::Matrix3d> lu(J);
  if (!lu.isInvertible()) return false;
  const Eigen::Matrix3d dp_dtheta = lu.inverse();
  Eigen::Vector3d counts = -kMotorCountsPerNm * (dp_dtheta.transpose() * force_N);
  const double biggest = counts.cwiseAbs().maxCoeff();
  if (!std::isfinite(biggest)) return false;
  if (biggest > 32767.0) counts *= 32767.0 / biggest;
  for (int i = 0; i < 3; ++i) motor[i] = static_cast<std::int16_t>(std::lround(counts[i]));
  return true;
}

}  // namespace haptic::drivers::falcon
