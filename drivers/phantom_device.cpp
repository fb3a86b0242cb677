#include "drivers/phantom_device.hpp"
#include "platform/clock.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>
#include <time.h>

namespace haptic::drivers {

DeviceCapabilities touch_default_capabilities() {
  DeviceCapabilities c{};
  c.max_force_N = 3.3;
  c.max_stiffness_N_per_m = 1260.0;
  c.servo_rate_hz = 1000.0;
  c.workspace_radius_m = 0.11;  // half-diagonal of 160 x 120 x 70 mm, rounded up
  c.min_damping_Ns_per_m = 0.0; // not published by the vendor: identify b_d on the bench (README)
  for (int i = 0; i < 3; ++i) c.sensed_axes[i] = c.actuated_axes[i] = true;
  c.name = "Phantom/Touch via OpenHaptics HD";
  return c;
}

namespace {
std::string hd_error_text(const hd::HDErrorInfo& e) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s (0x%04x), internal code %d", hd::error_name(e.errorCode), e.errorCode,
                e.internalErrorCode);
  return buf;
}
using platform::monotonic_s;
}  // namespace

PhantomDevice::PhantomDevice(const PhantomConfig& config, const SafetyLimits& limits)
    : HapticDevice(touch_default_capabilities(), limits),
      config_(config),
      library_path_(hd::HdLibrary::resolve_path(config.hd_library_path)) {}

PhantomDevice::~PhantomDevice() { stop(); }

void PhantomDevice::start() {
  stop();
  lib_ = std::make_unique<hd::HdLibrary>(config_.hd_library_path);  // throws LibraryMissing
  const char* name = config_.device_name.empty() ? nullptr : config_.device_name.c_str();
  handle_ = lib_->hdInitDevice(name);
  hd::HDErrorInfo err = lib_->hdGetError();
  if (err.errorCode != hd::kSuccess || handle_ == hd::kInvalidHandle) {
    const std::string what = "hdInitDevice(\"" + (name ? config_.device_name : std::string("default device")) +
                             "\") failed: " + hd_error_text(err) +
                             ". Is the Touch plugged in, powered, and configured with the vendor's "
                             "Touch_Setup / device driver? (library: " + lib_->path() + ")";
    handle_ = hd::kInvalidHandle;
    lib_.reset();
    throw std::runtime_error(what);
  }
  // Nominal limits from the library, when it answers (HD_NOMINAL_MAX_FORCE in N,
  // HD_NOMINAL_MAX_STIFFNESS in N/mm, HD_USABLE_WORKSPACE_DIMENSIONS in mm).
  DeviceCapabilities caps = capabilities();
  double v[6] = {0, 0, 0, 0, 0, 0};
  lib_->hdGetDoublev(hd::kNominalMaxForce, v);
  if (lib_->hdGetError().errorCode == hd::kSuccess && v[0] > 0.0 && std::isfinite(v[0])) caps.max_force_N = v[0];
  v[0] = 0.0;
  lib_->hdGetDoublev(hd::kNominalMaxStiffness, v);
  if (lib_->hdGetError().errorCode == hd::kSuccess && v[0] > 0.0 && std::isfinite(v[0]))
    caps.max_stiffness_N_per_m = v[0] * 1000.0;
  for (double& x : v) x = 0.0;
  lib_->hdGetDoublev(hd::kUsableWorkspaceDimensions, v);
  identity_ = HdIdentity{};
  if (lib_->hdGetError().errorCode == hd::kSuccess) {
    identity_.has_workspace_box = true;
    for (int i = 0; i < 6; ++i) identity_.workspace_box_mm[i] = v[i];
    double r2 = 0.0;  // bound on |p| over the box: max over corners
    for (int i = 0; i < 3; ++i) {
      const double m = std::fmax(std::fabs(v[i]), std::fabs(v[i + 3])) * 1e-3;
      r2 += m * m;
    }
    if (r2 > 0.0 && std::isfinite(r2)) caps.workspace_radius_m = std::sqrt(r2);
  }
  set_capabilities(caps);
  read_identity();

  lib_->hdEnable(hd::kForceOutput);
  calibrated_ = false;
  calibrated_seen_.store(false, std::memory_order_release);
  sequence_ = 0;
  servo_enabled_.store(true, std::memory_order_release);
  arm();  // before the scheduler runs, so servo faults (calibration) latch
  callback_ = lib_->hdScheduleAsynchronous(&PhantomDevice::servo_trampoline, this, hd::kMaxSchedulerPriority);
  lib_->hdStartScheduler();
  scheduler_started_ = true;
  err = lib_->hdGetError();
  if (err.errorCode != hd::kSuccess) {
    const std::string what = "hdStartScheduler failed: " + hd_error_text(err);
    stop();
    throw std::runtime_error(what);
  }
}

