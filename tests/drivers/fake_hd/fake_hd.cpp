// Fake OpenHaptics HD library: a test fixture that implements the subset of the libHD.so C ABI
// that drivers/hd_library.hpp binds, with the public signatures and constant values, plus a few
// fakehd_* control functions the tests reach through dlsym on the same handle.
// It is NOT a device emulation: positions are whatever the test sets, forces are recorded.
// Scheduler: in manual mode (default) nothing runs until fakehd_run_frames(n) calls the
// scheduled callbacks n times on the caller's thread (deterministic tests and benchmarks);
// in automatic mode hdStartScheduler starts a 1 kHz thread like the real library.
// A process that cannot call the fakehd_* functions (the haptic-devices tool under test) sets the
// fixture up through the environment, read at hdInitDevice:
//   FAKEHD_AUTO=1                  automatic mode (the 1 kHz scheduler thread)
//   FAKEHD_POSITION_MM="x,y,z"     initial stylus position
//   FAKEHD_PLANT="m,b,c"           after every frame the stylus moves as a mass m (kg) with viscous
//                                  damping b (N s/m) and Coulomb friction c (N) under the frame's force
//   FAKEHD_CIRCLE_MM="r"           the stylus circles (radius r mm, 1 turn per second): never still
//   FAKEHD_CALIBRATION=0x5001      what hdCheckCalibration returns (default HD_CALIBRATION_OK, 0x5000)
//   FAKEHD_FORCE_LOG=path          every frame's force and position are written to path (CSV) at
//                                  hdDisableDevice, so a test can see what a station sent
//   FAKEHD_USER=1                  a scripted user (stand-in for the person `haptic-devices check`
//                                  prompts): while no force is commanded the hand holds the stylus and
//                                  sweeps it through 90% of the usable workspace box on each axis
//                                  (x, y, z sines of 0.5, 0.7, 0.9 Hz about the box centre) and presses
//                                  button 1 at 0.5-0.8 s and button 2 at 1.3-1.6 s of every 2 s; at the
//                                  first nonzero commanded force it lets go for good (as the check tells
//                                  the user to), buttons released, and FAKEHD_PLANT moves the stylus
//   FAKEHD_FORCE_GAIN="gx,gy,gz"   the plant feels each commanded force component times g (default 1):
//                                  -1 is a device that pushes the wrong way on that axis, 0 a dead motor
//   FAKEHD_DEAD_BUTTONS=mask       these button bits never read as pressed (a broken switch)
//   FAKEHD_HD_VERSION="s"          what hdGetString(HD_VERSION) answers (default "3.00 (fake_hd test stand-in)")
// hdGetString answers HD_DEVICE_MODEL_TYPE / _VENDOR / _DRIVER_VERSION / _SERIAL_NUMBER with strings that
// say it is this fixture; HD_DEVICE_FIRMWARE_VERSION is not answered (HD_INVALID_ENUM).
// The plant is a test model with known b (so a b_d measurement can be checked), not a Touch model.
#include <atomic>
#include <array>
#include <chrono>
#include <string>
#include <vector>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>

extern "C" {
typedef unsigned int HHD;
typedef unsigned int HDenum;
typedef unsigned int HDerror;
typedef unsigned short HDushort;
typedef int HDint;
typedef double HDdouble;
typedef const char* HDstring;
typedef unsigned int HDCallbackCode;
typedef unsigned long HDSchedulerHandle;
typedef HDCallbackCode (*HDSchedulerCallback)(void*);
typedef struct {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
} HDErrorInfo;
}

