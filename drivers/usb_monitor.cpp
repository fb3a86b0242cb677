#include "drivers/usb_monitor.hpp"

#include <libusb.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace haptic::drivers {

namespace {
std::string read_sysfs_attr(const std::string& port_path, const char* attr) {
  std::ifstream in("/sys/bus/usb/devices/" + port_path + "/" + attr);
  std::string line;
  if (in && std::getline(in, line)) return line;
  return {};
}

UsbDeviceInfo describe(libusb_device* dev) {
  UsbDeviceInfo info;
  libusb_device_descriptor dd{};
  if (libusb_get_device_descriptor(dev, &dd) != 0) return info;
  info.vendor_id = dd.idVendor;
  info.product_id = dd.idProduct;
  info.bus = libusb_get_bus_number(dev);
  info.address = libusb_get_device_address(dev);
  std::uint8_t ports[8];
  const int n = libusb_get_port_numbers(dev, ports, sizeof ports);
  char path[64];
  int len = std::snprintf(path, sizeof path, "%u", info.bus);
  for (int i = 0; i < n && len > 0 && len < static_cast<int>(sizeof path); ++i)
    len += std::snprintf(path + len, sizeof path - static_cast<std::size_t>(len), "%c%u", i == 0 ? '-' : '.', ports[i]);
  info.port_path = path;
  char node[40];
  std::snprintf(node, sizeof node, "/dev/bus/usb/%03u/%03u", info.bus, info.address);
  info.devnode = node;
  const KnownIdentity* id = find_identity(dd.idVendor, dd.idProduct);
  info.kind = id ? id->kind : DeviceKind::kUnknown;
  info.model = id ? id->model : "";
  // Serial and product from sysfs (readable without opening the device); fall back to the
  // string descriptors when sysfs has none and we may open the device.
  if (n > 0) {
    info.serial = read_sysfs_attr(info.port_path, "serial");
    info.product = read_sysfs_attr(info.port_path, "product");
  }
  if ((info.serial.empty() && dd.iSerialNumber != 0) || (info.product.empty() && dd.iProduct != 0)) {
    libusb_device_handle* h = nullptr;
    if (libusb_open(dev, &h) == 0) {
      unsigned char buf[128];
      if (info.serial.empty() && dd.iSerialNumber != 0 &&
          libusb_get_string_descriptor_ascii(h, dd.iSerialNumber, buf, sizeof buf) > 0)
        info.serial = reinterpret_cast<char*>(buf);
      if (info.product.empty() && dd.iProduct != 0 &&
          libusb_get_string_descriptor_ascii(h, dd.iProduct, buf, sizeof buf) > 0)
        info.product = reinterpret_cast<char*>(buf);
      libusb_close(h);
    }
  }
  return info;
}
}  // namespace

UsbMonitor::UsbMonitor(const UsbMonitorConfig& config) : config_(config) {
  if (!(config.rescan_period_s >= 0.01 && config.rescan_period_s <= 10.0))
    throw std::invalid_argument("drivers.usb.rescan_period_s = " + std::to_string(config.rescan_period_s) +
                                " is out of range; allowed [0.01, 10]");
  const int rc = libusb_init(&ctx_);
  if (rc != 0) {
    ctx_ = nullptr;
    throw std::runtime_error(std::string("libusb_init failed: ") + libusb_error_name(rc) +
                             " (no usbfs at /dev/bus/usb? inside a container without /dev/bus/usb "
                             "no USB device can be found)");
  }
}

UsbMonitor::~UsbMonitor() {
  stop();
  if (ctx_ != nullptr) libusb_exit(ctx_);
}

std::vector<UsbDeviceInfo> UsbMonitor::enumerate(bool known_only) {
  std::vector<UsbDeviceInfo> out;
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx_, &list);
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor dd{};
    if (libusb_get_device_descriptor(list[i], &dd) != 0) continue;
    if (known_only && find_identity(dd.idVendor, dd.idProduct) == nullptr) continue;
    out.push_back(describe(list[i]));
  }
  if (list != nullptr) libusb_free_device_list(list, 1);
  return out;
}

