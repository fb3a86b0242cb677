#pragma once
// Novint Falcon: the wire protocol and kinematics, written for this project from the PUBLIC
// description in the libnifalcon sources (BSD; Kyle Machulis et al.; the Novint firmware's packet
// layout documented in FalconFirmwareNovintSDK.h/.cpp, the FTDI set-up in FalconCommLibUSB.cpp,
// firmware loading in FalconFirmware.cpp, the delta-robot geometry in FalconGeometry.h and
// R. E. Stamper's kinematics in FalconKinematicStamper.cpp). No code is copied; every number
// below is one stated there. Nothing here was checked against a real Falcon (we have none):
// see drivers/README.md for what is and is not known.
//
// USB: the Falcon is an FTDI FT232 USB-serial chip (0403:cb48), interface 0, bulk OUT 0x02 and
// bulk IN 0x81; every bulk IN transfer starts with the FTDI's two modem-status bytes.
// Firmware mode (to load the firmware the user supplies): latency 16 ms, 9600 baud (divisor
// 0x4138), 8N1, no flow control, RTS low, DTR low then high; write 0x0a 0x43 0x0d until the reply
// (after the status bytes) is 0x0a 0x44 0x2c 0x0d (on Linux) or 0x00 0x0a 0x44 0x2c 0x0d;
// DTR low, baud divisor 0x15 ("140000"), write 'A' and expect 'A' back; then the firmware file is
// written in chunks of at most 62 bytes and the device echoes every byte (compared).
// Normal mode: latency 1 ms, baud divisor 0x0002, purge RX and TX.
// Servo exchange (Novint firmware): the host sends 16 printable bytes, the device answers 16:
//   host -> device  '<' m0 m1 m2 m3  m4..m7  m8..m11  ctl  0  '>'   each byte + 0x41 ('A')
//     m: three int16 motor commands, 4 nibbles each, least significant first;
//     ctl: 0x01 homing mode, 0x02 red, 0x04 green, 0x08 blue LED (as the libnifalcon code sets
//     them; its header comment lists homing as 0x10, which does not fit the nibble: the code wins)
//   device -> host  '<' e0..e3  e4..e7  e8..e11  info  x  '>'   each byte - 0x41
//     e: three int16 encoder counts; info bits 0..3 buttons, bits 4..6 "axis homed" (top, right, left)
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

namespace haptic::drivers::falcon {

inline constexpr std::uint16_t kVendorId = 0x0403;   // FTDI
inline constexpr std::uint16_t kProductId = 0xcb48;  // Falcon
inline constexpr unsigned char kEndpointOut = 0x02, kEndpointIn = 0x81;
inline constexpr std::size_t kPacketSize = 16;
inline constexpr std::size_t kFirmwareChunk = 62;

// FTDI vendor requests (bmRequestType 0x40) used by the set-up, in libftdi's numbering.
inline constexpr std::uint8_t kFtdiRequestType = 0x40;
inline constexpr std::uint8_t kFtdiReset = 0, kFtdiModemCtrl = 1, kFtdiFlowCtrl = 2, kFtdiBaud = 3, kFtdiData = 4,
                              kFtdiLatency = 9;
inline constexpr std::uint16_t kPurgeRx = 1, kPurgeTx = 2;
inline constexpr std::uint16_t kBaud9600 = 0x4138, kBaudFirmware = 0x0015, kBaudNormal = 0x0002;
inline constexpr std::uint16_t kData8N1 = 8;
inline constexpr std::uint16_t kRtsLow = 0x0200, kDtrLow = 0x0100, kDtrHigh = 0x0101;

inline constexpr std::uint8_t kCtlHoming = 0x01, kLedRed = 0x02, kLedGreen = 0x04, kLedBlue = 0x08;
inline constexpr std::uint8_t kAllHomed = 0x07;  // the three "axis homed" bits

struct Status {
  std::int16_t encoder[3];
  std::uint8_t buttons;  // bits 0..3
  std::uint8_t homed;    // bits 0..2: the three axes (kAllHomed when homed)
};

// RT-safe. The 16-byte host -> device packet.
void encode_command(const std::int16_t motor[3], std::uint8_t control, unsigned char out[kPacketSize]);
// RT-safe. The device -> host packet (the 16 bytes from '<' to '>'); false when malformed.
bool decode_status(const unsigned char packet[kPacketSize], Status& out);
// RT-safe. Finds the newest complete packet in a byte stream (modem-status bytes already removed).
bool newest_status(const unsigned char* bytes, std::size_t n, Status& out);

// ---- kinematics (metres, radians; the device frame of libnifalcon: origin at the base centre,
// z pointing out of the device towards the user) --------------------------------------------------
// RT-safe. Leg angle theta1 (rad) of an encoder count: 320-slot wheel read in quadrature on a
// 14.25 mm shaft driving a 110 mm arm, 35 degrees at count 0.
double encoder_to_theta(std::int16_t count);
// RT-safe. Inverse kinematics: the three theta1 of the end-effector position p; false when p is
// outside the reachable set (no real solution).
bool inverse_kinematics(const Eigen::Vector3d& p, Eigen::Vector3d& theta);
// RT-safe. Forward kinematics by Newton's method from `guess` (the previous position): false when it
// does not converge to within 1e-6 rad in 20 iterations.
bool forward_kinematics(const Eigen::Vector3d& theta, const Eigen::Vector3d& guess, Eigen::Vector3d& p);
// RT-safe. Motor commands for the Cartesian force F at position p: joint torques tau = (dp/dtheta)^T F
// (same power: tau . dtheta = F . dp), times the 10000 counts per N m libnifalcon uses (its
// empirical scale, not a vendor figure), sign as there (negated); scaled down together (direction
// kept) when one would exceed the int16 range. False (and zero commands) when p is unreachable.
bool force_to_motor(const Eigen::Vector3d& p, const Eigen::Vector3d& force_N, std::int16_t motor[3]);
// RT-safe. d theta / d p at p (central differences of inverse_kinematics); false when unreachable.
bool joint_jacobian(const Eigen::Vector3d& p, Eigen::Matrix3d& dtheta_dp);

inline constexpr double kMotorCountsPerNm = 10000.0;

}  // namespace haptic::drivers::falcon
