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

// Starts a force-feedback device (Touch or Falcon); how(dev) says how it runs once started. On
// success it is watched for unplug by its USB identity.
template <class Dev, class How>
bool try_haptic(std::unique_ptr<Dev> dev, const char* name, How how, OpenedDevice& out, const UsbDeviceInfo* usb) {
  try {
    dev->start();
  } catch (const std::exception& e) {
    out.report += std::string(name) + ": cannot start: " + e.what() + "\n";
    return false;
  }
  out.report += std::string(name) + ": started " + how(*dev) + "\n";
  if (usb != nullptr && out.monitor) {
    out.monitor->watch(*usb, dev.get());
    out.report += std::string(name) + ": unplug detection on " + usb_line(*usb) + "\n";
  }
  out.device = std::move(dev);
  return true;
}

// This station's USB device of `kind` (see the header: usb_serial, else the index-th, else the only
// one); nullptr when none is plugged in. Throws DeviceMissing when usb_serial matches none of them
// or two are plugged in without usb_serial.
const UsbDeviceInfo* pick_usb(const std::vector<UsbDeviceInfo>& usb, DeviceKind kind, const DeviceSelection& sel, const std::string& what,
                              int index, const std::string& report) {
  std::vector<const UsbDeviceInfo*> mine;
  std::string serials;
  for (const UsbDeviceInfo& d : usb)
    if (d.kind == kind) {
      mine.push_back(&d);
      serials += (serials.empty() ? "\"" : ", \"") + d.serial + "\"";
    }
  if (!sel.usb_serial.empty()) {
    for (const UsbDeviceInfo* d : mine)
      if (d->serial == sel.usb_serial) return d;
    if (sel.kind == "auto") return nullptr;  // open_device refuses when no kind has it
    throw DeviceMissing("device.usb_serial = \"" + sel.usb_serial + "\": no " + what + " with that serial is plugged in (found: " +
                        (serials.empty() ? std::string("none") : serials) + "):\n" + report + kMissingHint);
  }
  if (index < 0 && mine.size() > 1)
    throw DeviceMissing(std::to_string(mine.size()) + " " + what + " devices are plugged in (serials " + serials +
                        "): say which is this station's with device.usb_serial" +
                        (kind == DeviceKind::kPhantomTouch ? " (and device.hd_device_name, its vendor configuration name)" : "") + ":\n" + report +
                        kMissingHint);
  const std::size_t i = index < 0 ? 0 : static_cast<std::size_t>(index);
  return i < mine.size() ? mine[i] : nullptr;
}

bool try_touch(const DeviceSelection& sel, OpenedDevice& out, const UsbDeviceInfo* usb) {
  return try_haptic(std::make_unique<PhantomDevice>(sel.touch, sel.safety), "touch",
                    [](const PhantomDevice& d) { return "through " + d.library_path(); }, out, usb);
}

bool try_falcon(const DeviceSelection& sel, OpenedDevice& out, const UsbDeviceInfo* usb) {
  FalconConfig c = sel.falcon;
  if (usb != nullptr) {  // open exactly the device that is watched for unplug
    c.usb_bus = usb->bus;
    c.usb_address = usb->address;
  }
  return try_haptic(std::make_unique<FalconDevice>(c, sel.safety), "falcon",
                    [](const FalconDevice&) { return std::string("(firmware loaded, homed; servo through libusb)"); }, out, usb);
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

std::string auto_device_absence(const DeviceSelection& sel) {
  if (sel.kind != "auto" || !sel.spacemouse.hidraw_path.empty()) return "";
  std::string report;
  try {
    UsbMonitor monitor(sel.usb);
    for (const UsbDeviceInfo& d : monitor.enumerate(true))
      if (d.kind == DeviceKind::kPhantomTouch || d.kind == DeviceKind::kFalcon) return "";
    report += "usb: no Touch or Falcon\n";
  } catch (const std::exception& e) {
    report += std::string("usb: ") + e.what() + "\n";  // open_device then tries no USB device either
  }
  for (const HidDeviceInfo& h : list_hid_devices(true))
    if (h.kind == DeviceKind::kSpaceMouse) return "";
  return report + "hid: no SpaceMouse\n";
}

OpenedDevice open_device(const DeviceSelection& sel) {
  const std::string& k = sel.kind;
  if (k != "auto" && k != "touch" && k != "falcon" && k != "spacemouse" && k != "simulated")
    throw std::invalid_argument("device.kind = \"" + k +
                                "\" is not allowed; allowed: \"auto\", \"touch\", \"falcon\", \"spacemouse\", \"simulated\"");
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
  const UsbDeviceInfo* touch_usb = k == "touch" || k == "auto" ? pick_usb(usb, DeviceKind::kPhantomTouch, sel, "Touch", -1, out.report) : nullptr;
  const UsbDeviceInfo* falcon_usb =
      k == "falcon" || k == "auto" ? pick_usb(usb, DeviceKind::kFalcon, sel, "Falcon", sel.falcon.index, out.report) : nullptr;
  if (k == "auto" && !sel.usb_serial.empty() && touch_usb == nullptr && falcon_usb == nullptr)
    throw DeviceMissing("device.usb_serial = \"" + sel.usb_serial + "\": no Touch or Falcon with that serial is plugged in:\n" + out.report + kMissingHint);
  bool ok = false;
  if (k == "touch" || (k == "auto" && touch_usb != nullptr)) ok = try_touch(sel, out, touch_usb);
  if (!ok && k == "touch") throw DeviceMissing("device.kind = \"touch\": no Touch could be started:\n" + out.report + kMissingHint);
  if (!ok && (k == "falcon" || (k == "auto" && falcon_usb != nullptr))) ok = try_falcon(sel, out, falcon_usb);
  if (!ok && k == "falcon") throw DeviceMissing("device.kind = \"falcon\": no Falcon could be started:\n" + out.report + kMissingHint);
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
  if (sel.kind == "falcon") return falcon_capabilities();
  if (sel.kind == "spacemouse") return spacemouse_capabilities(sel.spacemouse);
  if (sel.kind == "simulated") return simulated_capabilities(sel.simulated);
  return std::nullopt;
}

}  // namespace haptic::drivers
