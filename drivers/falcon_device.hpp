#pragma once
// Novint Falcon through libusb-1.0: the first device here whose whole servo path is open code.
// Protocol, firmware loading and kinematics: drivers/falcon_protocol.hpp (written from the public
// libnifalcon description; never checked against a real Falcon, see drivers/README.md).
//
// start(): finds the n-th 0403:cb48 on USB, claims interface 0, loads the firmware file the user
// supplies (device.falcon_firmware_path; Novint's firmware is not ours to ship) with every byte's
// echo compared, switches to normal mode, then homes: packets with the homing bit (red LED) until
// the device reports all three axes homed (the user moves the grip all the way out and pushes it
// straight in), then blue LED and arm(). Each servo exchange (service()) sends the newest limited
// force as motor commands (force_to_motor at the current position) and reads the newest status
// packet: encoders -> leg angles -> forward kinematics -> position (device frame: libnifalcon's,
// shifted so the middle of the travel along its axis, z = 0.11 m, is the origin), velocity by a
// filtered difference. A transfer failing with "no device" or an I/O error latches kUnplugged in that
// exchange: the tick's next read_newest() returns false (safe state within one tick), and nothing
// more is sent.
#include "drivers/device.hpp"
#include "drivers/falcon_protocol.hpp"

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

struct libusb_context;
struct libusb_device_handle;

namespace haptic::drivers {

struct FalconConfig {
  std::string firmware_path;       // device.falcon_firmware_path: required
  int index = 0;                   // device.falcon_index: which Falcon (0 = first on the bus)
  int usb_bus = -1, usb_address = -1;  // when >= 0: exactly this USB device (open_device's choice, watched for unplug)
  double homing_timeout_s = 30.0;  // device.falcon_homing_timeout_s
  bool own_thread = true;          // false: the owner calls service() (tests, benchmarks)
  double servo_rate_hz = 1000.0;   // own thread's exchange rate
};

// Published figures (Novint's public spec sheet as widely quoted: > 2 lb (~8.9 N) peak force,
// 4 x 4 x 4 in (~10 cm) workspace, 1 kHz servo). No b_d is published: the station requires
// device.damping_Ns_per_m, as for the Touch.
DeviceCapabilities falcon_capabilities();

class FalconDevice final : public HapticDevice {
 public:
  explicit FalconDevice(const FalconConfig& config, const SafetyLimits& limits = {});
  ~FalconDevice() override;

  // Non-RT. Throws std::runtime_error saying what is missing (no Falcon on USB, no firmware file
  // and the key that names it, an echo mismatch while loading, homing timeout with what to do).
  void start() override;
  void stop() override;

  // One servo exchange on the caller's thread (own_thread = false). Not RT-safe (libusb
  // transfers); it is the backend's I/O context. False when the device is in its safe state.
  bool service();
  std::uint64_t servo_frames() const { return frames_.load(std::memory_order_relaxed); }

 private:
  void open_usb();
  void load_firmware();
  void home();
  int exchange(std::uint8_t control, const std::int16_t motor[3], falcon::Status& status, bool& got);
  int ftdi(std::uint8_t request, std::uint16_t value);
  void release();

  FalconConfig config_;
  libusb_context* ctx_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<std::uint64_t> frames_{0};
  // I/O-context state.
  Eigen::Vector3d position_{0.0, 0.0, 0.11};  // libnifalcon frame
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
  double last_time_s_ = 0.0;
  std::uint64_t sequence_ = 0;
  std::uint8_t led_ = falcon::kLedBlue;
  unsigned char rx_[512];
  std::size_t rx_len_ = 0;
};

}  // namespace haptic::drivers
