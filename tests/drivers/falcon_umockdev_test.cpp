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

#include "tests/drivers/falcon_standin.hpp"

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
using haptic::testing::FalconStandIn;

// The stand-in bed plus the driver configuration the tests use.
struct FalconBed : haptic::testing::FalconBed {
  using haptic::testing::FalconBed::FalconBed;
  FalconConfig config() const {
    FalconConfig c;
    c.firmware_path = firmware_path;
    c.own_thread = false;  // the test is the servo loop: deterministic
    c.homing_timeout_s = 5.0;
    return c;
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

// device.usb_serial: the Falcon with that serial is the one opened (by its bus and address) and
// watched for unplug; a serial no Falcon has is refused naming the key and the serials found.
TEST(FalconUmockdev, TheUsbSerialChoosesTheFalconOpenedAndWatchedAndAnUnknownOneIsRefused) {
  FalconBed bed;
  DeviceSelection sel;
  sel.kind = "falcon";
  sel.falcon = bed.config();
  sel.usb_serial = "FALCON-OTHER";
  try {
    open_device(sel);
    FAIL("an unknown device.usb_serial was accepted");
  } catch (const DeviceMissing& e) {
    const std::string what = e.what();
    CHECK_TEXT(what.find("device.usb_serial = \"FALCON-OTHER\": no Falcon with that serial") != std::string::npos &&
                   what.find("found: \"FALCON-STANDIN-1\"") != std::string::npos,
               what.c_str());
  }
  sel.usb_serial = "FALCON-STANDIN-1";
  sel.falcon.index = 3;  // the serial decides, not the index
  OpenedDevice opened = open_device(sel);
  CHECK_TEXT(opened.report.find("falcon: unplug detection on 0403:cb48") != std::string::npos &&
                 opened.report.find("addr 009, serial \"FALCON-STANDIN-1\"") != std::string::npos,
             opened.report.c_str());
  CHECK(dynamic_cast<FalconDevice*>(opened.device.get()) != nullptr);
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

TEST(FalconUmockdev, OwnThreadLatchesTheUnplugAndTheNextReadIsFalse) {
  FalconBed bed;
  FalconConfig c = bed.config();
  c.own_thread = true;
  SafetyLimits lenient;  // the stand-in is slower than a Falcon; staleness is not under test here
  lenient.max_stale_reads = 100000;
  FalconDevice dev(c, lenient);
  STRCMP_EQUAL("", start_error(dev).c_str());
  DeviceSample s{};
  bool got = false;
  for (int i = 0; i < 2000 && !got; ++i) {  // bounded wait for the first sample
    got = dev.read_newest(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK(got);
  {
    std::lock_guard<std::mutex> l(bed.dev.mu);
    bed.dev.unplugged = true;
  }
  for (int i = 0; i < 2000 && dev.fault() == DeviceFault::kNone; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  CHECK(dev.fault() == DeviceFault::kUnplugged);  // latched by the servo thread's failing exchange
  CHECK_FALSE(dev.read_newest(s));                // the tick's next read
  dev.stop();
}
