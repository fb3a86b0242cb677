// The libusb and hidraw paths against umockdev stand-ins (hand-written device descriptions in
// tests/drivers/umockdev/). umockdev redirects /sys and /dev through its preload library, which
// must be in the process: CTest runs this binary with LD_PRELOAD=libumockdev-preload.so.0.
// Without it every test here FAILS with a message saying so (never a silent pass); the CMake
// file registers a separate "skipped" marker when umockdev is not installed at all.
#include "drivers/device_factory.hpp"
#include "drivers/tty_devices.hpp"
#include "drivers/phantom_device.hpp"
#include "drivers/spacemouse.hpp"
#include "drivers/usb_monitor.hpp"

#include <dlfcn.h>
#include <linux/hidraw.h>
#include <sys/ioctl.h>
#include <umockdev.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
const char* const kTouchSyspath = "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-3";

bool preload_active() {
  void* h = dlopen("libumockdev-preload.so.0", RTLD_NOW | RTLD_NOLOAD);
  if (h != nullptr) dlclose(h);
  return h != nullptr;
}

struct Testbed {
  UMockdevTestbed* tb = nullptr;
  Testbed() {
    if (!preload_active())
      FAIL("umockdev is NOT active in this process: run with LD_PRELOAD=libumockdev-preload.so.0 "
           "(ctest does). The libusb/hidraw stand-in tests did not run.");
    tb = umockdev_testbed_new();
  }
  ~Testbed() {
    if (tb != nullptr) g_object_unref(tb);
  }
  void add(const char* file) {
    GError* err = nullptr;
    const std::string path = std::string(HAPTIC_UMOCKDEV_DIR) + "/" + file;
    if (!umockdev_testbed_add_from_file(tb, path.c_str(), &err)) {
      const std::string msg = "umockdev_testbed_add_from_file(" + path + "): " + (err ? err->message : "?");
      if (err) g_error_free(err);
      FAIL(msg.c_str());
    }
  }
};

// Bounded wait for an asynchronous event (not a timing assertion): up to 5 s.
template <class Pred>
bool eventually(Pred pred) {
  for (int i = 0; i < 5000; ++i) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return pred();
}

struct FakeHd {
  void* h = nullptr;
  int (*run_frames)(int) = nullptr;
  void (*last_force)(double*) = nullptr;
  FakeHd() {
    h = dlopen(HAPTIC_FAKE_HD_PATH, RTLD_NOW | RTLD_LOCAL);
    if (h == nullptr) FAIL(dlerror());
    reinterpret_cast<void (*)()>(dlsym(h, "fakehd_reset"))();
    run_frames = reinterpret_cast<int (*)(int)>(dlsym(h, "fakehd_run_frames"));
    last_force = reinterpret_cast<void (*)(double*)>(dlsym(h, "fakehd_last_force"));
  }
  ~FakeHd() {
    reinterpret_cast<void (*)()>(dlsym(h, "fakehd_reset"))();
    dlclose(h);
  }
};

// Answers hidapi's HIDIOCGRDESCSIZE probe on an emulated hidraw node (umockdev has no built-in
// hidraw ioctls); everything else gets ENOTTY, as from a real node that does not support it.
gboolean on_hidraw_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer) {
  if (umockdev_ioctl_client_get_request(client) == HIDIOCGRDESCSIZE) {
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    GError* err = nullptr;
    UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(int), &err);
    if (d == nullptr) {
      if (err) g_error_free(err);
      umockdev_ioctl_client_complete(client, -1, EFAULT);
      return TRUE;
    }
    *reinterpret_cast<int*>(d->data) = 62;
    umockdev_ioctl_client_complete(client, 0, 0);
    return TRUE;
  }
  umockdev_ioctl_client_complete(client, -1, ENOTTY);
  return TRUE;
}

