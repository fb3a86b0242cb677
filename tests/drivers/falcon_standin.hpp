#pragma once
// The Falcon stand-in for umockdev (hand-made, NOT a recording; we have no Falcon): an ioctl handler
// on the emulated usbdevfs node of umockdev/falcon_usb.umockdev that plays the device side of the
// protocol as the public libnifalcon sources document it (drivers/falcon_protocol.hpp): it records
// the FTDI vendor requests, answers the boot loader handshake, echoes the firmware bytes, then
// answers every 16-byte servo packet with a status packet (encoders, buttons, homing bits). The
// status packets are encoded here, independently of the driver's decoder, from the documented
// layout. Used by test_drivers_umockdev and by the end-to-end Falcon station session.
// Needs libumockdev-preload in the process (LD_PRELOAD) and HAPTIC_UMOCKDEV_DIR.
#include "drivers/falcon_protocol.hpp"

#include <dlfcn.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace haptic::testing {

namespace falcon = haptic::drivers::falcon;

inline constexpr const char* kFalconNode = "/dev/bus/usb/001/009";

// The device side. All fields guarded by mu (the handler runs on umockdev's thread).
struct FalconStandIn {
  std::mutex mu;
  std::vector<std::pair<int, int>> controls;  // (bRequest, wValue) of every FTDI vendor request
  int baud = -1;
  bool firmware_mode_ok = false;              // 'A' seen at the firmware baud rate
  std::vector<unsigned char> firmware;        // bytes received while loading
  long corrupt_echo_at = -1;                  // flip this echoed byte (load failure test)
  int homing_packets_needed = 20;             // packets with the homing bit before the axes report homed
  int homing_packets = 0, servo_packets = 0, plain_packets = 0;
  std::int16_t encoder[3] = {0, 0, 0};
  std::uint8_t buttons = 0;
  std::int16_t last_motor[3] = {0, 0, 0};
  int last_control = -1;
  int max_abs_motor = 0;  // largest |motor command| seen in any servo packet
  bool unplugged = false;
  std::deque<unsigned char> to_host;

  struct Done {
    UMockdevIoctlData* urb;
    int actual;
    std::vector<unsigned char> in_data;
  };
  std::deque<Done> done;

  static int nibble_value(unsigned char c) { return c - 0x41; }
  void status_packet() {
    const bool homed = homing_packets >= homing_packets_needed;
    unsigned char p[16];
    p[0] = '<';
    for (int m = 0; m < 3; ++m)
      for (int n = 0; n < 4; ++n) p[1 + 4 * m + n] = static_cast<unsigned char>(0x41 + ((static_cast<std::uint16_t>(encoder[m]) >> (4 * n)) & 0xF));
    p[13] = static_cast<unsigned char>(0x41 + ((homed ? 0x70 : 0) | (buttons & 0x0F)));
    p[14] = 0x41;
    p[15] = '>';
    to_host.insert(to_host.end(), p, p + 16);
  }
  void host_wrote(const unsigned char* d, int n) {
    if (baud == falcon::kBaud9600 && n == 3 && d[0] == 0x0a && d[1] == 0x43 && d[2] == 0x0d) {
      for (unsigned char c : {0x0a, 0x44, 0x2c, 0x0d}) to_host.push_back(c);
    } else if (baud == falcon::kBaudFirmware && !firmware_mode_ok && n == 1 && d[0] == 'A') {
      firmware_mode_ok = true;
      to_host.push_back('A');
    } else if (baud == falcon::kBaudFirmware && firmware_mode_ok) {
      for (int i = 0; i < n; ++i) {
        const bool flip = static_cast<long>(firmware.size()) == corrupt_echo_at;
        firmware.push_back(d[i]);
        to_host.push_back(static_cast<unsigned char>(flip ? d[i] ^ 0xFF : d[i]));
      }
    } else if (baud == falcon::kBaudNormal && n == 16 && d[0] == '<' && d[15] == '>') {
      for (int m = 0; m < 3; ++m) {
        std::uint16_t v = 0;
        for (int k = 0; k < 4; ++k) v = static_cast<std::uint16_t>(v | (nibble_value(d[1 + 4 * m + k]) << (4 * k)));
        last_motor[m] = static_cast<std::int16_t>(v);
      }
      for (int m = 0; m < 3; ++m) max_abs_motor = std::max(max_abs_motor, std::abs(static_cast<int>(last_motor[m])));
      last_control = nibble_value(d[13]);
      ++servo_packets;
      if (last_control & falcon::kCtlHoming) ++homing_packets;
      else ++plain_packets;
      status_packet();
    }
  }
};

inline FalconStandIn* g_dev = nullptr;

