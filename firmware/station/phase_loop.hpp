#pragma once
// The periodic loop a phase of the station runs on (probe, run): a platform::PeriodicLoop over the
// ticks of one phase of the timeline (timeline.hpp), each deadline's tick index by the timeline's
// one rule. RT-safe apart from what `tick` does (the run phase's is; the probe's is not).
#include <atomic>
#include <cstdint>

#include "firmware/station/timeline.hpp"
#include "platform/periodic_loop.hpp"

namespace haptic::firmware {

// Sleeps until the loop can start the phase at tick k_first (Timeline::loop_start_ns: a loop
// started late joins the grid), then calls tick(k, info) at every deadline whose tick k
// (Timeline::tick_at) is not past `phase`, until tick returns false or `stop`.
template <class Tick>
void run_phase(const Timeline& t, TickPhase phase, std::int64_t k_first, platform::PeriodicLoop<>& loop, Tick&& tick,
               const std::atomic<bool>& stop) {
  loop.clock().sleep_until_ns(t.loop_start_ns(k_first, loop.clock().now_ns()));
  loop.run(
      [&](const platform::TickInfo& info) -> bool {
        const std::int64_t k = t.tick_at(info.scheduled_ns);  // = k_first + info.cycle when on time
        if (k < k_first) return true;  // woke before the phase's first tick: not the phase's yet
        if (t.phase_of(k) > phase) return false;
        return tick(k, info);
      },
      stop);
}

}  // namespace haptic::firmware
