// Falcon protocol and kinematics (drivers/falcon_protocol.hpp) without USB: packet layout as
// documented, encoder scale, the delta robot's symmetry, IK/FK agreement, and the force mapping
// delivering the same power in joint and Cartesian space.
#include "drivers/falcon_protocol.hpp"

#include <cmath>
#include <cstring>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers::falcon;

TEST_GROUP(FalconProtocol){};

TEST(FalconProtocol, CommandPacketIsPrintableNibblesLeastSignificantFirst) {
  const std::int16_t m[3] = {0x1234, -1, 0};
  unsigned char p[kPacketSize];
  encode_command(m, kCtlHoming | kLedRed, p);
  // '<' then 4 nibbles + 'A' per motor, least significant first (0x1234 -> E D C B); control
  // nibble 0x3 -> 'D'; 'A'; '>'
  STRNCMP_EQUAL("<EDCBPPPPAAAADA>", reinterpret_cast<const char*>(p), kPacketSize);
}

TEST(FalconProtocol, StatusPacketDecodesEncodersButtonsAndHoming) {
  // The libnifalcon header's worked example: bytes 0x4A 0x46 0x4B 0x50 ("JFKP") -> nibbles 9 5 A F,
  // least significant first 0xFA59: -1447 as int16 (the header quotes the magnitude, 1447).
  unsigned char p[kPacketSize] = {'<', 'J', 'F', 'K', 'P', 'A', 'A', 'A', 'A', 'P', 'P', 'P', 'P', 0, 'A', '>'};
  p[13] = static_cast<unsigned char>(0x41 + 0x70 + 0x05);  // all homed, buttons 0101
  Status s{};
  CHECK(decode_status(p, s));
  CHECK_EQUAL(-1447, s.encoder[0]);  // 0xFA59 as int16
  CHECK_EQUAL(0, s.encoder[1]);
  CHECK_EQUAL(-1, s.encoder[2]);
  CHECK_EQUAL(kAllHomed, s.homed);
  CHECK_EQUAL(0x5, s.buttons);
  p[5] = 'Z';  // not a nibble
  CHECK_FALSE(decode_status(p, s));
}

TEST(FalconProtocol, NewestCompletePacketWinsInAByteStream) {
  unsigned char stream[50];
  std::memset(stream, 'x', sizeof stream);
  const std::int16_t a[3] = {1, 2, 3}, b[3] = {4, 5, 6};
  unsigned char pa[kPacketSize], pb[kPacketSize];
  encode_command(a, 0, pa);  // same layout both ways for the encoder part
  encode_command(b, 0, pb);
  std::memcpy(stream + 3, pa, kPacketSize);
  std::memcpy(stream + 22, pb, kPacketSize);  // then 12 bytes of a third, incomplete packet
  stream[38] = '<';
  Status s{};
  CHECK(newest_status(stream, sizeof stream, s));
  CHECK_EQUAL(4, s.encoder[0]);
  CHECK_EQUAL(6, s.encoder[2]);
  CHECK_FALSE(newest_status(stream, 17, s));  // only garbage and a partial packet
}

TEST(FalconProtocol, EncoderScaleIs35DegreesAtZeroAndTheShaftToArmRatioPerTurn) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  DOUBLES_EQUAL(35.0 * kDeg, encoder_to_theta(0), 1e-12);
  // 1280 counts = one motor turn = 360 * 14.25 / 110 degrees of the arm
  DOUBLES_EQUAL(360.0 * 14.25 / 110.0 * kDeg, encoder_to_theta(1280) - encoder_to_theta(0), 1e-9);
}

TEST(FalconProtocol, EqualLegAnglesPutTheGripOnTheAxisAndIkFkAgree) {
  for (const std::int16_t c : {-800, 0, 600}) {
    const Eigen::Vector3d th(encoder_to_theta(c), encoder_to_theta(c), encoder_to_theta(c));
    Eigen::Vector3d p;
    CHECK(forward_kinematics(th, Eigen::Vector3d(0.0, 0.0, 0.11), p));
    DOUBLES_EQUAL(0.0, p.x(), 1e-7);
    DOUBLES_EQUAL(0.0, p.y(), 1e-7);
  }
  for (double x = -0.03; x <= 0.031; x += 0.03)
    for (double y = -0.03; y <= 0.031; y += 0.03)
      for (double z = 0.09; z <= 0.151; z += 0.03) {
        const Eigen::Vector3d p(x, y, z);
        Eigen::Vector3d th, q;
        CHECK(inverse_kinematics(p, th));
        CHECK(forward_kinematics(th, Eigen::Vector3d(0.0, 0.0, 0.11), q));
        CHECK((q - p).norm() < 1e-6);
      }
  Eigen::Vector3d th;
  CHECK_FALSE(inverse_kinematics(Eigen::Vector3d(0.0, 0.0, 0.5), th));  // far beyond the arms
}

TEST(FalconProtocol, MotorTorquesDeliverTheSamePowerAsTheCartesianForce) {
  const Eigen::Vector3d p(0.015, -0.01, 0.12), F(0.7, -0.4, 1.1), dp(2e-5, -1e-5, 3e-5);
  std::int16_t m[3];
  CHECK(force_to_motor(p, F, m));
  Eigen::Vector3d t0, t1;
  CHECK(inverse_kinematics(p, t0));
  CHECK(inverse_kinematics(p + dp, t1));
  const Eigen::Vector3d tau(-m[0] / kMotorCountsPerNm, -m[1] / kMotorCountsPerNm, -m[2] / kMotorCountsPerNm);
  // tau . dtheta = F . dp (to the rounding of the int16 commands and the finite step)
  DOUBLES_EQUAL(F.dot(dp), tau.dot(t1 - t0), 0.02 * std::abs(F.dot(dp)));
  // Saturation keeps the direction: a huge force scales all three together.
  std::int16_t big[3];
  CHECK(force_to_motor(p, 1000.0 * F, big));
  const int imax = std::abs(big[0]) >= std::abs(big[1]) && std::abs(big[0]) >= std::abs(big[2]) ? 0 : (std::abs(big[1]) >= std::abs(big[2]) ? 1 : 2);
  CHECK_EQUAL(32767, std::abs(big[imax]));
  for (int i = 0; i < 3; ++i) DOUBLES_EQUAL(static_cast<double>(m[i]) / m[imax], static_cast<double>(big[i]) / big[imax], 0.01);
}
