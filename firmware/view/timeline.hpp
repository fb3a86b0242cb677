#pragma once
// The web view of a recorded session with a timeline: the session log is
// replayed (firmware/session/replay.hpp), a frame kept every few ticks, and the live view's page
// plays them back at recorded speed with play/pause and a seek slider (by frame, or by run time:
// {"seek_t": s}, how `haptic-lab replay` keeps a run's stations on one timeline). Used by
// `haptic-station replay LOG --view-port P` and `sim --record --view-port P`. Not RT-safe.
#include <atomic>
#include <string>

#include "firmware/session/replay.hpp"
#include "firmware/view/server.hpp"

namespace haptic::firmware {

struct TimelineOptions {
  ViewServerConfig server;     // port, bind, rate
  double serve_s = 0;          // > 0: stop serving after this long; 0: until `stop`
  std::string mode = "replay"; // shown on the page ("replay" | "sim")
};

// Replays `log` (with `replay` options), keeps at most ~4000 frames, serves them until serve_s or
// `stop`. Prints the URL on stderr. Returns the replay's result.
ReplayResult serve_timeline(const std::string& log, const ReplayOptions& replay, const TimelineOptions& options, const std::atomic<bool>& stop);

}  // namespace haptic::firmware
