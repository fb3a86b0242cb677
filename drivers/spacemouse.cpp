#include "drivers/spacemouse.hpp"
#include "platform/clock.hpp"

#include <hidapi/hidapi.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <time.h>
#include <unistd.h>

namespace haptic::drivers {

namespace {
std::int16_t le16(const std::uint8_t* p) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0]) | (static_cast<std::uint16_t>(p[1]) << 8));
}

std::string narrow(const wchar_t* w) {
  std::string s;
  if (w == nullptr) return s;
  for (; *w != 0; ++w) s.push_back(*w < 128 ? static_cast<char>(*w) : '?');
  return s;
}

void hidapi_init_once() {
  static std::once_flag once;
  std::call_once(once, [] { hid_init(); });
}


const SpaceMouseConfig& checked(const SpaceMouseConfig& c) {
  if (!(c.full_scale_counts >= 1.0 && c.full_scale_counts <= 32767.0))
    throw std::invalid_argument("drivers.spacemouse.full_scale_counts = " + std::to_string(c.full_scale_counts) +
                                " is out of range; allowed [1, 32767]");
  if (!(c.range_m > 0.0 && c.range_m <= 1.0))
    throw std::invalid_argument("drivers.spacemouse.range_m = " + std::to_string(c.range_m) +
                                " is out of range; allowed (0, 1]");
  if (!(c.sample_rate_hz >= 10.0 && c.sample_rate_hz <= 10000.0))
    throw std::invalid_argument("drivers.spacemouse.sample_rate_hz = " + std::to_string(c.sample_rate_hz) +
                                " is out of range; allowed [10, 10000]");
  return c;
}

using platform::monotonic_s;
}  // namespace

DeviceCapabilities spacemouse_capabilities(const SpaceMouseConfig& c) {
  DeviceCapabilities caps{};
  caps.max_force_N = 0.0;  // no force feedback
  caps.max_stiffness_N_per_m = 0.0;
  caps.servo_rate_hz = c.sample_rate_hz;
  caps.workspace_radius_m = c.range_m * 1.7320508075688772;  // corner of the +/-range cube
  caps.min_damping_Ns_per_m = 0.0;
  for (int i = 0; i < 3; ++i) {
    caps.sensed_axes[i] = true;
    caps.actuated_axes[i] = false;
  }
  caps.name = "3Dconnexion SpaceMouse via hidapi (position input only, NO force feedback)";
  return caps;
}

bool decode_spacemouse_report(const std::uint8_t* d, std::size_t n, SpaceMouseState& s) {
  if (d == nullptr || n < 1) return false;
  switch (d[0]) {
    case 1:
      if (n < 7) return false;
      for (int i = 0; i < 3; ++i) s.translation[i] = le16(d + 1 + 2 * i);
      if (n >= 13)
        for (int i = 0; i < 3; ++i) s.rotation[i] = le16(d + 7 + 2 * i);
      break;
    case 2:
      if (n < 7) return false;
      for (int i = 0; i < 3; ++i) s.rotation[i] = le16(d + 1 + 2 * i);
      break;
    case 3: {
      if (n < 2) return false;
      std::uint32_t b = 0;
      for (std::size_t i = 1; i < n && i <= 4; ++i) b |= static_cast<std::uint32_t>(d[i]) << (8 * (i - 1));
      s.buttons = b;
      break;
    }
    default:
      return false;
  }
  ++s.reports;
  return true;
}

std::vector<HidDeviceInfo> list_hid_devices(bool known_only) {
  hidapi_init_once();
  std::vector<HidDeviceInfo> out;
  hid_device_info* all = hid_enumerate(0, 0);
  for (hid_device_info* p = all; p != nullptr; p = p->next) {
    const KnownIdentity* id = find_identity(p->vendor_id, p->product_id);
    if (known_only && id == nullptr) continue;
    HidDeviceInfo info;
    info.path = p->path ? p->path : "";
    info.vendor_id = p->vendor_id;
    info.product_id = p->product_id;
    info.serial = narrow(p->serial_number);
    info.manufacturer = narrow(p->manufacturer_string);
    info.product = narrow(p->product_string);
    info.kind = id ? id->kind : DeviceKind::kUnknown;
    info.model = id ? id->model : "";
    out.push_back(std::move(info));
  }
  hid_free_enumeration(all);
  return out;
}

