#pragma once
// `haptic-station log info|export|plot`: what a session log (firmware/session/log.hpp) holds, any
// of its /ticks or /packets fields as CSV with units in the header, and /ticks fields of one or
// more stations (a run folder's station-<i>.h5) drawn on one run-time axis (tools/plots/plot_log.py). Reads the units, descriptions
// and flag-bit names the log stores (kTickFields, rt::kTickFlagNames); an older log without them is
// described with this program's definitions and says so. Not RT-safe.
#include <CLI/CLI.hpp>

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

namespace haptic::firmware {

// Exit statuses of `log`: 0 done; 2 bad options or LOG is not a session log (missing, a directory,
// not HDF5, not format = "haptic-session"), 3 the log is damaged (a dataset cannot be read) or the
// CSV cannot be written.
inline constexpr int kLogExitBadInput = 2;
inline constexpr int kLogExitFailed = 3;

struct LogArgs {
  std::string log;                  // LOG.h5
  std::vector<std::string> fields;  // export: --field NAME[,NAME...]
  std::string out;                  // export: --out FILE.csv ("" : stdout); plot: --out FILE.png
  std::vector<std::string> logs;    // plot: LOG.h5 or RUN_DIR, one or more
};

struct LogCommands {
  CLI::App* log = nullptr;
  CLI::App* info = nullptr;
  CLI::App* exp = nullptr;
  CLI::App* plot = nullptr;
};
LogCommands add_log_options(CLI::App& app, LogArgs& a);
// Runs the parsed `log` subcommand; returns the exit status (messages on stderr).
int log_command(const LogCommands& c, const LogArgs& a);

// The two commands as functions (tests, other tools): write to `out`, throw LogError.
struct LogError : std::runtime_error {
  int status;
  LogError(int s, const std::string& what) : std::runtime_error(what), status(s) {}
};
void log_info(const std::string& path, std::ostream& out);
void log_export(const std::string& path, const std::vector<std::string>& fields, std::ostream& out);
// The logs `log plot` draws for its arguments: a file as is, a directory's station-<i>.h5 by i.
std::vector<std::string> plot_logs(const std::vector<std::string>& args);

}  // namespace haptic::firmware
