#pragma once
// Replay: `haptic-station replay LOG` rebuilds the rt::StationCore a session
// log (firmware/session/log.hpp) was recorded with, feeds it the recorded inputs in the recorded
// order (the packets offered before each tick, then the tick with its device sample) and compares
// every tick's state hash with the recorded one: a bit-exact replay matches at every tick. With
// other gains (B_i, a scale on P_ij or D_ij) it re-runs the session's inputs through the changed
// core (no comparison) so "what if" can be asked of a recorded problem. Not RT-safe.
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "firmware/session/log.hpp"

namespace haptic::firmware {

struct ReplayOptions {
  double damping_Ns_per_m = -1;  // >= 0: re-run with this B_i instead of the recorded one
  double p_scale = 1.0;          // P_ij := p_scale P_ij
  double d_scale = 1.0;          // D_ij := d_scale D_ij
  std::string trace_csv;         // "": none; else per-tick rows (t, force, VP, energies, recorded force, match)
  std::int64_t from_tick = -1;   // >= 0: print every tick from this run index on (stepping through)
  std::int64_t to_tick = -1;     // >= 0: stop after this run index (and print up to it)
  std::string state_json;        // "": none; else the core's full state after the last tick replayed (x, v, VP, links)
  bool gains_changed() const { return damping_Ns_per_m >= 0 || p_scale != 1.0 || d_scale != 1.0; }
};

struct ReplayResult {
  std::int64_t ticks = 0;             // ticks replayed
  std::int64_t matched = 0;           // ticks whose state hash equals the recorded one
  std::int64_t first_mismatch = -1;   // run index k of the first tick that differs (-1: none)
  std::int64_t inputs_end = -1;       // run index of the first tick with inputs lost (dropped records, truncation), -1: complete
  std::int64_t last_tick = -1;        // run index of the last tick replayed
  bool stopped_at_to = false;         // the replay ended at options.to_tick
  bool gains_changed = false;
  double max_force_difference_N = 0;  // |F_replay - F_recorded| max over the ticks
  int station_id = 0;
  std::string source;
  std::string recorded_build_id;      // the build that wrote the log ("" in older logs without it)
  std::string replay_build_id;        // this program's
  bool bit_exact() const { return !gains_changed && first_mismatch < 0 && ticks > 0 && matched == ticks; }
  // The log holds every input of the run, or the replay stopped (--to) before the first one lost.
  bool inputs_complete() const { return inputs_end < 0 || (stopped_at_to && inputs_end > last_tick); }
  std::string summary() const;       // one line for people
};

// Called after every replayed tick with the core, the recorded row and the tick's index in the log.
using ReplayObserver = std::function<void(const rt::StationCore& core, const TickRecord& recorded, std::int64_t index)>;

// A session log that cannot be replayed although it is one: a ring of the last minutes
// (station.record_ring_s) that wrapped holds no core state at its first tick.
struct NotReplayable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Replays the log at `path`. Throws NotReplayable for a wrapped ring log, std::runtime_error when
// it is not a session log or is damaged.
ReplayResult replay_session(const std::string& path, const ReplayOptions& options, const ReplayObserver& observer = {});

// Every recorded tick row of a log (for viewers and tests).
std::vector<TickRecord> read_tick_records(hid_t file);

}  // namespace haptic::firmware
