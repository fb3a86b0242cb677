#include "drivers/falcon_device.hpp"

#include "platform/clock.hpp"

#include <libusb.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <thread>

namespace haptic::drivers {

namespace {
using namespace falcon;
constexpr unsigned kTimeoutMs = 1000;      // set-up transfers
constexpr unsigned kServoTimeoutMs = 100;  // one servo exchange
constexpr double kOriginZ = 0.11;          // libnifalcon frame z of our device-frame origin (middle of the travel)

std::string usb_error(int rc) { return std::string(libusb_error_name(rc)) + " (" + std::to_string(rc) + ")"; }

// Copies the payload of a bulk IN transfer, dropping the FTDI's two modem-status bytes at the
// start of every 64-byte USB packet.
std::size_t strip_status(const unsigned char* in, int n, unsigned char* out) {
  std::size_t k = 0;
  for (int off = 0; off < n; off += 64) {
    const int end = std::min(n, off + 64);
    for (int i = off + 2; i < end; ++i) out[k++] = in[i];
  }
  return k;
}
}  // namespace

DeviceCapabilities falcon_capabilities() {
  DeviceCapabilities c{};
  c.max_force_N = 8.9;               // "> 2 lb" (Novint spec sheet)
  c.max_stiffness_N_per_m = 0.0;     // not published
  c.servo_rate_hz = 1000.0;
  c.workspace_radius_m = 0.0875;     // half-diagonal of the 10 cm cube, rounded up
  c.min_damping_Ns_per_m = 0.0;      // not published: the station requires device.damping_Ns_per_m
  for (int i = 0; i < 3; ++i) c.sensed_axes[i] = c.actuated_axes[i] = true;
  c.name = "Novint Falcon via libusb";
  return c;
}

FalconDevice::FalconDevice(const FalconConfig& config, const SafetyLimits& limits)
    : HapticDevice(falcon_capabilities(), limits), config_(config) {}

FalconDevice::~FalconDevice() { stop(); }

int FalconDevice::ftdi(std::uint8_t request, std::uint16_t value) {
  return libusb_control_transfer(handle_, kFtdiRequestType, request, value, 0, nullptr, 0, kTimeoutMs);
}

void FalconDevice::open_usb() {
  int rc = libusb_init(&ctx_);
  if (rc != 0) throw std::runtime_error("falcon: libusb_init failed: " + usb_error(rc));
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx_, &list);
  libusb_device* found = nullptr;
  int seen = 0;
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0 || d.idVendor != kVendorId || d.idProduct != kProductId) continue;
    const bool at = config_.usb_bus >= 0 ? libusb_get_bus_number(list[i]) == config_.usb_bus && libusb_get_device_address(list[i]) == config_.usb_address
                                          : seen == config_.index;
    ++seen;
    if (at) found = list[i];
  }
  if (found != nullptr) rc = libusb_open(found, &handle_);
  libusb_free_device_list(list, 1);
  if (found == nullptr)
    throw std::runtime_error(config_.usb_bus >= 0 ? "falcon: the chosen Falcon (bus " + std::to_string(config_.usb_bus) + " address " +
                                                        std::to_string(config_.usb_address) + ") is gone from the bus"
                                                  : "falcon: no Novint Falcon (USB 0403:cb48) number " + std::to_string(config_.index) + " found (" +
                                                        std::to_string(seen) + " on the bus; device.falcon_index counts from 0)");
  if (rc != 0)
    throw std::runtime_error("falcon: cannot open the Falcon's USB node: " + usb_error(rc) +
                             (rc == LIBUSB_ERROR_ACCESS ? "; see `haptic-devices` for the udev rule" : ""));
  libusb_set_auto_detach_kernel_driver(handle_, 1);  // ftdi_sio may have bound it
  rc = libusb_claim_interface(handle_, 0);
  if (rc != 0) throw std::runtime_error("falcon: cannot claim interface 0: " + usb_error(rc));
}

