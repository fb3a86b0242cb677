#pragma once
// The station's one periodic loop (DESIGN.md, "The station process"): one platform::RtThread and
// one platform::PeriodicLoop run every tick of the station's timeline (timeline.hpp), from the first
// probing tick to the last run tick. What a tick does is its stage's: probe (or a rejoining
// station's provisional probes), then run; the non-RT side hands the next stage over once the one
// before it has ended and whatever the next one needs is built (the core is built on the calling
// thread while the loop keeps the grid with empty set-up ticks). Each tick index comes from the
// timeline's one time-to-tick rule; a stage on a timeline with another epoch (a rejoin learns the
// session's) moves the loop onto that grid (PeriodicLoop::move_grid). One catch at the loop boundary
// (around PeriodicLoop::run inside the RtThread body): an exception ends the loop and enters the safe
// state (zero force to the device); the non-RT side reports it.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <semaphore>
#include <string>
#include <vector>

#include "drivers/device.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/tick.hpp"
#include "firmware/station/timeline.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/rt_thread.hpp"

namespace haptic::firmware {

// A stage's share of the loop's counters (its ticks, overruns, missed cycles, overrun storms).
struct LoopCounts {
  std::uint64_t ticks = 0, overruns = 0, missed_cycles = 0, overrun_storms = 0;
};

struct RunPhaseResult {
  PhaseStatus status = PhaseStatus::kFailed;
  std::string message;
  LoopCounts loop{};                 // the run stage's share of the loop
  platform::LoopStats whole_loop{};  // the loop's own statistics, probe to run (wake-up latency and execution histograms)
  std::string rt_summary;
  std::vector<std::string> rt_warnings;
  std::int64_t first_run_k = -1;     // epoch index of the first run tick (-1: none ran)
  std::int64_t last_run_k = -1;      // epoch index of the last run tick (-1: none ran; skipped periods are not ticks)
  bool loop_exception = false;       // the loop boundary caught an exception: safe state latched
  std::string loop_exception_what;   // its message (copied on the non-RT side)
  bool stopped_by_signal = false;
};

// Safe state after a caught exception: zero force to the device. RT-safe, never throws.
void enter_safe_state(drivers::HapticDevice* device) noexcept;

// What the non-RT side hears while the loop runs (any may be empty). Called on the thread that
// waits on the loop, never on the RT thread.
struct RunObserver {
  std::function<void(const std::string& rt_summary, const std::vector<std::string>& rt_warnings)> rt_ready;  // after the RT set-up
  std::function<void(const platform::LoopReport&)> report;  // the loop's throttled reports
  std::function<void()> idle;  // every 100 ms while the caller waits (non-RT monitoring, e.g. neighbour events)
};

// One stage of the loop: the ticks k >= k_first of `timeline` whose phase is at most `last_phase`
// (kBefore ticks included: a probe stage watches before the epoch). `tick` returning false ends the
// stage early. Called on the RT thread; a run stage's tick must be RT-safe.
using StageTickFn = std::function<bool(std::int64_t k, const platform::TickInfo& info)>;
struct LoopStage {
  Timeline timeline;
  TickPhase last_phase = TickPhase::kRun;
  std::int64_t k_first = 0;
  StageTickFn tick;
  bool new_grid = false;   // the timeline's epoch is not the loop's grid yet: move the loop onto it
  bool ends_loop = false;  // the loop ends with this stage (the run)
};

// What one stage of the loop did (read after StationLoop::wait_stage returned).
struct StageOutcome {
  bool ended = false;          // its last tick ran (or its tick ended it)
  bool ran = false;            // at least one of its ticks ran: then first_k, last_k (may be < 0: before the epoch)
  std::int64_t first_k = -1;
  std::int64_t last_k = -1;
  LoopCounts counts{};         // the loop's counters over the stage's ticks
};

class StationLoop {
 public:
  static constexpr int kMaxStages = 4;  // probe, (rejoin's provisional probes), run; and a spare
  // The RT thread (plan.file.rt) and the loop (plan.file.loop); `device` gets zero force on an
  // exception at the loop boundary (may be null). Nothing runs until start().
  StationLoop(const StationPlan& plan, drivers::HapticDevice* device, const std::atomic<bool>& stop);
  ~StationLoop();  // ends the loop and joins
  StationLoop(const StationLoop&) = delete;
  StationLoop& operator=(const StationLoop&) = delete;