void run_unplug_scenario(bool prefer_hotplug) {
  Testbed bed;
  bed.add("touch_usb.umockdev");
  FakeHd fake;
  UsbMonitorConfig mc;
  mc.prefer_hotplug = prefer_hotplug;
  mc.rescan_period_s = 0.02;
  UsbMonitor monitor(mc);
  auto known = monitor.enumerate(true);
  LONGS_EQUAL(1, known.size());

  PhantomConfig pc;
  pc.hd_library_path = HAPTIC_FAKE_HD_PATH;
  PhantomDevice touch(pc);
  touch.start();
  monitor.watch(known[0], &touch);
  monitor.start();
  CHECK_EQUAL(prefer_hotplug, monitor.using_hotplug());

  // Station ticks with a force on the device.
  const double f[3] = {0.4, 0.0, 0.0};
  DeviceSample s{};
  double out[3];
  fake.run_frames(1);
  for (int k = 0; k < 3; ++k) {
    CHECK(touch.read_newest(s));
    touch.command_force(f);
    fake.run_frames(1);
  }
  fake.last_force(out);
  DOUBLES_EQUAL(0.4, out[0], 0.0);

  // Unplug: kernel "remove" uevent, then the device disappears from /sys and /dev.
  umockdev_testbed_uevent(bed.tb, kTouchSyspath, "remove");
  umockdev_testbed_remove_device(bed.tb, kTouchSyspath);
  CHECK_TEXT(eventually([&] { return monitor.removals() >= 1; }),
             prefer_hotplug ? "libusb hotplug never reported the removal"
                            : "re-enumeration never noticed the removal");

  // The first tick after the monitor saw it: safe state in that tick.
  CHECK_FALSE(touch.read_newest(s));
  CHECK(touch.fault() == DeviceFault::kUnplugged);
  touch.command_force(f);
  fake.run_frames(1);  // the servo frame of that tick
  fake.last_force(out);
  DOUBLES_EQUAL(0.0, out[0], 0.0);
  monitor.stop();
  LONGS_EQUAL(0, monitor.enumerate(true).size());
}
}  // namespace

TEST_GROUP(UmockdevUsb) {};

TEST(UmockdevUsb, EnumerationFindsTheTouchWithItsSerialAndSkipsOtherDevices) {
  Testbed bed;
  bed.add("touch_usb.umockdev");
  UsbMonitor monitor;
  auto all = monitor.enumerate(false);
  LONGS_EQUAL(2, all.size());
  auto known = monitor.enumerate(true);
  LONGS_EQUAL(1, known.size());
  LONGS_EQUAL(0x2988, known[0].vendor_id);
  LONGS_EQUAL(0x0302, known[0].product_id);
  LONGS_EQUAL(1, known[0].bus);
  LONGS_EQUAL(5, known[0].address);
  STRCMP_EQUAL("1-3", known[0].port_path.c_str());
  STRCMP_EQUAL("TOUCH-0001", known[0].serial.c_str());
  STRCMP_EQUAL("/dev/bus/usb/001/005", known[0].devnode.c_str());
  CHECK(known[0].kind == DeviceKind::kPhantomTouch);
}

TEST(UmockdevUsb, HotplugRemovalPutsTheTouchInTheSafeStateWithinOneTick) { run_unplug_scenario(true); }

TEST(UmockdevUsb, ReEnumerationFallbackAlsoDetectsTheRemoval) { run_unplug_scenario(false); }

TEST(UmockdevUsb, AutoSelectionPicksThePluggedTouchAndWatchesItForUnplug) {
  Testbed bed;
  bed.add("touch_usb.umockdev");
  FakeHd fake;
  DeviceSelection sel;  // kind "auto"
  sel.touch.hd_library_path = HAPTIC_FAKE_HD_PATH;
  OpenedDevice d = open_device(sel);
  CHECK(dynamic_cast<PhantomDevice*>(d.device.get()) != nullptr);
  CHECK_TEXT(d.report.find("serial \"TOUCH-0001\"") != std::string::npos, d.report.c_str());
  CHECK_TEXT(d.report.find("touch: unplug detection on 2988:0302") != std::string::npos, d.report.c_str());
  umockdev_testbed_uevent(bed.tb, kTouchSyspath, "remove");
  umockdev_testbed_remove_device(bed.tb, kTouchSyspath);
  CHECK(eventually([&] { return d.device->fault() == DeviceFault::kUnplugged; }));
}

