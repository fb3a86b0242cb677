#include "platform/install_paths.hpp"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace haptic::platform {

std::string executable_dir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  return exe.parent_path().string();
}

std::string tools_dir() {
  if (const char* e = std::getenv("HAPTIC_TOOLS_DIR"); e != nullptr && *e != '\0') return e;
  const std::string dir = executable_dir();
  if (dir.empty()) return "share/haptic/tools";  // no /proc: relative to the working directory
  return (std::filesystem::path(dir) / ".." / "share" / "haptic" / "tools").lexically_normal().string();
}

}  // namespace haptic::platform