inline gboolean on_usbdevfs(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer) {
  FalconStandIn& s = *g_dev;
  std::lock_guard<std::mutex> lock(s.mu);
  const gulong req = umockdev_ioctl_client_get_request(client);
  UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
  switch (req) {
    case USBDEVFS_GET_CAPABILITIES: {
      UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
      *reinterpret_cast<guint32*>(d->data) = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM;
      g_object_unref(d);
      umockdev_ioctl_client_complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_GETDRIVER: umockdev_ioctl_client_complete(client, -1, ENODATA); return TRUE;  // no kernel driver bound
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
    case USBDEVFS_DISCONNECT_CLAIM:
    case USBDEVFS_CLEAR_HALT: umockdev_ioctl_client_complete(client, s.unplugged ? -1 : 0, s.unplugged ? ENODEV : 0); return TRUE;
    case USBDEVFS_SUBMITURB: {
      if (s.unplugged) {
        umockdev_ioctl_client_complete(client, -1, ENODEV);
        return TRUE;
      }
      UMockdevIoctlData* urb_data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
      auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
      UMockdevIoctlData* buf = umockdev_ioctl_data_resolve(urb_data, offsetof(usbdevfs_urb, buffer), static_cast<gsize>(urb->buffer_length), nullptr);
      FalconStandIn::Done d{urb_data, 0, {}};
      if (urb->type == USBDEVFS_URB_TYPE_CONTROL) {
        const unsigned char* setup = buf->data;
        if (setup[0] == falcon::kFtdiRequestType) {
          const int value = setup[2] | (setup[3] << 8);
          s.controls.emplace_back(setup[1], value);
          if (setup[1] == falcon::kFtdiBaud) s.baud = value;
          if (setup[1] == falcon::kFtdiBaud && value == falcon::kBaud9600) {  // a new start: boot loader again
            s.firmware_mode_ok = false;
            s.firmware.clear();
            s.homing_packets = s.plain_packets = 0;
          }
        }
      } else if (urb->endpoint == falcon::kEndpointOut) {
        s.host_wrote(buf->data, urb->buffer_length);
        d.actual = urb->buffer_length;
      } else {  // bulk IN: the FTDI's two modem-status bytes, then whatever is pending
        d.in_data = {0x31, 0x60};
        while (static_cast<int>(d.in_data.size()) < urb->buffer_length && !s.to_host.empty()) {
          d.in_data.push_back(s.to_host.front());
          s.to_host.pop_front();
        }
        d.actual = static_cast<int>(d.in_data.size());
      }
      g_object_unref(buf);
      s.done.push_back(std::move(d));
      umockdev_ioctl_client_complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY: {
      if (s.done.empty()) {
        umockdev_ioctl_client_complete(client, -1, s.unplugged ? ENODEV : EAGAIN);
        return TRUE;
      }
      FalconStandIn::Done d = std::move(s.done.front());
      s.done.pop_front();
      auto* urb = reinterpret_cast<usbdevfs_urb*>(d.urb->data);
      urb->status = 0;
      urb->actual_length = d.actual;
      if (!d.in_data.empty()) {
        UMockdevIoctlData* buf = umockdev_ioctl_data_resolve(d.urb, offsetof(usbdevfs_urb, buffer), static_cast<gsize>(urb->buffer_length), nullptr);
        umockdev_ioctl_data_update(buf, 0, d.in_data.data(), static_cast<gint>(d.in_data.size()));
        g_object_unref(buf);
      }
      UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), nullptr);
      umockdev_ioctl_data_set_ptr(ptr, 0, d.urb);
      g_object_unref(ptr);
      g_object_unref(d.urb);
      umockdev_ioctl_client_complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_DISCARDURB: umockdev_ioctl_client_complete(client, -1, EINVAL); return TRUE;  // every URB completes at once
    default: return FALSE;
  }
}

// A testbed with the Falcon stand-in attached (or, with_falcon = false, an empty bus).
struct FalconBed {
  UMockdevTestbed* tb = nullptr;
  UMockdevIoctlBase* handler = nullptr;
  FalconStandIn dev;
  std::string firmware_path;
  std::vector<unsigned char> firmware;

  explicit FalconBed(bool with_falcon = true) {
    void* pre = dlopen("libumockdev-preload.so.0", RTLD_NOW | RTLD_NOLOAD);
    if (pre == nullptr)
      throw std::runtime_error("umockdev preload is NOT active (LD_PRELOAD=libumockdev-preload.so.0, as ctest sets): Falcon tests did not run");
    dlclose(pre);
    g_dev = &dev;
    tb = umockdev_testbed_new();
    if (with_falcon) {
      handler = umockdev_ioctl_base_new();
      g_signal_connect(handler, "handle-ioctl", G_CALLBACK(on_usbdevfs), nullptr);
      GError* err = nullptr;
      if (!umockdev_testbed_attach_ioctl(tb, kFalconNode, handler, &err)) throw std::runtime_error("umockdev attach_ioctl failed");
      const std::string file = std::string(HAPTIC_UMOCKDEV_DIR) + "/falcon_usb.umockdev";
      if (!umockdev_testbed_add_from_file(tb, file.c_str(), &err)) throw std::runtime_error("cannot add " + file);
    }
    // A made-up "firmware" (NOT Novint's): 1000 bytes, so the load spans 17 chunks of <= 62.
    for (int i = 0; i < 1000; ++i) firmware.push_back(static_cast<unsigned char>((i * 37 + 11) & 0xFF));
    firmware_path = std::string(umockdev_testbed_get_root_dir(tb)) + "/falcon-standin-firmware.bin";
    std::ofstream(firmware_path, std::ios::binary).write(reinterpret_cast<const char*>(firmware.data()), static_cast<std::streamsize>(firmware.size()));
  }
  ~FalconBed() {
    if (handler != nullptr) {
      umockdev_testbed_detach_ioctl(tb, kFalconNode, nullptr);
      g_object_unref(handler);
    }
    g_object_unref(tb);
    g_dev = nullptr;
  }
  int index_of(int request, int value) {
    std::lock_guard<std::mutex> l(dev.mu);
    for (std::size_t i = 0; i < dev.controls.size(); ++i)
      if (dev.controls[i].first == request && dev.controls[i].second == value) return static_cast<int>(i);
    return -1;
  }
};

}  // namespace haptic::testing
