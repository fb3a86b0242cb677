#include "firmware/station/loop.hpp"

#include <chrono>
#include <cstring>
#include <exception>
#include <semaphore>

#include "firmware/station/phase_loop.hpp"
#include "platform/rt_thread.hpp"

namespace haptic::firmware {

namespace {

// What the RT thread leaves for the non-RT side (written before `done` is released).
struct LoopOutcome {
  std::int64_t first_run_k = -1;
  std::int64_t last_kr = -1;
  bool exception = false;
  char what[256] = {};
  platform::LoopStats stats{};
};

// The RtThread body: wait for the run epoch, run the loop; the one catch of the run phase.
void loop_body(const StationPlan& plan, drivers::HapticDevice* device, const RunTickFn& tick, platform::PeriodicLoop<>& loop,
               std::atomic<bool>& stop, LoopOutcome& out) {
  const StationTimes& t = plan.times;
  try {
    // From kr = 0, or for a station past the run start (rejoining) the next tick of the session's
    // grid, to the end of the run.
    run_phase(
        t, TickPhase::kRun, t.run_k0, loop,
        [&](std::int64_t k, const platform::TickInfo& info) -> bool {
          const std::int64_t kr = k - t.run_k0;
          if (out.first_run_k < 0) out.first_run_k = k;
          out.last_kr = kr;
          tick(k, kr, info);
          return !stop.load(std::memory_order_acquire);
        },
        stop);
  } catch (const std::exception& e) {
    enter_safe_state(device);
    out.exception = true;
    std::strncpy(out.what, e.what(), sizeof out.what - 1);
  } catch (...) {
    enter_safe_state(device);
    out.exception = true;
    std::strncpy(out.what, "unknown exception", sizeof out.what - 1);
  }
  out.stats = loop.stats();
}

}  // namespace

void enter_safe_state(drivers::HapticDevice* device) noexcept {
  if (device == nullptr) return;
  const double zero[3] = {0, 0, 0};
  try {
    device->command_force(zero);
  } catch (...) {  // the device's own safe state (a latched fault) zeroes every force it sends
  }
}

RunPhaseResult run_periodic(const StationPlan& plan, drivers::HapticDevice* device, const RunTickFn& tick, std::atomic<bool>& stop,
                            const RunObserver& observer) {
  RunPhaseResult r;
  platform::PeriodicLoop<> loop(plan.file.loop);
  LoopOutcome out;
  std::binary_semaphore done(0);
  try {
    platform::RtThread rt_thread(plan.file.rt, [&](const platform::RtReport&) {
      loop_body(plan, device, tick, loop, stop, out);
      done.release();
    });
    r.rt_summary = rt_thread.setup_summary();
    r.rt_warnings = rt_thread.setup_warnings();
    if (observer.rt_ready) observer.rt_ready(r.rt_summary, r.rt_warnings);
    const auto interval = std::min<std::chrono::nanoseconds>(std::chrono::nanoseconds(plan.file.loop.report_interval_ns),
                                                             std::chrono::milliseconds(100));
    platform::LoopReport rep;
    while (!done.try_acquire_for(interval)) {
      if (observer.report && loop.take_report(rep)) observer.report(rep);
      if (observer.idle) observer.idle();
    }
    rt_thread.join();
  } catch (const std::exception& e) {  // RtThread set-up refused (rt.require_rt)
    r.status = PhaseStatus::kFailed;
    r.message = std::string("real-time set-up: ") + e.what();
    return r;
  }
  r.loop = out.stats;
  r.first_run_k = out.first_run_k;
  r.loop_exception = out.exception;
  r.loop_exception_what = out.what;
  r.stopped_by_signal = stop.load(std::memory_order_acquire) && out.last_kr + 1 < plan.times.run_ticks;
  if (r.loop_exception) {
    r.status = PhaseStatus::kFailed;
    r.message = "the run loop caught an exception (safe state: zero force): " + r.loop_exception_what;
  } else {
    r.status = r.stopped_by_signal ? PhaseStatus::kStopped : PhaseStatus::kOk;
  }
  return r;
}

RunPhaseResult run_loop(const StationPlan& plan, const TickInputs& in, TickRecords& rec, TickCounters& cnt, std::atomic<bool>& stop,
                        const RunObserver& observer) {
  const RunTickFn tick = [&](std::int64_t k, std::int64_t kr, const platform::TickInfo& info) { run_tick(in, rec, cnt, k, kr, info); };
  return run_periodic(plan, in.device, tick, stop, observer);
}

}  // namespace haptic::firmware
