#pragma once
// run: the fourth phase of `haptic-station run` (DESIGN.md, "The station process"). The run ticks
// k in [run_k0, run_k0 + run_ticks) on platform::RtThread + PeriodicLoop, each one run_tick().
// The core is built before the RT thread is created and handed to it once (TickInputs). One catch
// at the loop boundary (around PeriodicLoop::run inside the RtThread body): an exception ends the
// loop and enters the safe state (zero force to the device); the non-RT side reports it.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "firmware/station/phase.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/tick.hpp"
#include "platform/periodic_loop.hpp"

namespace haptic::firmware {

struct RunPhaseResult {
  PhaseStatus status = PhaseStatus::kFailed;
  std::string message;
  platform::LoopStats loop{};
  std::string rt_summary;
  std::vector<std::string> rt_warnings;
  std::int64_t first_run_k = -1;     // epoch index of the first run tick (-1: none ran)
  bool loop_exception = false;       // the loop boundary caught an exception: safe state latched
  std::string loop_exception_what;   // its message (copied on the non-RT side)
  bool stopped_by_signal = false;
};

// Safe state after a caught exception: zero force to the device. RT-safe, never throws.
void enter_safe_state(drivers::HapticDevice* device) noexcept;

// What the non-RT side hears while the run phase runs (either may be empty). Called on the
// thread that called run_periodic(), never on the RT thread.
struct RunObserver {
  std::function<void(const std::string& rt_summary, const std::vector<std::string>& rt_warnings)> rt_ready;  // after the RT set-up
  std::function<void(const platform::LoopReport&)> report;  // the loop's throttled reports
  std::function<void()> idle;  // every 100 ms while the loop runs (non-RT monitoring, e.g. neighbour events)
};

// One run tick at epoch index k = run_k0 + kr (run_tick() in the station). Called on the RT thread.
using RunTickFn = std::function<void(std::int64_t k, std::int64_t kr, const platform::TickInfo& info)>;

// The RT side of the run phase for any tick function: RtThread (plan.file.rt), wait for the run
// epoch (a rejoining station, already past it, for the next tick of the session's grid), PeriodicLoop (plan.file.loop) until run_ticks or `stop`; an exception out of `tick` is
// caught at the loop boundary, ends the loop and enters the safe state of `device` (may be null).
// The calling thread waits on a semaphore with a timeout of one report interval and hands the
// loop's reports to `observer` (no polling of the RT side). Not RT-safe (owns the RT thread).
RunPhaseResult run_periodic(const StationPlan& plan, drivers::HapticDevice* device, const RunTickFn& tick, std::atomic<bool>& stop,
                            const RunObserver& observer);

// The run phase of the station: run_periodic() with run_tick(in, rec, cnt, ...). Not RT-safe.
RunPhaseResult run_loop(const StationPlan& plan, const TickInputs& in, TickRecords& rec, TickCounters& cnt, std::atomic<bool>& stop,
                        const RunObserver& observer);

}  // namespace haptic::firmware