  // Creates the RT thread, which sleeps until the first stage's first tick (its timeline's rule:
  // a loop that starts late joins the grid) and runs it. Throws on a refused RT set-up
  // (rt.require_rt), with the set-up's message. Not RT-safe.
  void start(LoopStage first, const RunObserver& observer);
  // Hands the next stage over; the loop takes it at its first tick after the current stage ended
  // (set-up ticks until then). Returns its index. Not RT-safe.
  int hand_over(LoopStage next);
  // Waits until stage `index` ended (true) or the loop ended (false), serving `observer` every
  // 100 ms (or the loop's report interval, if shorter). Not RT-safe.
  bool wait_stage(int index, const RunObserver& observer);
  // Ends the loop after its current tick (a phase on the non-RT side failed, or no stage follows)
  // and waits for the RT thread. Idempotent. Not RT-safe.
  void finish();
  // Waits until the loop ended by itself (its last stage ran out, `stop`, or an exception), then
  // what the run stage `run_index` did. Not RT-safe.
  RunPhaseResult run_result(int run_index, const RunObserver& observer);

  const StageOutcome& stage(int index) const { return outcomes_[index]; }
  bool loop_ended() const { return ended_.load(std::memory_order_acquire); }

 private:
  bool on_tick(const platform::TickInfo& info);
  void body();
  void serve(const RunObserver& observer);
  std::chrono::nanoseconds serve_interval() const;
  LoopCounts share_since(const LoopCounts& start) const;

  const StationPlan& plan_;
  drivers::HapticDevice* device_;
  const std::atomic<bool>& stop_;
  platform::PeriodicLoop<> loop_;
  LoopStage stages_[kMaxStages];
  StageOutcome outcomes_[kMaxStages];
  std::atomic<int> published_{0};     // stages handed over (the RT thread reads it)
  int current_ = 0;                   // the stage the loop runs (RT thread only)
  bool current_done_ = false;         // ... has ended; set-up ticks until the next is handed over
  std::atomic<int> stages_ended_{0};  // stages whose outcome is written (they end in order)
  std::atomic<bool> abort_{false};
  std::atomic<bool> ended_{false};
  std::counting_semaphore<64> events_{0};  // a stage ended, or the loop ended
  bool exception_ = false;
  char what_[256] = {};
  std::string rt_summary_;
  std::vector<std::string> rt_warnings_;
  std::unique_ptr<platform::RtThread> thread_;
};

// One run tick at epoch index k = run_k0 + kr (run_tick() in the station). Called on the RT thread.
using RunTickFn = std::function<void(std::int64_t k, std::int64_t kr, const platform::TickInfo& info)>;

// The run stage of `plan`'s timeline: `tick` at every run tick from run_k0 (or, for a stage
// handed over late, the next tick of the grid) to the end of the run, until `stop`. new_grid: the
// loop is not on the run's grid yet (a rejoining station that learned the session's epoch).
LoopStage run_stage(const StationPlan& plan, const RunTickFn& tick, const std::atomic<bool>& stop, bool new_grid);

// A loop whose only stage is the run (tests; a station's run goes through run_station): the RT
// thread waits for the run epoch (a station already past it: the next tick of the session's grid)
// and runs `tick` until run_ticks or `stop`. Not RT-safe (owns the RT thread).
RunPhaseResult run_periodic(const StationPlan& plan, drivers::HapticDevice* device, const RunTickFn& tick, std::atomic<bool>& stop,
                            const RunObserver& observer);

}  // namespace haptic::firmware