namespace {
constexpr HDerror kSuccess = 0;
constexpr HDerror kInvalidOperation = 0x0102;
constexpr HDerror kIllegalBegin = 0x0400;
constexpr HDenum kCurrentButtons = 0x2000, kCurrentPosition = 0x2050, kCurrentVelocity = 0x2051,
                 kUsableWorkspace = 0x2551, kNominalMaxStiffness = 0x2602, kNominalMaxForce = 0x2603,
                 kCurrentForce = 0x2700, kForceOutput = 0x4000, kCalibrationOk = 0x5000;
constexpr HHD kInvalidHandle = 0xFFFFFFFFu;
constexpr HDenum kVersion = 0x2500, kDeviceModelType = 0x2501, kDeviceDriverVersion = 0x2502, kDeviceVendor = 0x2503,
                 kDeviceSerialNumber = 0x2504;
constexpr double kUsableBoxMm[6] = {-80, -60, -35, 80, 60, 35};  // HD_USABLE_WORKSPACE_DIMENSIONS answer

struct State {
  std::mutex mu;  // guards configuration; frames run under it too (a fixture, not RT code)
  HDerror init_error = kSuccess;
  HDenum calibration = kCalibrationOk;
  unsigned long fail_frame = 0;  // 1-based frame whose end raises fail_code; 0 = never
  HDerror fail_code = 0;
  bool manual = true;
  double position_mm[3] = {0, 0, 0};
  double velocity_mm_s[3] = {0, 0, 0};
  int buttons = 0;
  double max_force_N = 3.3;
  double last_force[3] = {0, 0, 0};
  unsigned long frames = 0;
  bool initialized = false;
  bool in_frame = false;
  bool force_output = false;
  double plant_mass = 0.0, plant_b = 0.0, plant_coulomb = 0.0;  // plant off when mass == 0
  double circle_mm = 0.0;
  bool user = false, user_released = false;  // FAKEHD_USER
  double force_gain[3] = {1, 1, 1};          // FAKEHD_FORCE_GAIN
  int dead_buttons = 0;                      // FAKEHD_DEAD_BUTTONS
  std::string hd_version = "3.00 (fake_hd test stand-in)";
  std::string force_log;                  // FAKEHD_FORCE_LOG
  std::vector<std::array<double, 7>> log; // per frame: CLOCK_MONOTONIC s, force N, position mm
  HDSchedulerCallback cb = nullptr;
  void* cb_data = nullptr;
  HDerror errors[16] = {};
  int error_count = 0;
  std::atomic<bool> running{false};
  std::thread thread;
};
State& g() {
  static State s;
  return s;
}
void push_error(State& s, HDerror e) {
  if (s.error_count < 16) s.errors[s.error_count++] = e;
}
// FAKEHD_* environment set-up (see the top comment). Called with s.mu held.
void read_environment(State& s) {
  if (const char* a = std::getenv("FAKEHD_AUTO")) s.manual = std::strcmp(a, "1") != 0;
  if (const char* p = std::getenv("FAKEHD_POSITION_MM"))
    std::sscanf(p, "%lf,%lf,%lf", &s.position_mm[0], &s.position_mm[1], &s.position_mm[2]);
  if (const char* p = std::getenv("FAKEHD_PLANT")) std::sscanf(p, "%lf,%lf,%lf", &s.plant_mass, &s.plant_b, &s.plant_coulomb);
  if (const char* c = std::getenv("FAKEHD_CIRCLE_MM")) s.circle_mm = std::atof(c);
  if (const char* u = std::getenv("FAKEHD_USER")) s.user = std::strcmp(u, "1") == 0;
  s.user_released = false;
  if (const char* gn = std::getenv("FAKEHD_FORCE_GAIN"))
    std::sscanf(gn, "%lf,%lf,%lf", &s.force_gain[0], &s.force_gain[1], &s.force_gain[2]);
  if (const char* d = std::getenv("FAKEHD_DEAD_BUTTONS")) s.dead_buttons = static_cast<int>(std::strtol(d, nullptr, 0));
  if (const char* v = std::getenv("FAKEHD_HD_VERSION")) s.hd_version = v;
  if (const char* c = std::getenv("FAKEHD_CALIBRATION")) s.calibration = static_cast<HDenum>(std::strtoul(c, nullptr, 0));
  if (const char* f = std::getenv("FAKEHD_FORCE_LOG")) {
    s.force_log = f;
    s.log.reserve(200000);
  }
}
// One 1 ms step of the environment's motion after a frame (semi-implicit Euler). Called with s.mu held.
void move_stylus(State& s) {
  constexpr double dt = 1e-3;
  if (s.circle_mm > 0.0) {
    const double w = 2.0 * 3.141592653589793, t = static_cast<double>(s.frames) * dt;
    s.position_mm[0] = s.circle_mm * std::cos(w * t);
    s.position_mm[1] = s.circle_mm * std::sin(w * t);
    s.velocity_mm_s[0] = -w * s.circle_mm * std::sin(w * t);
    s.velocity_mm_s[1] = w * s.circle_mm * std::cos(w * t);
    return;
  }
  if (s.user && !s.user_released) {
    if (s.last_force[0] != 0.0 || s.last_force[1] != 0.0 || s.last_force[2] != 0.0) {
      s.user_released = true;  // told to let go before the force test; from here the plant moves it
      s.buttons = 0;
    } else {
      constexpr double kHz[3] = {0.5, 0.7, 0.9};
      const double t = static_cast<double>(s.frames) * dt;
      for (int i = 0; i < 3; ++i) {
        const double c = 0.5 * (kUsableBoxMm[i] + kUsableBoxMm[i + 3]), a = 0.45 * (kUsableBoxMm[i + 3] - kUsableBoxMm[i]);
        const double w = 2.0 * 3.141592653589793 * kHz[i];
        s.position_mm[i] = c + a * std::sin(w * t);
        s.velocity_mm_s[i] = a * w * std::cos(w * t);
      }
      const double phase = std::fmod(t, 2.0);
      const int pressed = (phase >= 0.5 && phase < 0.8 ? 1 : 0) | (phase >= 1.3 && phase < 1.6 ? 2 : 0);
      s.buttons = pressed & ~s.dead_buttons;
      return;
    }
  }
  if (s.plant_mass <= 0.0) return;
  for (int i = 0; i < 3; ++i) {
    const double v = s.velocity_mm_s[i] * 1e-3, f = s.last_force[i] * s.force_gain[i];
    double net = f - s.plant_b * v;
    if (v != 0.0) net -= std::copysign(s.plant_coulomb, v);
    else net = std::abs(f) <= s.plant_coulomb ? 0.0 : f - std::copysign(s.plant_coulomb, f);
    double v_new = v + net / s.plant_mass * dt;
    if (v != 0.0 && (v_new > 0.0) != (v > 0.0) && std::abs(f) <= s.plant_coulomb) v_new = 0.0;  // friction stops it
    s.velocity_mm_s[i] = v_new * 1e3;
    s.position_mm[i] += v_new * 1e3 * dt;
  }
}

int run_frames_locked(State& s, int n) {
  int ran = 0;
  for (int i = 0; i < n && s.cb != nullptr; ++i) {
    HDSchedulerCallback cb = s.cb;
    void* d = s.cb_data;
    s.mu.unlock();
    const HDCallbackCode code = cb(d);
    s.mu.lock();
    ++ran;
    if (code == 0) s.cb = nullptr;  // HD_CALLBACK_DONE
  }
  return ran;
}
}  // namespace

