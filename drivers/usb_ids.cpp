#include "drivers/usb_ids.hpp"

namespace haptic::drivers {

namespace {
constexpr std::uint16_t kAny = 0xFFFF;
constexpr KnownIdentity kTable[] = {
    {0x2988, 0x0302, DeviceKind::kPhantomTouch, "3D Systems Touch, USB model (2988:0302; cdc_acm, /dev/ttyACM*)"},
    {0x0301, 0x2988, DeviceKind::kPhantomTouch, "3D Systems Touch, USB model (0301:2988; cdc_acm, /dev/ttyACM*)"},
    {0x2988, 0x0304, DeviceKind::kPhantomTouch, "3D Systems Touch, HID model (2988:0304; /dev/hidraw*)"},
    {0x2988, kAny, DeviceKind::kPhantomTouch, "3D Systems/SensAble device (unlisted model)"},
    {0x0403, 0xcb48, DeviceKind::kFalcon, "Novint Falcon (FTDI 0403:cb48)"},
    // 3Dconnexion under Logitech's vendor id (product ids from public device lists).
    {0x046d, 0xc603, DeviceKind::kSpaceMouse, "3Dconnexion SpaceMouse Plus XT"},
    {0x046d, 0xc605, DeviceKind::kSpaceMouse, "3Dconnexion CADman"},
    {0x046d, 0xc606, DeviceKind::kSpaceMouse, "3Dconnexion SpaceMouse Classic"},
    {0x046d, 0xc621, DeviceKind::kSpaceMouse, "3Dconnexion SpaceBall 5000"},
    {0x046d, 0xc623, DeviceKind::kSpaceMouse, "3Dconnexion SpaceTraveler"},
    {0x046d, 0xc625, DeviceKind::kSpaceMouse, "3Dconnexion SpacePilot"},
    {0x046d, 0xc626, DeviceKind::kSpaceMouse, "3Dconnexion SpaceNavigator"},
    {0x046d, 0xc627, DeviceKind::kSpaceMouse, "3Dconnexion SpaceExplorer"},
    {0x046d, 0xc628, DeviceKind::kSpaceMouse, "3Dconnexion SpaceNavigator for Notebooks"},
    {0x046d, 0xc629, DeviceKind::kSpaceMouse, "3Dconnexion SpacePilot Pro"},
    {0x046d, 0xc62b, DeviceKind::kSpaceMouse, "3Dconnexion SpaceMouse Pro"},
    {0x256f, 0xc635, DeviceKind::kSpaceMouse, "3Dconnexion SpaceMouse Compact"},
    {0x256f, kAny, DeviceKind::kSpaceMouse, "3Dconnexion device"},
};
}  // namespace

const KnownIdentity* find_identity(std::uint16_t vendor_id, std::uint16_t product_id) {
  for (const KnownIdentity& k : kTable)
    if (k.vendor_id == vendor_id && k.product_id == product_id) return &k;
  for (const KnownIdentity& k : kTable)
    if (k.vendor_id == vendor_id && k.product_id == kAny) return &k;
  return nullptr;
}

const KnownIdentity* known_identities(int* n) {
  *n = static_cast<int>(sizeof kTable / sizeof kTable[0]);
  return kTable;
}

const char* backend_name(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::kPhantomTouch: return "OpenHaptics HD library (libHD.so, dlopen) -> PhantomDevice";
    case DeviceKind::kFalcon: return "libusb-1.0 -> FalconDevice (open code from libnifalcon's public protocol description; firmware file from device.falcon_firmware_path)";
    case DeviceKind::kSpaceMouse: return "hidapi/hidraw -> SpaceMouseDevice (position input only, NO force feedback)";
    case DeviceKind::kUnknown: break;
  }
  return "none";
}

}  // namespace haptic::drivers
