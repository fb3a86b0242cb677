#pragma once
// The USB identities we recognise and which backend drives each. Sources (public, see README):
//  - Phantom/Touch: the USB Touch as 2988:0302 or 0301:2988, bound to the kernel's cdc_acm
//    driver (a /dev/ttyACM* node, group dialout by default); the current Touch HID model as
//    2988:0304 (a /dev/hidraw* node), as reported publicly; any other product under
//    vendor 0x2988 is reported as "unlisted model".
//  - 3Dconnexion SpaceMouse family: vendor 0x256f (3Dconnexion) any product; vendor 0x046d
//    (Logitech, older 3Dconnexion devices) only the product ids listed in usb_ids.cpp.
//  - Novint Falcon: 0403:cb48 (its FTDI FT232 USB-serial chip with Novint's product id, as the
//    public libnifalcon sources give it).
#include <cstdint>

namespace haptic::drivers {

enum class DeviceKind : std::uint8_t {
  kUnknown = 0,
  kPhantomTouch,  // servo through the OpenHaptics HD library (PhantomDevice)
  kSpaceMouse,    // position input through hidapi, no force feedback (SpaceMouseDevice)
  kFalcon,        // servo through libusb, our own driver (FalconDevice)
};

struct KnownIdentity {
  std::uint16_t vendor_id;
  std::uint16_t product_id;  // 0xFFFF = any product of this vendor
  DeviceKind kind;
  const char* model;
};

// Identity lookup; nullptr when not one of ours. RT-safe (static table).
const KnownIdentity* find_identity(std::uint16_t vendor_id, std::uint16_t product_id);
// All identities (for udev rules); count in *n.
const KnownIdentity* known_identities(int* n);
// "OpenHaptics HD library (libHD.so)", "hidapi (position input only, no force feedback)", ...
const char* backend_name(DeviceKind kind);

}  // namespace haptic::drivers
