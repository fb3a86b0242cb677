#pragma once
// USB discovery and hotplug of the identities in usb_ids.hpp, through libusb.
// Hotplug: libusb_hotplug_register_callback when libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG),
// else periodic re-enumeration (rescan_period_s). Either way events are handled on the
// monitor's own (non-RT) thread; a removal of a watched device calls notify_unplugged() on its
// HapticDevice, which puts that device in the safe state: its next output is zero force and
// the station's next read_newest() returns false.
#include "drivers/device.hpp"
#include "drivers/usb_ids.hpp"

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

struct libusb_context;
struct libusb_device;

namespace haptic::drivers {

struct UsbDeviceInfo {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::string port_path;      // sysfs name, e.g. "1-3"
  std::string serial;         // sysfs "serial" attribute, else the string descriptor, else ""
  std::string product;
  std::string devnode;        // /dev/bus/usb/BBB/DDD
  DeviceKind kind = DeviceKind::kUnknown;
  const char* model = "";
};

struct UsbMonitorConfig {
  bool prefer_hotplug = true;     // false forces periodic re-enumeration
  double rescan_period_s = 0.25;  // re-enumeration period when hotplug is unavailable; [0.01, 10]
};

class UsbMonitor {
 public:
  // Non-RT. Throws std::runtime_error when libusb cannot initialise (no usbfs).
  explicit UsbMonitor(const UsbMonitorConfig& config = {});
  ~UsbMonitor();
  UsbMonitor(const UsbMonitor&) = delete;
  UsbMonitor& operator=(const UsbMonitor&) = delete;

  // Non-RT. Current devices; known_only: only identities from usb_ids.hpp.
  std::vector<UsbDeviceInfo> enumerate(bool known_only);

  // Non-RT. When the device at (bus, address) leaves, device->notify_unplugged() is called from
  // the monitor thread. The device must outlive the monitor or be unwatched first.
  void watch(const UsbDeviceInfo& info, HapticDevice* device);
  void unwatch(HapticDevice* device);

  // Non-RT. Starts/stops the event thread (hotplug or re-enumeration).
  void start();
  void stop();

  bool using_hotplug() const { return hotplug_registered_; }
  // Whether this libusb supports hotplug callbacks on this system (else re-enumeration).
  static bool hotplug_capability();
  std::uint64_t arrivals() const { return arrivals_.load(std::memory_order_acquire); }
  std::uint64_t removals() const { return removals_.load(std::memory_order_acquire); }

 private:
  struct Watch {
    std::uint8_t bus;
    std::uint8_t address;
    HapticDevice* device;
  };
  static int hotplug_trampoline(libusb_context* ctx, libusb_device* dev, int event, void* self);
  void on_left(std::uint8_t bus, std::uint8_t address);
  void thread_main(bool hotplug);
  void rescan();

  UsbMonitorConfig config_;
  libusb_context* ctx_ = nullptr;
  bool hotplug_registered_ = false;
  int hotplug_handle_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::mutex mu_;  // guards watches_ and present_ (non-RT side only)
  std::vector<Watch> watches_;
  std::vector<std::uint16_t> present_;  // (bus << 8 | address) of known devices, for rescans
  std::atomic<std::uint64_t> arrivals_{0}, removals_{0};
};

}  // namespace haptic::drivers