extern "C" {
// ---- HD subset ------------------------------------------------------------------------------
HHD hdInitDevice(HDstring) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (s.init_error != kSuccess) {
    push_error(s, s.init_error);
    return kInvalidHandle;
  }
  read_environment(s);
  s.initialized = true;
  return 1;
}
HDErrorInfo hdGetError() {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  HDErrorInfo e{kSuccess, 0, 1};
  if (s.error_count > 0) {
    e.errorCode = s.errors[0];
    e.internalErrorCode = -static_cast<int>(s.errors[0]);
    std::memmove(s.errors, s.errors + 1, sizeof(HDerror) * static_cast<unsigned>(s.error_count - 1));
    --s.error_count;
  }
  return e;
}
void hdEnable(HDenum cap) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (cap == kForceOutput) s.force_output = true;
}
void hdDisable(HDenum cap) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (cap == kForceOutput) s.force_output = false;
}
HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback cb, void* data, HDushort) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  s.cb = cb;
  s.cb_data = data;
  return 7;
}
void hdUnschedule(HDSchedulerHandle) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  s.cb = nullptr;
}
void hdStartScheduler() {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (!s.initialized) {
    push_error(s, kInvalidOperation);
    return;
  }
  if (s.manual || s.running.load()) return;
  s.running.store(true);
  s.thread = std::thread([&s] {
    auto next = std::chrono::steady_clock::now();
    while (s.running.load()) {
      {
        std::lock_guard<std::mutex> l2(s.mu);
        run_frames_locked(s, 1);
        if (!s.force_log.empty() && s.log.size() < 2000000)
          s.log.push_back({std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(), s.last_force[0],
                           s.last_force[1], s.last_force[2], s.position_mm[0], s.position_mm[1], s.position_mm[2]});
        move_stylus(s);
      }
      next += std::chrono::milliseconds(1);
      std::this_thread::sleep_until(next);
    }
  });
}
void hdStopScheduler() {
  State& s = g();
  if (s.running.exchange(false) && s.thread.joinable()) s.thread.join();
}
void hdBeginFrame(HHD) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (s.in_frame) push_error(s, kIllegalBegin);
  s.in_frame = true;
}
void hdEndFrame(HHD) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  s.in_frame = false;
  ++s.frames;
  if (s.fail_frame != 0 && s.frames == s.fail_frame) push_error(s, s.fail_code);
}
void hdGetDoublev(HDenum pname, HDdouble* out) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  switch (pname) {
    case kCurrentPosition: std::memcpy(out, s.position_mm, sizeof s.position_mm); break;
    case kCurrentVelocity: std::memcpy(out, s.velocity_mm_s, sizeof s.velocity_mm_s); break;
    case kNominalMaxForce: out[0] = s.max_force_N; break;
    case kNominalMaxStiffness: out[0] = 1.26; break;
    case kUsableWorkspace: std::memcpy(out, kUsableBoxMm, sizeof kUsableBoxMm); break;
    default: push_error(s, 0x0100); break;  // HD_INVALID_ENUM
  }
}
HDstring hdGetString(HDenum pname) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  switch (pname) {
    case kVersion: return s.hd_version.c_str();
    case kDeviceModelType: return "fake_hd stand-in (tests/drivers/fake_hd, not a device)";
    case kDeviceVendor: return "none (test fixture)";
    case kDeviceDriverVersion: return "none (test fixture)";
    case kDeviceSerialNumber: return "FAKE-0001";
    default: push_error(s, 0x0100); return nullptr;  // HD_INVALID_ENUM
  }
}
void hdGetIntegerv(HDenum pname, HDint* out) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (pname == kCurrentButtons) out[0] = s.buttons;
}
void hdSetDoublev(HDenum pname, const HDdouble* in) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  if (pname == kCurrentForce) {
    if (!s.in_frame) push_error(s, kInvalidOperation);
    std::memcpy(s.last_force, in, sizeof s.last_force);
  }
}
HDenum hdCheckCalibration() {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  return s.calibration;
}
void hdDisableDevice(HHD) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  s.initialized = false;
  if (!s.force_log.empty()) {
    if (FILE* f = std::fopen(s.force_log.c_str(), "w")) {
      std::fprintf(f, "frame,t_s,fx_N,fy_N,fz_N,x_mm,y_mm,z_mm\n");
      for (std::size_t i = 0; i < s.log.size(); ++i)
        std::fprintf(f, "%zu,%.6f,%.9g,%.9g,%.9g,%.6f,%.6f,%.6f\n", i, s.log[i][0], s.log[i][1], s.log[i][2], s.log[i][3], s.log[i][4],
                     s.log[i][5], s.log[i][6]);
      std::fclose(f);
    }
    s.log.clear();
  }
}

