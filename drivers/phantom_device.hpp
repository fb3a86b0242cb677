#pragma once
// Phantom Omni / Touch through the vendor's OpenHaptics HD library (loaded at run time, see
// hd_library.hpp). The servo runs inside the library's own 1 kHz scheduler thread: our
// asynchronous callback reads position/velocity/buttons, publishes the sample, takes the newest
// limited force from the mailbox (zero in the safe state) and sets it, all in one HD frame.
// HD errors after a frame latch kServoError (detail = HD error code); hdCheckCalibration() other
// than HD_CALIBRATION_OK latches kCalibrationNeeded. Unplug detection comes from UsbMonitor
// (usb_monitor.hpp), which calls notify_unplugged() on this device.
#include "drivers/device.hpp"
#include "drivers/hd_library.hpp"

#include <atomic>
#include <memory>
#include <string>

namespace haptic::drivers {

struct PhantomConfig {
  std::string hd_library_path;  // "" = $HAPTIC_HD_LIBRARY or "libHD.so"
  std::string device_name;      // HD configuration name; "" = HD_DEFAULT_DEVICE
};

// What the HD library says about the device it opened (read once in start(), non-RT).
struct HdIdentity {
  bool reported = false;       // the library exports hdGetString (optional in our binding)
  std::string hd_version;      // hdGetString(HD_VERSION): the HD library's version
  std::string model, vendor, driver_version, serial;  // HD_DEVICE_MODEL_TYPE, _VENDOR, _DRIVER_VERSION, _SERIAL_NUMBER
  double firmware_version = 0.0;  // hdGetDoublev(HD_DEVICE_FIRMWARE_VERSION); 0 when not answered
  bool has_workspace_box = false;   // HD_USABLE_WORKSPACE_DIMENSIONS answered
  double workspace_box_mm[6] = {-80, -60, -35, 80, 60, 35};  // min xyz, max xyz (spec-sheet default until answered)
};

// Touch-class defaults used until the library reports HD_NOMINAL_MAX_FORCE etc. (public spec
// sheet figures for the 3D Systems Touch: 3.3 N peak force, ~1.26 N/mm stiffness, 160x120x70 mm).
DeviceCapabilities touch_default_capabilities();

class PhantomDevice final : public HapticDevice {
 public:
  explicit PhantomDevice(const PhantomConfig& config, const SafetyLimits& limits = {});
  ~PhantomDevice() override;

  // Non-RT. Loads libHD.so, hdInitDevice, reads the nominal limits, enables force output,
  // schedules the servo callback and starts the scheduler. Throws hd::LibraryMissing when the
  // library is absent, std::runtime_error naming the HD error when the device cannot start.
  void start() override;
  void stop() override;  // non-RT: zero force, stop scheduler, disable device

  const std::string& library_path() const { return library_path_; }
  std::uint64_t servo_frames() const { return frames_.load(std::memory_order_relaxed); }
  // RT-safe. hdCheckCalibration said HD_CALIBRATION_OK in a servo frame (until then no sample is
  // published; any other answer is the kCalibrationNeeded fault, its detail the HD code).
  bool calibrated() const { return calibrated_seen_.load(std::memory_order_acquire); }
  // Non-RT, after start(): identification strings and the usable workspace box the library reported.
  const HdIdentity& identity() const { return identity_; }

 private:
  static hd::HDCallbackCode servo_trampoline(void* self);
  hd::HDCallbackCode servo_frame();  // runs on the HD scheduler thread; RT-safe
  void release();
  void read_identity();  // non-RT, in start()

  PhantomConfig config_;
  std::string library_path_;
  std::unique_ptr<hd::HdLibrary> lib_;
  hd::HHD handle_ = hd::kInvalidHandle;
  hd::HDSchedulerHandle callback_ = 0;
  bool scheduler_started_ = false;
  std::atomic<bool> servo_enabled_{false};
  bool calibrated_ = false;  // servo-thread only
  std::atomic<bool> calibrated_seen_{false};  // calibrated_, for other threads
  std::uint64_t sequence_ = 0;  // servo-thread only
  std::atomic<std::uint64_t> frames_{0};
  HdIdentity identity_;
};

}  // namespace haptic::drivers
