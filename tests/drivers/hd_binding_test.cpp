// The OpenHaptics HD binding (dlopen) against the fake vendor library built in this folder.
#include "drivers/hd_library.hpp"
#include "drivers/phantom_device.hpp"

#include <dlfcn.h>
#include <chrono>
#include <string>
#include <thread>

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

namespace {
struct Fake {
  void* h = nullptr;
  void (*reset)() = nullptr;
  void (*set_init_error)(unsigned) = nullptr;
  void (*set_calibration)(unsigned) = nullptr;
  void (*fail_at_frame)(unsigned long, unsigned) = nullptr;
  void (*set_max_force)(double) = nullptr;
  void (*set_state)(const double*, const double*, int) = nullptr;
  int (*run_frames)(int) = nullptr;
  void (*last_force)(double*) = nullptr;
  int (*force_output_enabled)() = nullptr;
  int (*initialized)() = nullptr;
  void (*set_manual)(int) = nullptr;
  Fake() {
    h = dlopen(HAPTIC_FAKE_HD_PATH, RTLD_NOW | RTLD_LOCAL);
    if (h == nullptr) FAIL(dlerror());
    bind(reset, "fakehd_reset");
    bind(set_init_error, "fakehd_set_init_error");
    bind(set_calibration, "fakehd_set_calibration");
    bind(fail_at_frame, "fakehd_fail_at_frame");
    bind(set_max_force, "fakehd_set_max_force");
    bind(set_state, "fakehd_set_state");
    bind(run_frames, "fakehd_run_frames");
    bind(last_force, "fakehd_last_force");
    bind(force_output_enabled, "fakehd_force_output_enabled");
    bind(initialized, "fakehd_initialized");
    bind(set_manual, "fakehd_set_manual");
    reset();
  }
  ~Fake() {
    reset();
    dlclose(h);
  }
  template <class F>
  void bind(F& f, const char* name) {
    f = reinterpret_cast<F>(dlsym(h, name));
    if (f == nullptr) FAIL(name);
  }
};

PhantomConfig fake_config() {
  PhantomConfig c;
  c.hd_library_path = HAPTIC_FAKE_HD_PATH;
  return c;
}
}  // namespace

TEST_GROUP(HdBinding) {};

TEST(HdBinding, AbsentLibraryIsReportedAsExactlyThat) {
  PhantomConfig c;
  c.hd_library_path = "/nonexistent/libHD.so";
  PhantomDevice d(c);
  try {
    d.start();
    FAIL("expected hd::LibraryMissing");
  } catch (const hd::LibraryMissing& e) {
    const std::string what = e.what();
    CHECK(what.find("OpenHaptics HD library not available") != std::string::npos);
    CHECK(what.find("/nonexistent/libHD.so") != std::string::npos);
  }
  CHECK(d.fault() == DeviceFault::kNotStarted);
  CHECK(!hd::HdLibrary::probe("/nonexistent/libHD.so").empty());
}

TEST(HdBinding, LibraryWithoutTheHdSymbolsIsRefusedByName) {
  try {
    hd::HdLibrary lib("libm.so.6");
    FAIL("expected hd::LibraryMissing");
  } catch (const hd::LibraryMissing& e) {
    CHECK(std::string(e.what()).find("lacks required symbols: hdInitDevice") != std::string::npos);
  }
}

TEST(HdBinding, InitFailureThrowsWithTheHdErrorName) {
  Fake fake;
  fake.set_init_error(0x0302);  // HD_COMM_ERROR
  PhantomDevice d(fake_config());
  try {
    d.start();
    FAIL("expected std::runtime_error");
  } catch (const hd::LibraryMissing&) {
    FAIL("the library is present");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("hdInitDevice") != std::string::npos);
    CHECK(std::string(e.what()).find("HD_COMM_ERROR (0x0302)") != std::string::npos);
  }
  CHECK(d.fault() == DeviceFault::kNotStarted);
}

TEST(HdBinding, ServoFrameConvertsUnitsAndAppliesTheNominalForceLimit) {
  Fake fake;
  fake.set_max_force(2.0);
  const double p_mm[3] = {10.0, -20.0, 30.0}, v_mm_s[3] = {0.0, 100.0, 0.0};
  fake.set_state(p_mm, v_mm_s, 0x3);
  PhantomDevice d(fake_config());
  d.start();
  DOUBLES_EQUAL(2.0, d.capabilities().max_force_N, 0.0);  // HD_NOMINAL_MAX_FORCE
  DOUBLES_EQUAL(1260.0, d.capabilities().max_stiffness_N_per_m, 1e-9);
  CHECK(fake.force_output_enabled() == 1);
  LONGS_EQUAL(1, fake.run_frames(1));
  DeviceSample s{};
  CHECK(d.read_newest(s));
  DOUBLES_EQUAL(0.010, s.position_m[0], 1e-12);
  DOUBLES_EQUAL(-0.020, s.position_m[1], 1e-12);
  DOUBLES_EQUAL(0.100, s.velocity_m_per_s[1], 1e-12);
  LONGS_EQUAL(3, s.buttons);
  const double f[3] = {0.0, 0.0, -5.0};
  d.command_force(f);
  fake.run_frames(1);
  double out[3];
  fake.last_force(out);
  DOUBLES_EQUAL(-2.0, out[2], 1e-12);
  d.stop();
  CHECK(fake.force_output_enabled() == 0);
  CHECK(fake.initialized() == 0);
}