void PhantomDevice::read_identity() {
  if (lib_->hdGetString != nullptr) {
    identity_.reported = true;
    auto text = [&](hd::HDenum what) {
      const hd::HDstring t = lib_->hdGetString(what);
      const bool ok = lib_->hdGetError().errorCode == hd::kSuccess;
      return ok && t != nullptr ? std::string(t) : std::string();
    };
    identity_.hd_version = text(hd::kVersion);
    identity_.model = text(hd::kDeviceModelType);
    identity_.vendor = text(hd::kDeviceVendor);
    identity_.driver_version = text(hd::kDeviceDriverVersion);
    identity_.serial = text(hd::kDeviceSerialNumber);
  }
  double fw = 0.0;
  lib_->hdGetDoublev(hd::kDeviceFirmwareVersion, &fw);
  if (lib_->hdGetError().errorCode == hd::kSuccess && std::isfinite(fw)) identity_.firmware_version = fw;
}

hd::HDCallbackCode PhantomDevice::servo_trampoline(void* self) {
  return static_cast<PhantomDevice*>(self)->servo_frame();
}

hd::HDCallbackCode PhantomDevice::servo_frame() {
  if (!servo_enabled_.load(std::memory_order_acquire)) return hd::kCallbackDone;
  lib_->hdBeginFrame(handle_);
  if (!calibrated_) {
    const hd::HDenum cal = lib_->hdCheckCalibration();
    if (cal == hd::kCalibrationOk) {
      calibrated_ = true;
      calibrated_seen_.store(true, std::memory_order_release);
    } else {
      raise_fault(DeviceFault::kCalibrationNeeded, static_cast<std::int32_t>(cal));
    }
  }
  double p_mm[3] = {0, 0, 0}, v_mm_s[3] = {0, 0, 0};
  lib_->hdGetDoublev(hd::kCurrentPosition, p_mm);
  lib_->hdGetDoublev(hd::kCurrentVelocity, v_mm_s);
  hd::HDint buttons = 0;
  if (lib_->hdGetIntegerv != nullptr) lib_->hdGetIntegerv(hd::kCurrentButtons, &buttons);
  double f[3];
  take_force(f);  // exactly zero in the safe state (including "calibration needed" above)
  lib_->hdSetDoublev(hd::kCurrentForce, f);
  lib_->hdEndFrame(handle_);
  frames_.fetch_add(1, std::memory_order_relaxed);
  const hd::HDErrorInfo err = lib_->hdGetError();
  if (err.errorCode != hd::kSuccess) {
    raise_fault(DeviceFault::kServoError, static_cast<std::int32_t>(err.errorCode));
    return hd::kCallbackContinue;  // keep running: the following frames write zero force
  }
  if (calibrated_) {
    DeviceSample s{};
    for (int i = 0; i < 3; ++i) {
      s.position_m[i] = p_mm[i] * 1e-3;
      s.velocity_m_per_s[i] = v_mm_s[i] * 1e-3;
    }
    s.buttons = static_cast<std::uint32_t>(buttons);
    s.time_s = monotonic_s();
    s.sequence = ++sequence_;
    publish_sample(s);
  }
  return hd::kCallbackContinue;
}

void PhantomDevice::stop() {
  disarm();  // from here take_force() yields zero
  if (!lib_) return;
  if (scheduler_started_) {
    // Let the scheduler run at least two more frames so a zero force reaches the motors
    // before the scheduler stops (bounded wait, 250 ms; the fake library may be in manual mode).
    const std::uint64_t f0 = frames_.load(std::memory_order_relaxed);
    for (int i = 0; i < 250 && frames_.load(std::memory_order_relaxed) < f0 + 2; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    servo_enabled_.store(false, std::memory_order_release);
    lib_->hdStopScheduler();
    if (lib_->hdUnschedule != nullptr) lib_->hdUnschedule(callback_);
    scheduler_started_ = false;
  }
  servo_enabled_.store(false, std::memory_order_release);
  if (lib_->hdDisable != nullptr) lib_->hdDisable(hd::kForceOutput);
  if (handle_ != hd::kInvalidHandle) lib_->hdDisableDevice(handle_);
  lib_->hdGetError();  // drop anything the shutdown left on the error stack
  handle_ = hd::kInvalidHandle;
  lib_.reset();
}

}  // namespace haptic::drivers