// Firmware mode, handshake, the user's firmware file with every byte's echo compared, normal mode.
void FalconDevice::load_firmware() {
  if (config_.firmware_path.empty())
    throw std::runtime_error("falcon: no firmware file: set device.falcon_firmware_path to the Novint firmware the Falcon "
                             "needs at every power-up (not shipped here; libnifalcon's sources describe where it comes from)");
  std::ifstream f(config_.firmware_path, std::ios::binary);
  const std::vector<unsigned char> fw((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (!f.good() && !f.eof()) throw std::runtime_error("falcon: cannot read device.falcon_firmware_path = \"" + config_.firmware_path + "\"");
  if (fw.empty()) throw std::runtime_error("falcon: device.falcon_firmware_path = \"" + config_.firmware_path + "\" is missing or empty");
  const std::pair<std::uint8_t, std::uint16_t> setup[] = {
      {kFtdiReset, kPurgeRx}, {kFtdiReset, kPurgeTx}, {kFtdiLatency, 16}, {kFtdiBaud, kBaud9600}, {kFtdiData, kData8N1},
      {kFtdiFlowCtrl, 0},     {kFtdiModemCtrl, kRtsLow}, {kFtdiModemCtrl, kDtrLow}, {kFtdiModemCtrl, kDtrHigh}};
  for (const auto& [req, val] : setup)
    if (const int rc = ftdi(req, val); rc < 0) throw std::runtime_error("falcon: FTDI set-up request " + std::to_string(req) + " failed: " + usb_error(rc));
  unsigned char buf[64];
  int n = 0;
  bool ok = false;
  for (int attempt = 0; attempt < 100 && !ok; ++attempt) {
    unsigned char hello[3] = {0x0a, 0x43, 0x0d};
    if (libusb_bulk_transfer(handle_, kEndpointOut, hello, 3, &n, kTimeoutMs) != 0) break;
    if (libusb_bulk_transfer(handle_, kEndpointIn, buf, sizeof buf, &n, kTimeoutMs) != 0) break;
    static constexpr unsigned char kReply[5] = {0x00, 0x0a, 0x44, 0x2c, 0x0d};
    ok = (n == 7 && std::memcmp(buf + 2, kReply, 5) == 0) || (n == 6 && std::memcmp(buf + 2, kReply + 1, 4) == 0);
  }
  if (!ok) throw std::runtime_error("falcon: the boot loader did not answer the firmware-mode handshake (is it a Falcon?)");
  unsigned char a = 'A';
  if (ftdi(kFtdiModemCtrl, kDtrLow) < 0 || ftdi(kFtdiBaud, kBaudFirmware) < 0 ||
      libusb_bulk_transfer(handle_, kEndpointOut, &a, 1, &n, kTimeoutMs) != 0 ||
      libusb_bulk_transfer(handle_, kEndpointIn, buf, 3, &n, kTimeoutMs) != 0 || n != 3 || buf[2] != 'A')
    throw std::runtime_error("falcon: the boot loader did not echo 'A' at the firmware baud rate");
  for (std::size_t done = 0; done < fw.size();) {
    const int len = static_cast<int>(std::min(kFirmwareChunk, fw.size() - done));
    if (const int rc = libusb_bulk_transfer(handle_, kEndpointOut, const_cast<unsigned char*>(fw.data() + done), len, &n, kTimeoutMs); rc != 0)
      throw std::runtime_error("falcon: firmware write failed at byte " + std::to_string(done) + ": " + usb_error(rc));
    for (int echoed = 0; echoed < len;) {
      if (const int rc = libusb_bulk_transfer(handle_, kEndpointIn, buf, len + 2 - echoed, &n, kTimeoutMs); rc != 0 || n < 2)
        throw std::runtime_error("falcon: no firmware echo at byte " + std::to_string(done + echoed) + ": " + usb_error(rc));
      for (int i = 2; i < n; ++i, ++echoed)
        if (echoed >= len || buf[i] != fw[done + echoed])
          throw std::runtime_error("falcon: firmware echo differs at byte " + std::to_string(done + echoed) +
                                   ": the load failed (replug the Falcon and retry)");
    }
    done += len;
  }
  for (const auto& [req, val] : {std::pair<std::uint8_t, std::uint16_t>{kFtdiLatency, 1}, {kFtdiBaud, kBaudNormal}, {kFtdiReset, kPurgeRx}, {kFtdiReset, kPurgeTx}})
    if (const int rc = ftdi(req, val); rc < 0) throw std::runtime_error("falcon: FTDI normal-mode request failed: " + usb_error(rc));
}

// One servo exchange: send the packet, read what arrived, decode the newest complete status.
// Returns 0 (also when nothing arrived in time: the tick's stale-sample check decides) or the libusb error.
int FalconDevice::exchange(std::uint8_t control, const std::int16_t motor[3], Status& status, bool& got) {
  unsigned char out[kPacketSize];
  encode_command(motor, control, out);
  int n = 0;
  int rc = libusb_bulk_transfer(handle_, kEndpointOut, out, kPacketSize, &n, kServoTimeoutMs);
  unsigned char in[64];
  if (rc == 0) rc = libusb_bulk_transfer(handle_, kEndpointIn, in, sizeof in, &n, kServoTimeoutMs);
  got = false;
  if (rc == LIBUSB_ERROR_TIMEOUT) return 0;
  if (rc != 0) return rc;
  unsigned char payload[64];
  const std::size_t k = strip_status(in, n, payload);
  if (rx_len_ + k > sizeof rx_) rx_len_ = 0;  // never fills with a working device; drop stale bytes
  std::memcpy(rx_ + rx_len_, payload, k);
  rx_len_ += k;
  got = newest_status(rx_, rx_len_, status);
  if (got) rx_len_ = 0;
  return 0;
}

void FalconDevice::home() {
  const std::int16_t zero[3] = {0, 0, 0};
  const double t0 = platform::monotonic_s();
  while (platform::monotonic_s() - t0 < config_.homing_timeout_s) {
    Status s{};
    bool got = false;
    if (const int rc = exchange(kCtlHoming | kLedRed, zero, s, got); rc != 0)
      throw std::runtime_error("falcon: USB failed while homing: " + usb_error(rc));
    if (got && s.homed == kAllHomed) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  throw std::runtime_error("falcon: not homed within " + std::to_string(config_.homing_timeout_s) +
                           " s (device.falcon_homing_timeout_s): move the grip all the way out, then push it straight in");
}

void FalconDevice::start() {
  release();
  try {
    open_usb();
    load_firmware();
    home();
  } catch (...) {
    release();
    throw;
  }
  frames_.store(0);
  sequence_ = 0;
  rx_len_ = 0;
  arm();
  if (config_.own_thread) {
    running_.store(true);
    thread_ = std::thread([this] {
      const auto period_ns = static_cast<std::int64_t>(1e9 / config_.servo_rate_hz);
      std::int64_t next = platform::monotonic_ns();
      while (running_.load(std::memory_order_acquire) && service()) {
        next += period_ns;
        platform::sleep_until_monotonic_ns(next);
      }
    });
  }
}

bool FalconDevice::service() {
  if (handle_ == nullptr || fault() != DeviceFault::kNone) return false;
  double f[3];
  take_force(f);  // exactly zero in the safe state
  std::int16_t motor[3] = {0, 0, 0};
  force_to_motor(position_, Eigen::Vector3d(f[0], f[1], f[2]), motor);
  Status s{};
  bool got = false;
  if (const int rc = exchange(led_, motor, s, got); rc != 0) {
    // Unplugged (or the link broke): latched here, so the tick's next read_newest() is false.
    raise_fault(rc == LIBUSB_ERROR_NO_DEVICE || rc == LIBUSB_ERROR_IO ? DeviceFault::kUnplugged : DeviceFault::kServoError, rc);
    return false;
  }
  frames_.fetch_add(1, std::memory_order_relaxed);
  if (!got) return true;
  const Eigen::Vector3d theta(encoder_to_theta(s.encoder[0]), encoder_to_theta(s.encoder[1]), encoder_to_theta(s.encoder[2]));
  Eigen::Vector3d p;
  if (!forward_kinematics(theta, position_, p)) {
    raise_fault(DeviceFault::kOutOfRange, 1);  // encoders no reachable position matches
    return false;
  }
  const double now = platform::monotonic_s();
  if (sequence_ > 0 && now > last_time_s_) velocity_ = 0.5 * velocity_ + 0.5 * (p - position_) / (now - last_time_s_);
  position_ = p;
  last_time_s_ = now;
  DeviceSample out{};
  for (int i = 0; i < 3; ++i) {
    out.position_m[i] = p[i] - (i == 2 ? kOriginZ : 0.0);
    out.velocity_m_per_s[i] = velocity_[i];
  }
  out.buttons = s.buttons;
  out.time_s = now;
  out.sequence = ++sequence_;
  publish_sample(out);
  return true;
}

void FalconDevice::release() {
  running_.store(false);
  if (thread_.joinable()) thread_.join();
  if (handle_ != nullptr) {
    libusb_release_interface(handle_, 0);
    libusb_close(handle_);
    handle_ = nullptr;
  }
  if (ctx_ != nullptr) {
    libusb_exit(ctx_);
    ctx_ = nullptr;
  }
}

void FalconDevice::stop() {
  disarm();  // from here take_force() yields zero
  running_.store(false);
  if (thread_.joinable()) thread_.join();
  if (handle_ != nullptr && fault() != DeviceFault::kUnplugged) {
    const std::int16_t zero[3] = {0, 0, 0};
    Status s{};
    bool got = false;
    exchange(0, zero, s, got);  // zero motor commands, LEDs off
  }
  release();
}

}  // namespace haptic::drivers
