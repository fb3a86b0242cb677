#pragma once
// Picks, opens and starts the station's device from the [device] config table, and explains
// every choice (what was found, why a backend could not be used). Non-RT, start-up only.
//   kind = "auto"       : first Touch whose HD library starts, else first SpaceMouse; NEVER a
//                         simulated user: nothing found is a DeviceMissing error
//   kind = "touch"      : PhantomDevice (OpenHaptics HD library) or DeviceMissing saying what is missing
//   kind = "spacemouse" : SpaceMouseDevice (position input only, NO force feedback)
//   kind = "falcon"     : FalconDevice (libusb; needs the firmware file, device.falcon_firmware_path);
//                         "auto" takes a Falcon found on USB when no Touch started
//   kind = "simulated"  : SimulatedDevice (owner-stepped: the station must call service()); a
//                         simulated user is only ever what the configuration asked for
// A started Touch, Falcon or SpaceMouse that has a USB identity is watched by a UsbMonitor (hotplug or
// re-enumeration), so unplugging it puts the device in the safe state.
// Two devices on one PC: usb_serial (device.usb_serial) names this station's device by the serial
// `haptic-devices` lists; the Falcon opened and the device watched for unplug are then that one.
// Two Touches (or Falcons) plugged in without usb_serial are refused (DeviceMissing naming the key
// and the serials found): the unplug watch must never be on the neighbour's device. A Touch's servo
// goes through the HD library, which picks the device by its vendor configuration name
// (device.hd_device_name, Touch_Setup): name the same device in both keys.
#include "drivers/device.hpp"
#include "drivers/falcon_device.hpp"
#include "drivers/phantom_device.hpp"
#include "drivers/simulated_device.hpp"
#include "drivers/spacemouse.hpp"
#include "drivers/usb_monitor.hpp"

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace haptic::drivers {

struct DeviceSelection {
  std::string kind = "auto";  // drivers key device.kind: "auto" | "touch" | "falcon" | "spacemouse" | "simulated"
  PhantomConfig touch{};
  FalconConfig falcon{};
  SpaceMouseConfig spacemouse{};
  SimulatedDeviceConfig simulated{};
  SafetyLimits safety{};
  UsbMonitorConfig usb{};
  std::string usb_serial;  // device.usb_serial: "" = the only device of the kind (the falcon_index-th Falcon)
};

struct OpenedDevice {
  std::unique_ptr<UsbMonitor> monitor;   // declared first: destroyed after the device stops
  std::unique_ptr<HapticDevice> device;  // started
  SimulatedDevice* simulated = nullptr;  // non-null when the owner must call service() per tick
  std::string report;                    // one line per step: what was found and why it was (not) used
  OpenedDevice() = default;
  OpenedDevice(OpenedDevice&&) = default;
  OpenedDevice& operator=(OpenedDevice&&) = default;
  ~OpenedDevice();
};

// No requested device could be started (what() says what was found, why each backend failed,
// and which key fixes it). The station exits with its own code for this (firmware/station/phase.hpp).
class DeviceMissing : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws std::invalid_argument for a bad kind (naming device.kind and the allowed values) and
// DeviceMissing when no real device of the requested kind starts ("auto" included: a station
// never falls back to a simulated user on its own).
OpenedDevice open_device(const DeviceSelection& selection);
// kind "auto" only: why open_device would throw DeviceMissing before trying any device (no Touch or
// Falcon on USB, no SpaceMouse hidraw node), for --check-config; "" when it would try one. Non-RT.
std::string auto_device_absence(const DeviceSelection& selection);

// The capabilities a device of `kind` ("touch", "spacemouse", "simulated") publishes before it is
// opened (the vendor's figures, or the simulated model's), for checks at planning time; nullopt for
// "auto" (unknown until open_device). Non-RT.
std::optional<DeviceCapabilities> published_capabilities(const DeviceSelection& selection);

}  // namespace haptic::drivers
