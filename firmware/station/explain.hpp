#pragma once
// Why a run failed, in words and in station-<id>.json (firmware/README.md, "Why a run failed"):
// for every non-zero exit of `haptic-station run`, the links, the times and the measured cause the
// station can see: this host's wake-up latency, overruns and skipped periods (the run loop's own
// measurements), each neighbour's silence or lateness (packets that arrived, the age of the newest
// against N̄) in the spans without a usable neighbour (OutageTracker), and the longest stall.
// Not RT-safe (the report phase, after the loop ended).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/station/report.hpp"

namespace haptic::firmware {

// This host's timing over a loop (the run loop, else the probing loop).
struct HostTiming {
  std::string loop;  // "run" or "probe"
  std::uint64_t ticks = 0, overruns = 0, missed_cycles = 0;
  bool have_latency = false;  // the probing loop keeps no wake-up histogram
  double wake_p99_ms = 0, wake_max_ms = 0, period_ms = 0;
  bool starving = false;  // platform::host_starving
};
HostTiming host_timing(const StationOutcome& o);
nlohmann::json host_json(const HostTiming& h);
// "this host over the run: wake-up P99 0.4 ms, max 13.6 ms, 36 overruns, 2 skipped periods in 2000 ticks
// of 2 ms: kept its period" (or "STARVING: ...").
std::string host_line(const HostTiming& h);

struct Explanation {
  std::vector<std::string> lines;  // printed as errors, in this order, and kept in the JSON
  nlohmann::json json;             // station-<id>.json "explanation"
};
// The explanation of exit `code` (empty lines for 0).
Explanation explain_exit(const StationOutcome& o, const RunConditions& c, int code);

}  // namespace haptic::firmware
