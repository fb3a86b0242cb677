// The Novint Falcon driver's real libusb code path against a umockdev stand-in. We have no Falcon
// and no capture of one: the stand-in is an ioctl handler on the emulated usbdevfs node
// (umockdev/falcon_usb.umockdev) that plays the device side of the protocol as the public
// libnifalcon sources document it (falcon_protocol.hpp): it records the FTDI vendor requests,
// answers the boot loader handshake, echoes the firmware bytes, then answers every 16-byte servo
// packet with a status packet (encoders, buttons, homing bits). The status packets are encoded
// here, independently of the driver's decoder, from the documented layout. Hand-made, NOT recorded.
#include "drivers/device_factory.hpp"
#include "drivers/falcon_device.hpp"
#include "drivers/falcon_protocol.hpp"

#include <dlfcn.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <mutex>
#include <thread>
#include <chrono>
#include <string>
#include <vector>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
constexpr const char* kFalconNode = "/dev/bus/usb/001/009";

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
      last_control = nibble_value(d[13]);
      ++servo_packets;
      if (last_control & falcon::kCtlHoming) ++homing_packets;
      else ++plain_packets;
      status_packet();
    }
  }
};

FalconStandIn* g_dev = nullptr;

gboolean on_usbdevfs(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer) {
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
    if (pre == nullptr) FAIL("umockdev preload is NOT active (LD_PRELOAD=libumockdev-preload.so.0, as ctest sets): Falcon tests did not run");
    dlclose(pre);
    g_dev = &dev;
    tb = umockdev_testbed_new();
    if (with_falcon) {
      handler = umockdev_ioctl_base_new();
      g_signal_connect(handler, "handle-ioctl", G_CALLBACK(on_usbdevfs), nullptr);
      GError* err = nullptr;
      if (!umockdev_testbed_attach_ioctl(tb, kFalconNode, handler, &err)) FAIL("attach_ioctl failed");
      const std::string file = std::string(HAPTIC_UMOCKDEV_DIR) + "/falcon_usb.umockdev";
      if (!umockdev_testbed_add_from_file(tb, file.c_str(), &err)) FAIL("cannot add falcon_usb.umockdev");
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
  FalconConfig config() const {
    FalconConfig c;
    c.firmware_path = firmware_path;
    c.own_thread = false;  // the test is the servo loop: deterministic
    c.homing_timeout_s = 5.0;
    return c;
  }
  int index_of(int request, int value) {
    std::lock_guard<std::mutex> l(dev.mu);
    for (std::size_t i = 0; i < dev.controls.size(); ++i)
      if (dev.controls[i].first == request && dev.controls[i].second == value) return static_cast<int>(i);
    return -1;
  }
};

std::string start_error(FalconDevice& d) {
  try {
    d.start();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(FalconUmockdev){};

TEST(FalconUmockdev, StartLoadsTheFirmwareWithTheDocumentedSetUpThenHomes) {
  FalconBed bed;
  FalconDevice dev(bed.config());
  const std::string err = start_error(dev);
  STRCMP_EQUAL("", err.c_str());
  CHECK(dev.fault() == DeviceFault::kNone);
  {
    std::lock_guard<std::mutex> l(bed.dev.mu);
    CHECK(bed.dev.firmware == bed.firmware);  // every byte arrived, in order
    CHECK(bed.dev.homing_packets >= bed.dev.homing_packets_needed);
    CHECK_EQUAL(0, bed.dev.plain_packets);  // nothing but homing packets until homed
  }
  // FTDI set-up order: 9600 baud for the handshake, the firmware baud, then normal mode (latency 1).
  const int b9600 = bed.index_of(falcon::kFtdiBaud, falcon::kBaud9600), bfw = bed.index_of(falcon::kFtdiBaud, falcon::kBaudFirmware),
            bnorm = bed.index_of(falcon::kFtdiBaud, falcon::kBaudNormal), lat1 = bed.index_of(falcon::kFtdiLatency, 1);
  CHECK(b9600 >= 0 && bfw > b9600 && bnorm > bfw && lat1 > bfw);
  CHECK(bed.index_of(falcon::kFtdiModemCtrl, falcon::kDtrHigh) > b9600);
  // After homing: servo packets without the homing bit, blue LED.
  CHECK(dev.service());
  std::lock_guard<std::mutex> l(bed.dev.mu);
  CHECK_EQUAL(1, bed.dev.plain_packets);
  CHECK_EQUAL(falcon::kLedBlue, bed.dev.last_control);
}

TEST(FalconUmockdev, EncodersBecomeAPositionAndAForceBecomesTheMotorCommandsOnTheWire) {
  FalconBed bed;
  FalconDevice dev(bed.config());
  STRCMP_EQUAL("", start_error(dev).c_str());
  // Encoders of the position (0.01, -0.02, 0.12) m (libnifalcon frame) through the documented
  // encoder scale: the driver's forward kinematics must find it again (to the encoder resolution).
  const Eigen::Vector3d p_true(0.01, -0.02, 0.12);
  Eigen::Vector3d theta;
  CHECK(falcon::inverse_kinematics(p_true, theta));
  const double rad_per_count = falcon::encoder_to_theta(1) - falcon::encoder_to_theta(0);
  {
    std::lock_guard<std::mutex> l(bed.dev.mu);
    for (int i = 0; i < 3; ++i)
      bed.dev.encoder[i] = static_cast<std::int16_t>(std::lround((theta[i] - falcon::encoder_to_theta(0)) / rad_per_count));
    bed.dev.buttons = 0x5;
  }
  DeviceSample s{};
  for (int k = 0; k < 3; ++k) {  // a reply arrives with the exchange that asked for it
    CHECK(dev.service());
    dev.read_newest(s);
  }
  CHECK(dev.read_newest(s));
  DOUBLES_EQUAL(p_true.x(), s.position_m[0], 2e-4);
  DOUBLES_EQUAL(p_true.y(), s.position_m[1], 2e-4);
  DOUBLES_EQUAL(p_true.z() - 0.11, s.position_m[2], 2e-4);  // device-frame origin at z = 0.11 m
  CHECK_EQUAL(0x5u, s.buttons);
  // A 1 N force along z: the motor commands the stand-in decodes are force_to_motor's at that position.
  const double f[3] = {0.0, 0.0, 1.0};
  dev.command_force(f);
  CHECK(dev.service());
  std::int16_t expect[3];
  const Eigen::Vector3d p_seen(s.position_m[0], s.position_m[1], s.position_m[2] + 0.11);
  CHECK(falcon::force_to_motor(p_seen, Eigen::Vector3d(0, 0, 1), expect));
  std::lock_guard<std::mutex> l(bed.dev.mu);
  for (int i = 0; i < 3; ++i) {
    CHECK(expect[i] != 0);
    CHECK(std::abs(bed.dev.last_motor[i] - expect[i]) <= 2);
  }
}

TEST(FalconUmockdev, UnplugIsTheSafeStateWithinOneTick) {
  FalconBed bed;
  FalconDevice dev(bed.config());
  STRCMP_EQUAL("", start_error(dev).c_str());
  DeviceSample s{};
  CHECK(dev.service());
  CHECK(dev.service());
  CHECK(dev.read_newest(s));  // tick k: fine
  {
    std::lock_guard<std::mutex> l(bed.dev.mu);
    bed.dev.unplugged = true;  // the USB node now answers ENODEV, as usbfs does after removal
  }
  CHECK_FALSE(dev.service());  // the backend's exchange of this tick fails
  CHECK(dev.fault() == DeviceFault::kUnplugged);
  CHECK_FALSE(dev.read_newest(s));  // tick k+1: the station knows
  const double f[3] = {1.0, 0.0, 0.0};
  dev.command_force(f);
  CHECK_FALSE(dev.service());  // nothing more is sent
  dev.stop();
}

TEST(FalconUmockdev, AFirmwareEchoMismatchFailsTheStartAndSaysWhere) {
  FalconBed bed;
  bed.dev.corrupt_echo_at = 300;
  FalconDevice dev(bed.config());
  const std::string err = start_error(dev);
  CHECK_TEXT(err.find("firmware echo differs at byte 300") != std::string::npos, err.c_str());
  CHECK(dev.fault() != DeviceFault::kNone);
}

TEST(FalconUmockdev, NoFirmwareFileNamesTheKey) {
  FalconBed bed;
  FalconConfig c = bed.config();
  c.firmware_path.clear();
  FalconDevice dev(c);
  const std::string err = start_error(dev);
  CHECK_TEXT(err.find("device.falcon_firmware_path") != std::string::npos, err.c_str());
}

TEST(FalconUmockdev, HomingTimeoutSaysWhatToDo) {
  FalconBed bed;
  bed.dev.homing_packets_needed = 1 << 30;
  FalconConfig c = bed.config();
  c.homing_timeout_s = 0.2;
  FalconDevice dev(c);
  const std::string err = start_error(dev);
  CHECK_TEXT(err.find("not homed") != std::string::npos && err.find("push it straight in") != std::string::npos, err.c_str());
}

TEST(FalconUmockdev, NoFalconOnTheBusIsAClearError) {
  FalconBed bed(false);
  FalconDevice dev(bed.config());
  const std::string err = start_error(dev);
  CHECK_TEXT(err.find("no Novint Falcon (USB 0403:cb48)") != std::string::npos, err.c_str());
}

TEST(FalconUmockdev, AutoPicksAPluggedFalconWhoseOwnThreadServes) {
  FalconBed bed;
  DeviceSelection sel;
  sel.kind = "auto";
  sel.falcon = bed.config();
  sel.falcon.own_thread = true;
  OpenedDevice opened = open_device(sel);
  CHECK_TEXT(opened.report.find("falcon: started") != std::string::npos, opened.report.c_str());
  auto* falcon = dynamic_cast<FalconDevice*>(opened.device.get());
  CHECK(falcon != nullptr);
  // Bounded wait (not a timing assertion): the 1 kHz thread delivers samples.
  DeviceSample s{};
  bool got = false;
  for (int i = 0; i < 2000 && !got; ++i) {
    got = opened.device->read_newest(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(got);
  CHECK(falcon->servo_frames() > 0);
}

TEST(FalconUmockdev, KindFalconWithoutOneIsDeviceMissingSayingWhy) {
  FalconBed bed(false);
  DeviceSelection sel;
  sel.kind = "falcon";
  sel.falcon = bed.config();
  try {
    open_device(sel);
    FAIL("open_device should throw DeviceMissing");
  } catch (const DeviceMissing& e) {
    const std::string what = e.what();
    CHECK_TEXT(what.find("device.kind = \"falcon\": no Falcon could be started") != std::string::npos, what.c_str());
    CHECK_TEXT(what.find("no Novint Falcon (USB 0403:cb48)") != std::string::npos, what.c_str());
  }
}
