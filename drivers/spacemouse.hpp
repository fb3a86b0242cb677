#pragma once
// HID devices through hidapi (hidraw backend): the 3Dconnexion SpaceMouse family as a
// POSITION-INPUT device for a station without a haptic device. It has NO force feedback:
// its capabilities say max_force_N = 0 and no actuated axis, so every commanded force is
// clamped to zero on the way out. Also: hidraw enumeration used to detect the Touch HID model.
//
// Public report format (hidraw input reports, little-endian int16, about +/-350 counts):
//   id 1: translation x, y, z (6 bytes); newer models send 12 bytes: translation then rotation
//   id 2: rotation rx, ry, rz (6 bytes)
//   id 3: buttons bitmap (up to 4 bytes)
// The cap's translation deflection is mapped to a position: p = t / full_scale_counts * range_m.
#include "drivers/device.hpp"
#include "drivers/usb_ids.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

struct hid_device_;

namespace haptic::drivers {

struct SpaceMouseState {
  std::int16_t translation[3];
  std::int16_t rotation[3];
  std::uint32_t buttons;
  std::uint64_t reports;  // decoded reports so far
};

// Decodes one input report (data[0] = report id) into state. False for unknown or short
// reports (state untouched). RT-safe.
bool decode_spacemouse_report(const std::uint8_t* data, std::size_t length, SpaceMouseState& state);

struct HidDeviceInfo {
  std::string path;  // /dev/hidrawN
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;
  std::string manufacturer;
  std::string product;
  DeviceKind kind = DeviceKind::kUnknown;
  const char* model = "";
};

// hidraw enumeration (non-RT). known_only: only identities from usb_ids.hpp.
std::vector<HidDeviceInfo> list_hid_devices(bool known_only);

enum class SpaceMouseMode : std::uint8_t { kOwnerPolled, kOwnThread };

struct SpaceMouseConfig {
  std::string hidraw_path;          // "" = first SpaceMouse found
  double full_scale_counts = 350.0; // deflection at full scale; [1, 32767]
  double range_m = 0.05;            // position at full deflection; (0, 1]
  SpaceMouseMode mode = SpaceMouseMode::kOwnThread;
  double sample_rate_hz = 500.0;    // own-thread publish rate; [10, 10000]
};

// The capabilities a SpaceMouseDevice reports: no force, no actuated axis. Non-RT.
DeviceCapabilities spacemouse_capabilities(const SpaceMouseConfig& config);

class SpaceMouseDevice final : public HapticDevice {
 public:
  explicit SpaceMouseDevice(const SpaceMouseConfig& config, const SafetyLimits& limits = {});
  ~SpaceMouseDevice() override;
  // Non-RT. Opens the hidraw node through hidapi; throws std::runtime_error naming the node and
  // the permission fix when it cannot.
  void start() override;
  void stop() override;
  // Device I/O context (own thread, or the owner in kOwnerPolled mode; NOT for the station tick:
  // it makes non-blocking read() calls). Drains pending reports, publishes one sample at t_s.
  // A read error means the node is gone: kUnplugged.
  void poll(double t_s);
  const std::string& path() const { return path_; }
  SpaceMouseState state() const { return state_; }  // poll-context only

 private:
  void thread_main();
  SpaceMouseConfig config_;
  std::string path_;
  hid_device_* dev_ = nullptr;
  SpaceMouseState state_{};
  double last_position_m_[3] = {0, 0, 0};
  double last_t_s_ = 0.0;
  std::uint64_t sequence_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace haptic::drivers
