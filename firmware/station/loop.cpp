#include "firmware/station/loop.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <exception>

namespace haptic::firmware {

namespace {

LoopCounts counts_of(const platform::LoopStats& s) { return {s.ticks, s.overruns, s.missed_cycles, s.overrun_storms}; }

}  // namespace

void enter_safe_state(drivers::HapticDevice* device) noexcept {
  if (device == nullptr) return;
  const double zero[3] = {0, 0, 0};
  try {
    device->command_force(zero);
  } catch (...) {  // the device's own safe state (a latched fault) zeroes every force it sends
  }
}

StationLoop::StationLoop(const StationPlan& plan, drivers::HapticDevice* device, const std::atomic<bool>& stop)
    : plan_(plan), device_(device), stop_(stop), loop_(plan.file.loop) {}

StationLoop::~StationLoop() { finish(); }

void StationLoop::start(LoopStage first, const RunObserver& observer) {
  stages_[0] = std::move(first);
  published_.store(1, std::memory_order_release);
  thread_ = std::make_unique<platform::RtThread>(plan_.file.rt, [this](const platform::RtReport&) { body(); });
  rt_summary_ = thread_->setup_summary();
  rt_warnings_ = thread_->setup_warnings();
  if (observer.rt_ready) observer.rt_ready(rt_summary_, rt_warnings_);
}

int StationLoop::hand_over(LoopStage next) {
  const int i = published_.load(std::memory_order_relaxed);
  if (i >= kMaxStages) throw std::logic_error("StationLoop: more than kMaxStages stages");
  stages_[i] = std::move(next);
  published_.store(i + 1, std::memory_order_release);
  return i;
}

// The loop's counters since `start` (a stage's share). The loop's thread, or after the loop ended.
LoopCounts StationLoop::share_since(const LoopCounts& start) const {
  const LoopCounts now = counts_of(loop_.stats());
  return {now.ticks - start.ticks, now.overruns - start.overruns, now.missed_cycles - start.missed_cycles, now.overrun_storms - start.overrun_storms};
}

// The RT thread: the loop from the first stage's first tick; the loop-boundary catch.
void StationLoop::body() {
  // The first deadline is the first stage's first tick (a loop that starts late: the next tick of the
  // grid at least one period ahead), and every deadline after it is on the timeline's grid.
  const Timeline& t = stages_[0].timeline;
  const std::int64_t first_deadline = t.time_of(t.first_tick_from(stages_[0].k_first, loop_.clock().now_ns()));
  try {
    loop_.run([this](const platform::TickInfo& info) { return on_tick(info); }, stop_, first_deadline);
  } catch (const std::exception& e) {
    enter_safe_state(device_);
    exception_ = true;
    std::strncpy(what_, e.what(), sizeof what_ - 1);
  } catch (...) {
    enter_safe_state(device_);
    exception_ = true;
    std::strncpy(what_, "unknown exception", sizeof what_ - 1);
  }
  StageOutcome& o = outcomes_[current_];
  if (!current_done_ && o.ran) o.counts = share_since(o.counts);  // ended by stop or an exception
  ended_.store(true, std::memory_order_release);
  events_.release();
}

// One deadline of the loop: a tick of the current stage, or a set-up tick between two stages. RT-safe
// apart from what a stage's tick does.
bool StationLoop::on_tick(const platform::TickInfo& info) {
  if (abort_.load(std::memory_order_acquire)) return false;
  if (current_done_) {
    const Timeline& t = stages_[current_].timeline;
    if (current_ + 1 >= published_.load(std::memory_order_acquire))  // nothing handed over yet: a set-up tick
      return t.phase_of(t.tick_at(info.scheduled_ns)) != TickPhase::kAfter;
    ++current_;
    current_done_ = false;
    const LoopStage& s = stages_[current_];
    if (s.new_grid) {  // onto the new timeline's grid: its next tick at least one period from now
      loop_.move_grid(s.timeline.time_of(s.timeline.first_tick_from(s.k_first, loop_.clock().now_ns())));
      return true;
    }
  }
  const LoopStage& s = stages_[current_];
  StageOutcome& o = outcomes_[current_];
  const std::int64_t k = s.timeline.tick_at(info.scheduled_ns);  // the one time-to-tick rule
  if (k < s.k_first) return true;
  bool more = s.timeline.phase_of(k) <= s.last_phase;
  if (more) {
    if (!o.ran) {
      o.ran = true;
      o.first_k = k;
      o.counts = counts_of(loop_.stats());  // the stage's start; its share at the end
    }
    o.last_k = k;
    more = s.tick(k, info);
  }
  if (more) return true;
  o.counts = o.ran ? share_since(o.counts) : LoopCounts{};
  o.ended = true;
  current_done_ = true;
  stages_ended_.store(current_ + 1, std::memory_order_release);
  events_.release();
  return !s.ends_loop;
}

// How long the non-RT side waits between two serve() calls: 100 ms, or the loop's report interval if shorter.
std::chrono::nanoseconds StationLoop::serve_interval() const {
  return std::min<std::chrono::nanoseconds>(std::chrono::nanoseconds(plan_.file.loop.report_interval_ns), std::chrono::milliseconds(100));
}

void StationLoop::serve(const RunObserver& observer) {
  platform::LoopReport rep;
  if (observer.report && loop_.take_report(rep)) observer.report(rep);
  if (observer.idle) observer.idle();
}

bool StationLoop::wait_stage(int index, const RunObserver& observer) {
  for (;;) {
    if (stages_ended_.load(std::memory_order_acquire) > index) return true;
    if (ended_.load(std::memory_order_acquire)) return stages_ended_.load(std::memory_order_acquire) > index;
    events_.try_acquire_for(serve_interval());
    serve(observer);
  }
}

void StationLoop::finish() {
  abort_.store(true, std::memory_order_release);
  if (thread_) thread_->join();
}

RunPhaseResult StationLoop::run_result(int run_index, const RunObserver& observer) {
  RunPhaseResult r;
  r.rt_summary = rt_summary_;
  r.rt_warnings = rt_warnings_;
  while (!ended_.load(std::memory_order_acquire)) {
    events_.try_acquire_for(serve_interval());
    serve(observer);
  }
  if (thread_) thread_->join();
  const StageOutcome& o = outcomes_[run_index];
  r.loop = o.counts;
  r.whole_loop = loop_.stats();
  r.first_run_k = o.ran ? o.first_k : -1;
  r.last_run_k = o.ran ? o.last_k : -1;
  r.loop_exception = exception_;
  r.loop_exception_what = what_;
  const Timeline& t = stages_[run_index].timeline;
  r.stopped_by_signal = stop_.load(std::memory_order_acquire) && (!o.ran || o.last_k + 1 < t.run_end_k());
  if (r.loop_exception) {
    r.status = PhaseStatus::kFailed;
    r.message = "the run loop caught an exception (safe state: zero force): " + r.loop_exception_what;
  } else if (r.stopped_by_signal) {
    r.status = PhaseStatus::kStopped;
  } else if (!o.ran) {
    r.status = PhaseStatus::kFailed;
    r.message = "no run tick ran: the run's ticks had passed when the core was handed to the loop";
  } else {
    r.status = PhaseStatus::kOk;
  }
  return r;
}

LoopStage run_stage(const StationPlan& plan, const RunTickFn& tick, const std::atomic<bool>& stop, bool new_grid) {
  LoopStage s;
  s.timeline = plan.times;
  s.last_phase = TickPhase::kRun;
  s.k_first = plan.times.run_k0;
  s.new_grid = new_grid;
  s.ends_loop = true;
  const std::int64_t run_k0 = plan.times.run_k0;
  s.tick = [&tick, &stop, run_k0](std::int64_t k, const platform::TickInfo& info) {
    tick(k, k - run_k0, info);
    return !stop.load(std::memory_order_acquire);
  };
  return s;
}

RunPhaseResult run_periodic(const StationPlan& plan, drivers::HapticDevice* device, const RunTickFn& tick, std::atomic<bool>& stop,
                            const RunObserver& observer) {
  StationLoop loop(plan, device, stop);
  try {
    loop.start(run_stage(plan, tick, stop, false), observer);
  } catch (const std::exception& e) {  // RtThread set-up refused (rt.require_rt)
    RunPhaseResult r;
    r.status = PhaseStatus::kFailed;
    r.message = std::string("real-time set-up: ") + e.what();
    return r;
  }
  return loop.run_result(0, observer);
}

}  // namespace haptic::firmware