SpaceMouseDevice::SpaceMouseDevice(const SpaceMouseConfig& config, const SafetyLimits& limits)
    : HapticDevice(spacemouse_capabilities(checked(config)), limits), config_(config) {}

SpaceMouseDevice::~SpaceMouseDevice() { stop(); }

void SpaceMouseDevice::start() {
  stop();
  hidapi_init_once();
  path_ = config_.hidraw_path;
  if (path_.empty()) {
    for (const HidDeviceInfo& d : list_hid_devices(true))
      if (d.kind == DeviceKind::kSpaceMouse) {
        path_ = d.path;
        break;
      }
    if (path_.empty())
      throw std::runtime_error(
          "no 3Dconnexion SpaceMouse found among the hidraw devices (device.hidraw_path is "
          "empty, so the first one is used); run haptic-devices to see what is connected");
  }
  dev_ = hid_open_path(path_.c_str());
  if (dev_ == nullptr) {
    const int err = errno;
    std::string why = "cannot open " + path_ + " through hidapi";
    if (access(path_.c_str(), R_OK | W_OK) != 0)
      why += ": no read/write permission (" + std::string(std::strerror(err)) +
             "); run build/bin/haptic-devices for the udev rule that fixes it";
    else
      why += ": not a hidraw device, or it vanished";
    throw std::runtime_error(why);
  }
  hid_set_nonblocking(dev_, 1);
  state_ = SpaceMouseState{};
  sequence_ = 0;
  for (double& p : last_position_m_) p = 0.0;
  last_t_s_ = 0.0;
  arm();
  if (config_.mode == SpaceMouseMode::kOwnThread) {
    running_.store(true, std::memory_order_release);
    thread_ = std::thread([this] { thread_main(); });
  }
}

void SpaceMouseDevice::stop() {
  disarm();
  running_.store(false, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  if (dev_ != nullptr) {
    hid_close(dev_);
    dev_ = nullptr;
  }
}

void SpaceMouseDevice::poll(double t_s) {
  if (dev_ == nullptr) return;
  std::uint8_t buf[64];
  for (int i = 0; i < 64; ++i) {  // drain what is pending, bounded
    const int n = hid_read(dev_, buf, sizeof buf);
    if (n < 0) {
      raise_fault(DeviceFault::kUnplugged, errno);
      return;
    }
    if (n == 0) break;
    decode_spacemouse_report(buf, static_cast<std::size_t>(n), state_);
  }
  double force_unused[3];
  take_force(force_unused);  // always zero: no actuated axis, max_force_N = 0
  DeviceSample s{};
  const double dt = t_s - last_t_s_;
  for (int i = 0; i < 3; ++i) {
    s.position_m[i] = state_.translation[i] / config_.full_scale_counts * config_.range_m;
    s.velocity_m_per_s[i] = (sequence_ > 0 && dt > 0.0) ? (s.position_m[i] - last_position_m_[i]) / dt : 0.0;
    last_position_m_[i] = s.position_m[i];
  }
  last_t_s_ = t_s;
  s.buttons = state_.buttons;
  s.time_s = t_s;
  s.sequence = ++sequence_;
  publish_sample(s);
}

void SpaceMouseDevice::thread_main() {
  const long period_ns = static_cast<long>(1e9 / config_.sample_rate_hz);
  std::int64_t next_ns = platform::monotonic_ns();
  while (running_.load(std::memory_order_acquire)) {
    poll(monotonic_s());
    next_ns += period_ns;
    platform::sleep_until_monotonic_ns(next_ns);
  }
}

}  // namespace haptic::drivers
