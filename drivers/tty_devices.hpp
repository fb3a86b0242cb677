#pragma once
// USB serial (cdc_acm) nodes of the devices we recognise: the USB Touch (2988:0302, 0301:2988)
// appears as /dev/ttyACM*, group dialout by default. Found through sysfs
// (/sys/bus/usb/devices/<interface>/tty/ttyACM* -> the interface's parent, the USB device, with
// idVendor/idProduct/serial), so it works under umockdev as on a real system. Non-RT (diagnostics and discovery).
#include <cstdint>
#include <string>
#include <vector>

#include "drivers/usb_ids.hpp"

namespace haptic::drivers {

struct TtyDeviceInfo {
  std::string node;        // /dev/ttyACM0
  std::uint16_t vendor_id = 0, product_id = 0;
  std::string serial;
  std::string driver;      // the interface's kernel driver (cdc_acm)
  DeviceKind kind = DeviceKind::kUnknown;
  const char* model = "";
};

// Every ttyACM node whose USB device has a known identity (all of them when known_only = false).
std::vector<TtyDeviceInfo> list_acm_devices(bool known_only);

}  // namespace haptic::drivers