// Two devices on one PC: device.usb_serial says which one is this station's; it is the one watched
// for unplug (unplugging the neighbour's device leaves this one running). Without usb_serial two
// Touches are refused naming the key and both serials; an unknown serial is refused naming it.
TEST(UmockdevUsb, TwoTouchesOnOnePcTheUsbSerialChoosesWhichIsWatchedAndWithoutItTheStartIsRefused) {
  FakeHd fake;
  DeviceSelection sel;
  sel.kind = "touch";
  sel.touch.hd_library_path = HAPTIC_FAKE_HD_PATH;
  {
  Testbed bed;
  bed.add("touch_usb.umockdev");
  bed.add("touch_usb_second.umockdev");
  try {
    (void)open_device(sel);
    FAIL("two Touches without device.usb_serial were accepted");
  } catch (const DeviceMissing& e) {
    const std::string m = e.what();
    CHECK_TEXT(m.find("device.usb_serial") != std::string::npos && m.find("serials ") != std::string::npos &&
                   m.find("\"TOUCH-0001\"") < m.find("usb: found") && m.find("\"TOUCH-0002\"") < m.find("usb: found"),
               m.c_str());
  }
  sel.usb_serial = "TOUCH-9999";
  try {
    (void)open_device(sel);
    FAIL("an unknown device.usb_serial was accepted");
  } catch (const DeviceMissing& e) {
    CHECK_TEXT(std::string(e.what()).find("device.usb_serial = \"TOUCH-9999\"") != std::string::npos, e.what());
  }
  }
  // each of the two in turn (whatever order the bus lists them in)
  const char* const paths[2] = {kTouchSyspath, "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-8"};
  const char* const serials[2] = {"TOUCH-0001", "TOUCH-0002"};
  for (int mine = 0; mine < 2; ++mine) {
    Testbed two;
    two.add("touch_usb.umockdev");
    two.add("touch_usb_second.umockdev");
    sel.usb_serial = serials[mine];
    OpenedDevice d = open_device(sel);
    CHECK_TEXT(d.report.find(std::string("touch: unplug detection on 2988:0302 3D Systems Touch, USB model (2988:0302; cdc_acm, /dev/ttyACM*) (bus 001 addr ") +
                             (mine == 0 ? "005" : "010") + ", serial \"" + serials[mine] + "\")") != std::string::npos,
               d.report.c_str());
    // the neighbour's Touch goes: this station keeps its device
    umockdev_testbed_uevent(two.tb, paths[1 - mine], "remove");
    umockdev_testbed_remove_device(two.tb, paths[1 - mine]);
    CHECK_TEXT(eventually([&] { return d.monitor->removals() >= 1; }), "the monitor never saw the neighbour's Touch leave");
    CHECK_TEXT(d.device->fault() == DeviceFault::kNone, fault_name(d.device->fault()));
    // this station's Touch goes: safe state
    umockdev_testbed_uevent(two.tb, paths[mine], "remove");
    umockdev_testbed_remove_device(two.tb, paths[mine]);
    CHECK(eventually([&] { return d.device->fault() == DeviceFault::kUnplugged; }));
    DeviceSample s{};
    CHECK_FALSE(d.device->read_newest(s));
  }
}

TEST(UmockdevUsb, HotplugReportsAnArrival) {
  Testbed bed;
  UsbMonitor monitor;
  monitor.start();
  CHECK(monitor.using_hotplug());
  bed.add("touch_usb.umockdev");
  umockdev_testbed_uevent(bed.tb, kTouchSyspath, "add");
  CHECK_TEXT(eventually([&] { return monitor.arrivals() >= 1; }), "libusb hotplug never reported the arrival");
  monitor.stop();
}

TEST_GROUP(UmockdevHidraw) {};