// ---- test controls ---------------------------------------------------------------------------
void fakehd_reset() {
  hdStopScheduler();
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  s.init_error = kSuccess;
  s.calibration = kCalibrationOk;
  s.fail_frame = 0;
  s.fail_code = 0;
  s.manual = true;
  for (int i = 0; i < 3; ++i) s.position_mm[i] = s.velocity_mm_s[i] = s.last_force[i] = 0.0;
  s.buttons = 0;
  s.max_force_N = 3.3;
  s.plant_mass = s.plant_b = s.plant_coulomb = s.circle_mm = 0.0;
  s.user = s.user_released = false;
  for (double& gn : s.force_gain) gn = 1.0;
  s.dead_buttons = 0;
  s.frames = 0;
  s.initialized = s.in_frame = s.force_output = false;
  s.cb = nullptr;
  s.cb_data = nullptr;
  s.error_count = 0;
}
void fakehd_set_init_error(unsigned code) { std::lock_guard<std::mutex> l(g().mu); g().init_error = code; }
void fakehd_set_calibration(unsigned state) { std::lock_guard<std::mutex> l(g().mu); g().calibration = state; }
void fakehd_fail_at_frame(unsigned long frame, unsigned code) {
  std::lock_guard<std::mutex> l(g().mu);
  g().fail_frame = frame;
  g().fail_code = code;
}
void fakehd_set_manual(int manual) { std::lock_guard<std::mutex> l(g().mu); g().manual = manual != 0; }
void fakehd_set_max_force(double f) { std::lock_guard<std::mutex> l(g().mu); g().max_force_N = f; }
void fakehd_set_state(const double position_mm[3], const double velocity_mm_s[3], int buttons) {
  std::lock_guard<std::mutex> l(g().mu);
  for (int i = 0; i < 3; ++i) {
    g().position_mm[i] = position_mm[i];
    g().velocity_mm_s[i] = velocity_mm_s[i];
  }
  g().buttons = buttons;
}
int fakehd_run_frames(int n) {
  State& s = g();
  std::lock_guard<std::mutex> l(s.mu);
  return run_frames_locked(s, n);
}
void fakehd_last_force(double out[3]) {
  std::lock_guard<std::mutex> l(g().mu);
  std::memcpy(out, g().last_force, sizeof g().last_force);
}
unsigned long fakehd_frames() { std::lock_guard<std::mutex> l(g().mu); return g().frames; }
int fakehd_force_output_enabled() { std::lock_guard<std::mutex> l(g().mu); return g().force_output ? 1 : 0; }
int fakehd_initialized() { std::lock_guard<std::mutex> l(g().mu); return g().initialized ? 1 : 0; }
}