TEST(HdBinding, CalibrationNeededIsASafeStateWithZeroForce) {
  Fake fake;
  fake.set_calibration(0x5002);  // HD_CALIBRATION_NEEDS_MANUAL_INPUT
  PhantomDevice d(fake_config());
  d.start();
  const double f[3] = {1.0, 0.0, 0.0};
  d.command_force(f);
  fake.run_frames(1);
  CHECK(d.fault() == DeviceFault::kCalibrationNeeded);
  LONGS_EQUAL(0x5002, d.fault_detail());
  double out[3];
  fake.last_force(out);
  DOUBLES_EQUAL(0.0, out[0], 0.0);
  DeviceSample s{};
  CHECK_FALSE(d.read_newest(s));
}

TEST(HdBinding, ServoCallbackErrorLatchesAndTheNextFrameOutputsZero) {
  Fake fake;
  fake.fail_at_frame(3, 0x0203);  // HD_EXCEEDED_MAX_VELOCITY at the end of frame 3
  PhantomDevice d(fake_config());
  d.start();
  DeviceSample s{};
  const double f[3] = {0.5, 0.0, 0.0};
  fake.run_frames(1);
  for (int k = 0; k < 2; ++k) {
    CHECK(d.read_newest(s));
    d.command_force(f);
    fake.run_frames(1);
  }
  double out[3];
  fake.last_force(out);
  DOUBLES_EQUAL(0.5, out[0], 0.0);  // frame 3 still carried the force; its end reported the error
  CHECK(d.fault() == DeviceFault::kServoError);
  LONGS_EQUAL(0x0203, d.fault_detail());
  CHECK_FALSE(d.read_newest(s));  // the station learns it in its next tick
  d.command_force(f);
  fake.run_frames(1);
  fake.last_force(out);
  DOUBLES_EQUAL(0.0, out[0], 0.0);  // and the next servo frame writes zero
}

TEST(HdBinding, UnplugNotificationZeroesTheNextServoFrame) {
  Fake fake;
  PhantomDevice d(fake_config());
  d.start();
  const double f[3] = {0.5, 0.0, 0.0};
  fake.run_frames(1);
  d.command_force(f);
  fake.run_frames(1);
  double out[3];
  fake.last_force(out);
  DOUBLES_EQUAL(0.5, out[0], 0.0);
  d.notify_unplugged();
  fake.run_frames(1);
  fake.last_force(out);
  DOUBLES_EQUAL(0.0, out[0], 0.0);
}

TEST(HdBinding, LibrarysOwnSchedulerThreadCarriesSamplesAndForces) {
  Fake fake;
  fake.set_manual(0);  // the fake's 1 kHz scheduler thread, as with the real library
  const double p_mm[3] = {5.0, 0.0, 0.0}, v_mm_s[3] = {0.0, 0.0, 0.0};
  fake.set_state(p_mm, v_mm_s, 0);
  SafetyLimits lenient;  // shared 2-core machine: a descheduled servo thread must not trip staleness
  lenient.max_stale_reads = 100000;
  PhantomDevice d(fake_config(), lenient);
  d.start();
  DeviceSample s{};
  bool got = false;
  for (int i = 0; i < 5000 && !got; ++i) {  // bounded wait, not a timing assertion
    got = d.read_newest(s);
    if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK_TEXT(got, "no sample from the scheduler thread within 5 s");
  DOUBLES_EQUAL(0.005, s.position_m[0], 1e-12);
  const double f[3] = {0.0, 0.25, 0.0};
  d.command_force(f);
  double out[3] = {0, 0, 0};
  for (int i = 0; i < 5000 && out[1] != 0.25; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    fake.last_force(out);
  }
  DOUBLES_EQUAL(0.25, out[1], 0.0);
  d.stop();
  fake.last_force(out);
  DOUBLES_EQUAL(0.0, out[1], 0.0);  // stop() let a zero-force frame out before stopping
}

// haptic-devices check's "open" item reads these: the identification strings through the optional
// hdGetString (HD_VERSION, HD_DEVICE_MODEL_TYPE, ...) and the usable workspace box, as the library answers.
TEST(HdBinding, IdentityAndWorkspaceBoxComeFromTheLibrary) {
  Fake fake;
  PhantomDevice d(fake_config());
  d.start();
  const HdIdentity& id = d.identity();
  CHECK(id.reported);
  STRCMP_EQUAL("3.00 (fake_hd test stand-in)", id.hd_version.c_str());
  STRCMP_EQUAL("fake_hd stand-in (tests/drivers/fake_hd, not a device)", id.model.c_str());
  STRCMP_EQUAL("FAKE-0001", id.serial.c_str());
  DOUBLES_EQUAL(0.0, id.firmware_version, 0.0);  // the fake does not answer HD_DEVICE_FIRMWARE_VERSION
  CHECK(id.has_workspace_box);
  DOUBLES_EQUAL(-80.0, id.workspace_box_mm[0], 0.0);
  DOUBLES_EQUAL(35.0, id.workspace_box_mm[5], 0.0);
  // the unanswered firmware query left nothing on the error stack for the servo frames
  LONGS_EQUAL(1, fake.run_frames(1));
  CHECK(d.fault() == DeviceFault::kNone);
  d.stop();
}
