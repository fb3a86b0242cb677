#include "drivers/tty_devices.hpp"

#include <filesystem>
#include <fstream>

namespace haptic::drivers {

namespace {
std::string read_attr(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::string s;
  std::getline(f, s);
  return s;
}
}  // namespace

std::vector<TtyDeviceInfo> list_acm_devices(bool known_only) {
  namespace fs = std::filesystem;
  std::vector<TtyDeviceInfo> out;
  std::error_code ec;
  // /sys/bus/usb/devices/<port>:<config>.<interface>/tty/ttyACM*: the interface cdc_acm bound;
  // its parent directory is the USB device with idVendor/idProduct/serial.
  for (const auto& e : fs::directory_iterator("/sys/bus/usb/devices", ec)) {
    if (e.path().filename().string().find(':') == std::string::npos) continue;  // interfaces only
    const fs::path iface = fs::canonical(e.path(), ec);
    if (ec) continue;
    std::error_code ec2;
    for (const auto& t : fs::directory_iterator(iface / "tty", ec2)) {
      const std::string name = t.path().filename().string();
      if (name.rfind("ttyACM", 0) != 0) continue;
      const fs::path usb = iface.parent_path();
      TtyDeviceInfo d;
      d.node = "/dev/" + name;
      try {
        d.vendor_id = static_cast<std::uint16_t>(std::stoul(read_attr(usb / "idVendor"), nullptr, 16));
        d.product_id = static_cast<std::uint16_t>(std::stoul(read_attr(usb / "idProduct"), nullptr, 16));
      } catch (const std::exception&) {
        continue;  // not a USB device directory
      }
      d.serial = read_attr(usb / "serial");
      std::error_code ec3;
      const fs::path drv = fs::read_symlink(iface / "driver", ec3);
      d.driver = ec3 ? std::string() : drv.filename().string();
      if (const KnownIdentity* k = find_identity(d.vendor_id, d.product_id)) {
        d.kind = k->kind;
        d.model = k->model;
      }
      if (!known_only || d.kind != DeviceKind::kUnknown) out.push_back(d);
    }
  }
  return out;
}

}  // namespace haptic::drivers
