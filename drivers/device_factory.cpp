#include "drivers/device_factory.hpp"

#include <cstdio>
#include <exception>
#include <stdexcept>

namespace haptic::drivers {

OpenedDevice::~OpenedDevice() {
  if (monitor) monitor->stop();
  if (device) device->stop();
}

namespace {
constexpr const char* kMissingHint =
    "Check the device with `haptic-devices` (permissions, vendor library, udev rules). To run this station with a "
    "SIMULATED user instead (it plays the scenario's scripted push, which the other stations feel), say so "
    "explicitly: device.kind = \"simulated\".";

std::string usb_line(const UsbDeviceInfo& d) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%04x:%04x %s (bus %03u addr %03u, serial \"%s\")", d.vendor_id, d.product_id,
                d.model, d.bus, d.address, d.serial.c_str());
  return buf;
}

bool try_touch(const DeviceSelection& sel, OpenedDevice& out, const UsbDeviceInfo* usb) {
  auto dev = std::make_unique<PhantomDevice>(sel.touch, sel.safety);
  try {
    dev->start();
  } catch (const std::exception& e) {
    out.report += std::string("touch: cannot start: ") + e.what() + "\n";
    return false;
  }
  out.report += "touch: started through " + dev->library_path() + "\n";
  if (usb != nullptr && out.monitor) {
    out.monitor->watch(*usb, dev.get());
    out.report += "touch: unplug detection on " + usb_line(*usb) + "\n";
  }
  out.device = std::move(dev);
  return true;
}

bool try_spacemouse(const DeviceSelection& sel, OpenedDevice& out) {
  auto dev = std::make_unique<SpaceMouseDevice>(sel.spacemouse, sel.safety);
  try {
    dev->start();
  } catch (const std::exception& e) {
    out.report += std::string("spacemouse: cannot start: ") + e.what() + "\n";
    return false;
  }
  out.report += "spacemouse: started on " + dev->path() +
                " (position input only, NO force feedback: every force is clamped to zero)\n";
  if (out.monitor) {
    for (const UsbDeviceInfo& d : out.monitor->enumerate(true))
      if (d.kind == DeviceKind::kSpaceMouse) {
        out.monitor->watch(d, dev.get());
        break;
      }
  }
  out.device = std::move(dev);
  return true;
}

void use_simulated(const DeviceSelection& sel, OpenedDevice& out) {
  SimulatedDeviceConfig c = sel.simulated;
  auto dev = std::make_unique<SimulatedDevice>(c, sel.safety);
  dev->start();
  out.simulated = c.mode == SimulatedDeviceMode::kOwnerStepped ? dev.get() : nullptr;
  out.report += "simulated: device + hand model (rt/user_model.hpp), no hardware\n";
  out.device = std::move(dev);
}
}  // namespace

OpenedDevice open_device(const DeviceSelection& sel) {
  const std::string& k = sel.kind;
  if (k != "auto" && k != "touch" && k != "spacemouse" && k != "simulated")
    throw std::invalid_argument("device.kind = \"" + k +
                                "\" is not allowed; allowed: \"auto\", \"touch\", \"spacemouse\", \"simulated\"");
  OpenedDevice out;
  if (k == "simulated") {
    use_simulated(sel, out);
    return out;
  }
  std::vector<UsbDeviceInfo> usb;
  try {
    out.monitor = std::make_unique<UsbMonitor>(sel.usb);
    usb = out.monitor->enumerate(true);
    for (const UsbDeviceInfo& d : usb) out.report += "usb: found " + usb_line(d) + "\n";
    if (usb.empty()) out.report += "usb: no known haptic/input device\n";
  } catch (const std::exception& e) {
    out.report += std::string("usb: ") + e.what() + " (unplug detection unavailable)\n";
    out.monitor.reset();
  }
  const UsbDeviceInfo* touch_usb = nullptr;
  for (const UsbDeviceInfo& d : usb)
    if (d.kind == DeviceKind::kPhantomTouch) {
      touch_usb = &d;
      break;
    }
  bool ok = false;
  if (k == "touch" || (k == "auto" && touch_usb != nullptr)) ok = try_touch(sel, out, touch_usb);
  if (!ok && k == "touch") throw DeviceMissing("device.kind = \"touch\": no Touch could be started:\n" + out.report + kMissingHint);
  if (!ok && (k == "spacemouse" || k == "auto")) {
    bool have_hid = !sel.spacemouse.hidraw_path.empty();
    for (const HidDeviceInfo& h : list_hid_devices(true)) {
      out.report += "hid: found " + h.path + " " + h.model + "\n";
      have_hid = have_hid || h.kind == DeviceKind::kSpaceMouse;
    }
    if (k == "spacemouse" || have_hid) ok = try_spacemouse(sel, out);
    if (!ok && k == "spacemouse")
      throw DeviceMissing("device.kind = \"spacemouse\": no SpaceMouse could be started:\n" + out.report + kMissingHint);
  }
  if (!ok) throw DeviceMissing("device.kind = \"auto\": no haptic or input device could be started:\n" + out.report + kMissingHint);
  if (out.monitor) out.monitor->start();
  return out;
}

std::optional<DeviceCapabilities> published_capabilities(const DeviceSelection& sel) {
  if (sel.kind == "touch") return touch_default_capabilities();
  if (sel.kind == "spacemouse") return spacemouse_capabilities(sel.spacemouse);
  if (sel.kind == "simulated") return simulated_capabilities(sel.simulated);
  return std::nullopt;
}

}  // namespace haptic::drivers
