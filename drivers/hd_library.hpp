#pragma once
// Run-time binding (dlopen) to the vendor's OpenHaptics HD library (libHD.so), which is the only
// servo path to a Phantom/Touch we use: the device's own servo protocol is not public and we do
// not invent one. We call this subset of its C ABI:
//   hdInitDevice, hdGetError, hdEnable, hdStartScheduler, hdScheduleAsynchronous,
//   hdBeginFrame, hdEndFrame, hdGetDoublev, hdSetDoublev, hdCheckCalibration,
//   hdStopScheduler, hdDisableDevice                          (required)
//   hdGetIntegerv, hdDisable, hdUnschedule, hdGetString         (optional: used when present)
// Types and constant values below are those of the public OpenHaptics 3.x headers hdDefines.h
// and hdScheduler.h (values checked against copies of those headers in public repositories,
// see drivers/README.md). Units of the HD API: positions in mm, velocities in mm/s, forces in N.
#include <cstdint>
#include <stdexcept>
#include <string>

namespace haptic::drivers::hd {

using HHD = unsigned int;
using HDenum = unsigned int;
using HDerror = unsigned int;
using HDushort = unsigned short;
using HDint = int;
using HDdouble = double;
using HDstring = const char*;
using HDCallbackCode = unsigned int;
using HDSchedulerHandle = unsigned long;
using HDSchedulerCallback = HDCallbackCode (*)(void* user_data);

struct HDErrorInfo {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
};

// hdDefines.h
inline constexpr HDerror kSuccess = 0x0000;
inline constexpr HDerror kCommError = 0x0302;        // HD_COMM_ERROR
inline constexpr HDerror kDeviceFault = 0x0300;      // HD_DEVICE_FAULT
inline constexpr HDenum kCurrentButtons = 0x2000;    // HD_CURRENT_BUTTONS (HDint)
inline constexpr HDenum kCurrentPosition = 0x2050;   // HD_CURRENT_POSITION (3 x mm)
inline constexpr HDenum kCurrentVelocity = 0x2051;   // HD_CURRENT_VELOCITY (3 x mm/s)
inline constexpr HDenum kVersion = 0x2500;                 // HD_VERSION (hdGetString: the HD library's version)
inline constexpr HDenum kDeviceModelType = 0x2501;         // HD_DEVICE_MODEL_TYPE (hdGetString)
inline constexpr HDenum kDeviceDriverVersion = 0x2502;     // HD_DEVICE_DRIVER_VERSION (hdGetString)
inline constexpr HDenum kDeviceVendor = 0x2503;            // HD_DEVICE_VENDOR (hdGetString)
inline constexpr HDenum kDeviceSerialNumber = 0x2504;      // HD_DEVICE_SERIAL_NUMBER (hdGetString)
inline constexpr HDenum kDeviceFirmwareVersion = 0x2505;   // HD_DEVICE_FIRMWARE_VERSION (hdGetDoublev)
inline constexpr HDenum kUsableWorkspaceDimensions = 0x2551;  // 6 x mm: min xyz, max xyz
inline constexpr HDenum kNominalMaxStiffness = 0x2602;        // N/mm
inline constexpr HDenum kNominalMaxForce = 0x2603;            // N
inline constexpr HDenum kCurrentForce = 0x2700;      // HD_CURRENT_FORCE (3 x N)
inline constexpr HDenum kForceOutput = 0x4000;       // HD_FORCE_OUTPUT (hdEnable capability)
inline constexpr HDenum kCalibrationOk = 0x5000;
inline constexpr HDenum kCalibrationNeedsUpdate = 0x5001;
inline constexpr HDenum kCalibrationNeedsManualInput = 0x5002;
inline constexpr HHD kInvalidHandle = 0xFFFFFFFFu;
inline constexpr HDushort kMaxSchedulerPriority = 0xFFFF;  // HD_MAX_SCHEDULER_PRIORITY = USHRT_MAX
// hdScheduler.h
inline constexpr HDCallbackCode kCallbackDone = 0;
inline constexpr HDCallbackCode kCallbackContinue = 1;

// The OpenHaptics release whose HD C ABI this binding targets: every signature, typedef and constant
// above is as in the public hdDefines.h / hd.h / hdScheduler.h of OpenHaptics 3.00 (hdDefines.h:
// HD_VERSION_MAJOR_NUMBER 3, HD_VERSION_MINOR_NUMBER 00, HD_VERSION_BUILD_NUMBER 66). Another major
// version may change them: `haptic-devices check` compares hdGetString(HD_VERSION)'s major number.
inline constexpr int kAbiMajorVersion = 3;
inline constexpr const char* kAbiDescription =
    "OpenHaptics 3.x HD C API (signatures and constants of hdDefines.h/hd.h/hdScheduler.h 3.00.66)";

// Name of an HD error code ("HD_COMM_ERROR", ...) or "HD error" when unknown. RT-safe.
const char* error_name(HDerror code);

// Thrown when the library cannot be loaded or lacks a required symbol. what() says exactly that.
class LibraryMissing : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The resolved entry points. Loading is non-RT; calling through the pointers is whatever the
// vendor library guarantees (the servo-frame calls are meant for its 1 kHz servo thread).
class HdLibrary {
 public:
  // Default library name searched with the normal dynamic-linker rules.
  static constexpr const char* kDefaultPath = "libHD.so";
  // Resolution order of the path: explicit argument if non-empty, else environment
  // HAPTIC_HD_LIBRARY, else kDefaultPath. Throws LibraryMissing.
  explicit HdLibrary(const std::string& path = {});
  ~HdLibrary();
  HdLibrary(const HdLibrary&) = delete;
  HdLibrary& operator=(const HdLibrary&) = delete;

  const std::string& path() const { return path_; }
  void* handle() const { return handle_; }
  // Non-throwing probe for diagnostics: empty string when loadable, else the reason.
  static std::string probe(const std::string& path = {});
  static std::string resolve_path(const std::string& path);

  HHD (*hdInitDevice)(HDstring config_name) = nullptr;
  HDErrorInfo (*hdGetError)() = nullptr;
  void (*hdEnable)(HDenum cap) = nullptr;
  void (*hdStartScheduler)() = nullptr;
  HDSchedulerHandle (*hdScheduleAsynchronous)(HDSchedulerCallback cb, void* user, HDushort priority) = nullptr;
  void (*hdBeginFrame)(HHD h) = nullptr;
  void (*hdEndFrame)(HHD h) = nullptr;
  void (*hdGetDoublev)(HDenum pname, HDdouble* params) = nullptr;
  void (*hdSetDoublev)(HDenum pname, const HDdouble* params) = nullptr;
  HDenum (*hdCheckCalibration)() = nullptr;
  void (*hdStopScheduler)() = nullptr;
  void (*hdDisableDevice)(HHD h) = nullptr;
  // Optional.
  void (*hdGetIntegerv)(HDenum pname, HDint* params) = nullptr;
  void (*hdDisable)(HDenum cap) = nullptr;
  void (*hdUnschedule)(HDSchedulerHandle h) = nullptr;
  HDstring (*hdGetString)(HDenum pname) = nullptr;  // identification strings (HD_VERSION, HD_DEVICE_*)

 private:
  std::string path_;
  void* handle_ = nullptr;
};

}  // namespace haptic::drivers::hd