void UsbMonitor::watch(const UsbDeviceInfo& info, HapticDevice* device) {
  std::lock_guard<std::mutex> l(mu_);
  watches_.push_back(Watch{info.bus, info.address, device});
}

void UsbMonitor::unwatch(HapticDevice* device) {
  std::lock_guard<std::mutex> l(mu_);
  watches_.erase(std::remove_if(watches_.begin(), watches_.end(),
                                [device](const Watch& w) { return w.device == device; }),
                 watches_.end());
}

int UsbMonitor::hotplug_trampoline(libusb_context*, libusb_device* dev, int event, void* self) {
  auto* m = static_cast<UsbMonitor*>(self);
  if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT) {
    m->on_left(libusb_get_bus_number(dev), libusb_get_device_address(dev));
  } else {
    m->arrivals_.fetch_add(1, std::memory_order_acq_rel);
  }
  return 0;  // keep the callback registered
}

void UsbMonitor::on_left(std::uint8_t bus, std::uint8_t address) {
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const Watch& w : watches_)
      if (w.bus == bus && w.address == address) w.device->notify_unplugged();
  }
  removals_.fetch_add(1, std::memory_order_acq_rel);
}

void UsbMonitor::rescan() {
  std::vector<std::uint16_t> now;
  for (const UsbDeviceInfo& d : enumerate(true)) now.push_back(static_cast<std::uint16_t>(d.bus << 8 | d.address));
  std::vector<std::uint16_t> before;
  {
    std::lock_guard<std::mutex> l(mu_);
    before.swap(present_);
    present_ = now;
  }
  for (std::uint16_t key : before)
    if (std::find(now.begin(), now.end(), key) == now.end())
      on_left(static_cast<std::uint8_t>(key >> 8), static_cast<std::uint8_t>(key & 0xFF));
  for (std::uint16_t key : now)
    if (std::find(before.begin(), before.end(), key) == before.end()) arrivals_.fetch_add(1, std::memory_order_acq_rel);
}

bool UsbMonitor::hotplug_capability() { return libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0; }

void UsbMonitor::start() {
  if (running_.load(std::memory_order_acquire)) return;
  hotplug_registered_ = false;
  if (config_.prefer_hotplug && libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0) {
    libusb_hotplug_callback_handle h = 0;
    const int rc = libusb_hotplug_register_callback(
        ctx_, static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
        LIBUSB_HOTPLUG_NO_FLAGS, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
        [](libusb_context* c, libusb_device* d, libusb_hotplug_event e, void* self) {
          return hotplug_trampoline(c, d, static_cast<int>(e), self);
        },
        this, &h);
    if (rc == LIBUSB_SUCCESS) {
      hotplug_registered_ = true;
      hotplug_handle_ = h;
    }
  }
  if (!hotplug_registered_) {
    std::lock_guard<std::mutex> l(mu_);
    present_.clear();
    for (const UsbDeviceInfo& d : enumerate(true)) present_.push_back(static_cast<std::uint16_t>(d.bus << 8 | d.address));
  }
  running_.store(true, std::memory_order_release);
  thread_ = std::thread([this, hotplug = hotplug_registered_] { thread_main(hotplug); });
}

void UsbMonitor::stop() {
  if (!running_.exchange(false, std::memory_order_acq_rel)) return;
  if (thread_.joinable()) thread_.join();  // returns within one 100 ms event wait or 10 ms of a rescan pause
  if (hotplug_registered_) {
    // Deregistering after the thread is gone: no callback can run any more.
    libusb_hotplug_deregister_callback(ctx_, hotplug_handle_);
    hotplug_registered_ = false;
  }
}

void UsbMonitor::thread_main(bool hotplug) {
  while (running_.load(std::memory_order_acquire)) {
    if (hotplug) {
      timeval tv{0, 100000};  // bounded so stop() is prompt even without a wake-up
      libusb_handle_events_timeout_completed(ctx_, &tv, nullptr);
    } else {
      rescan();
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(config_.rescan_period_s);
      while (running_.load(std::memory_order_acquire) && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));  // stop() stays prompt
    }
  }
}

}  // namespace haptic::drivers
