// Device selection at start-up: what the station opens and how it explains the choice.
#include "drivers/device_factory.hpp"

#include <stdexcept>
#include <string>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

TEST_GROUP(DeviceFactory) {};

TEST(DeviceFactory, SimulatedKindGivesAnOwnerSteppedSimulatedDevice) {
  DeviceSelection sel;
  sel.kind = "simulated";
  OpenedDevice d = open_device(sel);
  CHECK(d.device != nullptr);
  CHECK(d.simulated == d.device.get());
  CHECK(d.device->fault() == DeviceFault::kNone);
  CHECK(d.report.find("simulated") != std::string::npos);
}

TEST(DeviceFactory, UnknownKindNamesTheKeyAndTheAllowedValues) {
  DeviceSelection sel;
  sel.kind = "phantom";
  try {
    open_device(sel);
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("device.kind = \"phantom\"") != std::string::npos);
    CHECK(std::string(e.what()).find("\"simulated\"") != std::string::npos);
  }
}

TEST(DeviceFactory, RequestedTouchWithoutTheVendorLibrarySaysExactlyThat) {
  DeviceSelection sel;
  sel.kind = "touch";
  sel.touch.hd_library_path = "/nonexistent/libHD.so";
  try {
    open_device(sel);
    FAIL("expected std::runtime_error");
  } catch (const std::invalid_argument&) {
    FAIL("kind is valid");
  } catch (const DeviceMissing& e) {
    CHECK(std::string(e.what()).find("OpenHaptics HD library not available") != std::string::npos);
    CHECK(std::string(e.what()).find("hd_library_path") != std::string::npos);
  }
}

TEST(DeviceFactory, AutoWithNoDeviceIsAnErrorNotASimulatedUser) {
  DeviceSelection sel;  // kind "auto"
  sel.touch.hd_library_path = "/nonexistent/libHD.so";
  sel.spacemouse.hidraw_path = "/nonexistent/hidraw99";
  try {
    OpenedDevice d = open_device(sel);
    FAIL("expected DeviceMissing, got a device");
  } catch (const DeviceMissing& e) {
    CHECK_TEXT(std::string(e.what()).find("device.kind = \"simulated\"") != std::string::npos, e.what());
  }
}

TEST(DeviceFactory, RequestedTouchStartsThroughTheFakeVendorLibrary) {
  DeviceSelection sel;
  sel.kind = "touch";
  sel.touch.hd_library_path = HAPTIC_FAKE_HD_PATH;
  OpenedDevice d = open_device(sel);
  CHECK(d.device != nullptr);
  CHECK(d.simulated == nullptr);
  CHECK(d.report.find("touch: started through") != std::string::npos);
}
