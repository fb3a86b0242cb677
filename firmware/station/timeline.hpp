#pragma once
// The station's one timeline: the common tick index k (k = 0 at the epoch, the same on every
// station) and its one time-to-tick rule. Tick k is due at epoch_ns + k period_ns (CLOCK_MONOTONIC);
// k in [0, probe_ticks) probes, [probe_ticks, run_k0) is the set-up gap (build), [run_k0, run_k0 +
// run_ticks) runs, at run index kr = k - run_k0 (the index the core and its receive links count
// in). Probe, rejoin and run, stages of the station's one loop (loop.hpp), convert between time
// and ticks only through it. RT-safe (arithmetic).
#include <cstdint>

namespace haptic::firmware {

enum class TickPhase { kBefore, kProbe, kSetup, kRun, kAfter };

struct Timeline {
  std::int64_t epoch_ns = 0;     // CLOCK_MONOTONIC time of k = 0 (probing starts)
  std::int64_t period_ns = 0;
  std::int64_t probe_ticks = 0;  // k in [0, probe_ticks): probing
  std::int64_t run_k0 = 0;       // first run tick (probe_ticks + the set-up gap)
  std::int64_t run_ticks = 0;    // planned run length

  // When tick k is due.
  std::int64_t time_of(std::int64_t k) const { return epoch_ns + k * period_ns; }
  // The tick due nearest to ns (a deadline on the grid: exactly its tick; a late one rounds to it).
  // Rounded down, also before the epoch (k < 0: a loop that watches before probing).
  std::int64_t tick_at(std::int64_t ns) const {
    const std::int64_t d = ns - epoch_ns + period_ns / 2;
    return d >= 0 ? d / period_ns : -((-d + period_ns - 1) / period_ns);
  }
  std::int64_t run_epoch_ns() const { return time_of(run_k0); }
  std::int64_t run_end_k() const { return run_k0 + run_ticks; }
  TickPhase phase_of(std::int64_t k) const {
    if (k < 0) return TickPhase::kBefore;
    if (k < probe_ticks) return TickPhase::kProbe;
    if (k < run_k0) return TickPhase::kSetup;
    return k < run_end_k() ? TickPhase::kRun : TickPhase::kAfter;
  }
  // The first tick a loop started at now_ns runs, of a stage that starts at tick k_first: k_first
  // when it is due at least half a period after now_ns, else (a loop or stage that starts late: a
  // rejoining station) k_first + 2 + the whole periods now_ns is past k_first's due time: the tick of
  // the grid at least one period after now_ns. The loop's deadlines are exactly the ticks' due times.
  std::int64_t first_tick_from(std::int64_t k_first, std::int64_t now_ns) const {
    const std::int64_t t0 = time_of(k_first);
    return now_ns > t0 - period_ns / 2 ? k_first + (now_ns - t0) / period_ns + 2 : k_first;
  }
};

}  // namespace haptic::firmware
