#pragma once
// Where a binary finds the scripts it runs (figure and report scripts): relative to its own
// executable, so the same rule holds in the build tree and in any install prefix.
//   <prefix>/bin/haptic-station  ->  <prefix>/share/haptic/tools/plots/plot_run.py
//   build/bin/haptic-station     ->  build/share/haptic/tools/plots/plot_run.py (copied at configure)
// The environment variable HAPTIC_TOOLS_DIR overrides the directory (e.g. the source tree's
// tools/ while editing a script). Start-up / non-RT only: reads /proc/self/exe, allocates.
#include <string>

namespace haptic::platform {

// Directory of the running executable (resolved /proc/self/exe), "" when it cannot be read.
std::string executable_dir();

// $HAPTIC_TOOLS_DIR when set and non-empty, else <executable_dir>/../share/haptic/tools
// (normalized). The result is not checked for existence: callers say which script is missing.
std::string tools_dir();

}  // namespace haptic::platform
