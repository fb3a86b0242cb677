#include "drivers/hd_library.hpp"

#include <cstdlib>
#include <dlfcn.h>
#include <type_traits>

namespace haptic::drivers::hd {

const char* error_name(HDerror code) {
  switch (code) {
    case 0x0000: return "HD_SUCCESS";
    case 0x0100: return "HD_INVALID_ENUM";
    case 0x0101: return "HD_INVALID_VALUE";
    case 0x0102: return "HD_INVALID_OPERATION";
    case 0x0103: return "HD_INVALID_INPUT_TYPE";
    case 0x0104: return "HD_BAD_HANDLE";
    case 0x0200: return "HD_WARM_MOTORS";
    case 0x0201: return "HD_EXCEEDED_MAX_FORCE";
    case 0x0202: return "HD_EXCEEDED_MAX_FORCE_IMPULSE";
    case 0x0203: return "HD_EXCEEDED_MAX_VELOCITY";
    case 0x0204: return "HD_FORCE_ERROR";
    case 0x0300: return "HD_DEVICE_FAULT";
    case 0x0301: return "HD_DEVICE_ALREADY_INITIATED";
    case 0x0302: return "HD_COMM_ERROR";
    case 0x0303: return "HD_COMM_CONFIG_ERROR";
    case 0x0304: return "HD_TIMER_ERROR";
    case 0x0400: return "HD_ILLEGAL_BEGIN";
    case 0x0401: return "HD_ILLEGAL_END";
    case 0x0402: return "HD_FRAME_ERROR";
    case 0x0500: return "HD_INVALID_PRIORITY";
    case 0x0501: return "HD_SCHEDULER_FULL";
    case 0x0600: return "HD_INVALID_LICENSE";
    default: return "HD error";
  }
}

std::string HdLibrary::resolve_path(const std::string& path) {
  if (!path.empty()) return path;
  if (const char* env = std::getenv("HAPTIC_HD_LIBRARY"); env != nullptr && *env != '\0') return env;
  return kDefaultPath;
}

namespace {
std::string missing_message(const std::string& path, const char* why) {
  return "OpenHaptics HD library not available: dlopen(\"" + path + "\") failed: " + (why ? why : "?") +
         ". The Phantom/Touch servo loop needs the vendor's OpenHaptics for Linux (libHD.so) and its "
         "device driver; install them, then name the library in the station file: "
         "device.hd_library_path = \"/path/to/libHD.so\" (or the environment variable HAPTIC_HD_LIBRARY; "
         "haptic-devices --hd-library PATH checks it). Without it this station can only run a "
         "SpaceMouse (device.kind = \"spacemouse\", no force feedback) or, explicitly, a simulated "
         "user (device.kind = \"simulated\").";
}
}  // namespace

HdLibrary::HdLibrary(const std::string& path) : path_(resolve_path(path)) {
  dlerror();
  handle_ = dlopen(path_.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle_ == nullptr) throw LibraryMissing(missing_message(path_, dlerror()));
  std::string missing;
  auto bind = [&](auto& fn, const char* name, bool required) {
    void* sym = dlsym(handle_, name);
    if (sym == nullptr && required) missing += (missing.empty() ? "" : ", ") + std::string(name);
    fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(sym);
  };
  bind(hdInitDevice, "hdInitDevice", true);
  bind(hdGetError, "hdGetError", true);
  bind(hdEnable, "hdEnable", true);
  bind(hdStartScheduler, "hdStartScheduler", true);
  bind(hdScheduleAsynchronous, "hdScheduleAsynchronous", true);
  bind(hdBeginFrame, "hdBeginFrame", true);
  bind(hdEndFrame, "hdEndFrame", true);
  bind(hdGetDoublev, "hdGetDoublev", true);
  bind(hdSetDoublev, "hdSetDoublev", true);
  bind(hdCheckCalibration, "hdCheckCalibration", true);
  bind(hdStopScheduler, "hdStopScheduler", true);
  bind(hdDisableDevice, "hdDisableDevice", true);
  bind(hdGetIntegerv, "hdGetIntegerv", false);
  bind(hdDisable, "hdDisable", false);
  bind(hdUnschedule, "hdUnschedule", false);
  bind(hdGetString, "hdGetString", false);
  if (!missing.empty()) {
    dlclose(handle_);
    handle_ = nullptr;
    throw LibraryMissing("OpenHaptics HD library \"" + path_ +
                         "\" was loaded but lacks required symbols: " + missing +
                         " (not an OpenHaptics libHD.so, or an unsupported version)");
  }
}

HdLibrary::~HdLibrary() {
  if (handle_ != nullptr) dlclose(handle_);
}

std::string HdLibrary::probe(const std::string& path) {
  try {
    HdLibrary lib(path);
    return {};
  } catch (const LibraryMissing& e) {
    return e.what();
  }
}

}  // namespace haptic::drivers::hd