TEST(UmockdevHidraw, EnumerationFindsTheSpaceMouseAndTheTouchHidModel) {
  Testbed bed;
  bed.add("hid_devices.umockdev");
  auto hids = list_hid_devices(true);
  LONGS_EQUAL(2, hids.size());
  const HidDeviceInfo* sm = nullptr;
  const HidDeviceInfo* touch = nullptr;
  for (const auto& h : hids) {
    if (h.kind == DeviceKind::kSpaceMouse) sm = &h;
    if (h.kind == DeviceKind::kPhantomTouch) touch = &h;
  }
  CHECK(sm != nullptr);
  CHECK(touch != nullptr);
  STRCMP_EQUAL("/dev/hidraw0", sm->path.c_str());
  LONGS_EQUAL(0x256f, sm->vendor_id);
  LONGS_EQUAL(0xc635, sm->product_id);
  STRCMP_EQUAL("/dev/hidraw1", touch->path.c_str());
  LONGS_EQUAL(0x0304, touch->product_id);  // the current Touch HID model
  STRCMP_CONTAINS("HID model", touch->model);
}

TEST_GROUP(UmockdevTty) {};

TEST(UmockdevTty, TheUsbTouchIsFoundAsATtyAcmNodeWithItsIdentity) {
  Testbed bed;
  bed.add("touch_acm.umockdev");
  const auto ttys = list_acm_devices(true);
  LONGS_EQUAL(1, ttys.size());
  STRCMP_EQUAL("/dev/ttyACM0", ttys[0].node.c_str());
  LONGS_EQUAL(0x2988, ttys[0].vendor_id);
  LONGS_EQUAL(0x0302, ttys[0].product_id);
  STRCMP_EQUAL("TOUCH-ACM-3", ttys[0].serial.c_str());
  CHECK(ttys[0].kind == DeviceKind::kPhantomTouch);
}

TEST(UmockdevHidraw, SpaceMouseReportsAreDecodedThroughHidapiIntoSamples) {
  Testbed bed;
  bed.add("hid_devices.umockdev");
  UMockdevIoctlBase* handler = umockdev_ioctl_base_new();
  g_signal_connect(handler, "handle-ioctl", G_CALLBACK(on_hidraw_ioctl), nullptr);
  GError* err = nullptr;
  CHECK_TEXT(umockdev_testbed_attach_ioctl(bed.tb, "/dev/hidraw0", handler, &err), "attach_ioctl failed");
  const int master = umockdev_testbed_get_dev_fd(bed.tb, "/dev/hidraw0");
  CHECK(master >= 0);

  SpaceMouseConfig c;  // empty path: the first SpaceMouse found
  c.mode = SpaceMouseMode::kOwnerPolled;
  c.range_m = 0.05;
  SpaceMouseDevice sm(c);
  sm.start();
  STRCMP_EQUAL("/dev/hidraw0", sm.path().c_str());

  // One report at a time: the emulated node is a stream, a real hidraw node returns one
  // report per read().
  double t = 0.0;
  auto send = [&](const unsigned char* rep, std::size_t n) {
    const std::uint64_t before = sm.state().reports;
    CHECK(write(master, rep, n) == static_cast<ssize_t>(n));
    CHECK_TEXT(eventually([&] {
                 sm.poll(t += 0.002);
                 return sm.state().reports > before;
               }),
               "report never reached hidapi");
  };
  const unsigned char translation[7] = {1, 0x5E, 0x01, 0x00, 0x00, 0xA2, 0xFE};  // +350, 0, -350
  const unsigned char buttons[3] = {3, 0x02, 0x00};
  send(translation, sizeof translation);
  send(buttons, sizeof buttons);
  DeviceSample s{};
  CHECK(sm.read_newest(s));
  DOUBLES_EQUAL(0.05, s.position_m[0], 1e-12);
  DOUBLES_EQUAL(0.0, s.position_m[1], 1e-12);
  DOUBLES_EQUAL(-0.05, s.position_m[2], 1e-12);
  LONGS_EQUAL(2, s.buttons);
  const double f[3] = {1.0, 1.0, 1.0};
  sm.command_force(f);  // accepted, and clamped to zero: no force feedback
  sm.stop();
  umockdev_testbed_detach_ioctl(bed.tb, "/dev/hidraw0", nullptr);
  g_object_unref(handler);
}
