#pragma once
// Periodic loop on absolute CLOCK_MONOTONIC deadlines (clock_nanosleep TIMER_ABSTIME), the
// shape of every real-time tick in the station: the loop owns the timing, user code plugs in as
// a callback `bool tick(const TickInfo&)` (return false to stop). Overruns are detected,
// counted and skipped ahead to the next future deadline (never a burst of catch-up ticks).
// Statistics live in fixed-size members (no allocation). Reporting is throttled: at most one
// LoopReport per report interval is published into a latest-value mailbox
// (platform/latest_mailbox.hpp; the loop is its writer) that a non-RT thread reads with
// take_report(). Stopping is through a std::atomic<bool>.
#include <time.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "platform/latency_histogram.hpp"
#include "platform/latest_mailbox.hpp"
#include "platform/trace.hpp"
#include "platform/clock.hpp"

namespace haptic::platform {

// The real clock. now_ns() and sleep_until_ns() are RT-safe (vDSO read, one syscall).
struct MonotonicClock {
  std::int64_t now_ns() const { return monotonic_ns(); }
  void sleep_until_ns(std::int64_t deadline_ns) const { sleep_until_monotonic_ns(deadline_ns); }
};

struct LoopConfig {
  std::int64_t period_ns = 2'000'000;          // loop.period_ns: 10'000..1'000'000'000
  std::int64_t histogram_bin_ns = 1000;        // loop.histogram_bin_ns: 1..1'000'000
  std::int64_t report_interval_ns = 1'000'000'000;  // loop.report_interval_ns: >= 1 s (throttle)
  std::uint64_t max_ticks = 0;                 // loop.max_ticks: stop after this many ticks; 0 = until stopped
  std::uint32_t overrun_storm_count = 10;      // loop.overrun_storm_count: overruns in one window that make a storm (>= 1)
  std::int64_t overrun_storm_window_ns = 1'000'000'000;  // loop.overrun_storm_window_ns: > 0
};

// Throws std::invalid_argument naming the key and the allowed range. Not RT-safe.
void validate(const LoopConfig& config);

struct TickInfo {
  std::uint64_t index = 0;          // ticks executed before this one (0, 1, 2, ...)
  std::uint64_t cycle = 0;          // period number since start: index + missed cycles so far
  std::int64_t scheduled_ns = 0;    // absolute CLOCK_MONOTONIC deadline of this tick
  std::int64_t wake_ns = 0;         // when the thread actually woke
  std::int64_t wake_latency_ns = 0; // wake_ns - scheduled_ns
  std::int64_t prev_exec_ns = -1;   // previous tick's execution time (-1 on the first tick)
  std::uint64_t overruns = 0;       // overruns so far
  std::uint64_t missed_cycles = 0;  // skipped periods so far
  bool overrun_storm = false;       // true on the tick right after the storm threshold was reached
};

struct LoopStats {
  std::uint64_t ticks = 0;
  std::uint64_t overruns = 0;       // ticks that ended after the next deadline
  std::uint64_t missed_cycles = 0;  // periods skipped because of overruns
  std::uint64_t overrun_storms = 0;
  LatencyHistogram wake_latency;    // wake_ns - scheduled_ns
  LatencyHistogram exec_time;       // callback end - wake
};

// Published at most once per report interval (window = since the previous published report).
struct LoopReport {
  std::uint64_t ticks = 0, overruns = 0, missed_cycles = 0, overrun_storms = 0;  // totals
  std::uint64_t window_ticks = 0, window_overruns = 0;
  std::int64_t window_latency_min_ns = 0, window_latency_max_ns = 0, window_exec_max_ns = 0;
  double window_latency_avg_ns = 0.0;
};
std::string format_report(const LoopReport& report);  // one line; not RT-safe

// Whether the host could not keep the loop's period: it skipped at least 1 % of the periods
// (missed cycles: ticks that overran into the next deadline, or a stall), or the 99th percentile of
// the wake-up latency is a period or more (1 % of the ticks woke when the next deadline was already
// due). The one rule for "a starving host" of the station's report, its live view and the merge.
// RT-safe (arithmetic).
inline bool host_starving(std::uint64_t ticks, std::uint64_t missed_cycles, std::int64_t wake_p99_ns, std::int64_t period_ns) {
  if (ticks == 0) return false;
  return 100 * missed_cycles >= ticks + missed_cycles || wake_p99_ns >= period_ns;
}

template <class Clock = MonotonicClock>
class PeriodicLoop {
 public:
  explicit PeriodicLoop(const LoopConfig& config, Clock clock = Clock{}) : config_(config), clock_(clock) {
    validate(config_);
    stats_.wake_latency.bin_ns = config_.histogram_bin_ns;
    stats_.exec_time.bin_ns = config_.histogram_bin_ns;
  }

  // Runs until tick() returns false, stop becomes true, or max_ticks ticks ran. The first
  // deadline is first_deadline_ns (a grid the caller keeps, e.g. a timeline's ticks) or, when 0,
  // one period from now. RT-safe apart from what tick() does.
  template <class Tick>
  void run(Tick&& tick, const std::atomic<bool>& stop, std::int64_t first_deadline_ns = 0) {
    const std::int64_t period = config_.period_ns;
    std::int64_t next = first_deadline_ns != 0 ? first_deadline_ns : clock_.now_ns() + period;
    std::int64_t prev_exec = -1;
    std::int64_t window_start = next;
    std::int64_t storm_window_start = next;
    std::uint32_t storm_window_overruns = 0;
    bool storm_pending = false;
    window_ = Window{};
    while (!stop.load(std::memory_order_acquire)) {
      clock_.sleep_until_ns(next);
      const std::int64_t wake = clock_.now_ns();
      TickInfo info;
      info.index = stats_.ticks;
      info.cycle = stats_.ticks + stats_.missed_cycles;
      info.scheduled_ns = next;
      info.wake_ns = wake;
      info.wake_latency_ns = wake - next;
      info.prev_exec_ns = prev_exec;
      info.overruns = stats_.overruns;
      info.missed_cycles = stats_.missed_cycles;
      info.overrun_storm = storm_pending;
      storm_pending = false;
      trace::tick_begin(info.index, next, info.wake_latency_ns);
      const bool keep_going = tick(static_cast<const TickInfo&>(info));
      const std::int64_t end = clock_.now_ns();
      const std::int64_t exec = end - wake;
      trace::tick_end(info.index, exec);
      stats_.wake_latency.add(info.wake_latency_ns);
      stats_.exec_time.add(exec);
      window_.add(info.wake_latency_ns, exec);
      ++stats_.ticks;
      prev_exec = exec;

      // Next deadline: one period on; if that is already past, skip ahead to the first future one.
      std::int64_t following = next + period;
      if (end > following) {
        const std::int64_t missed = (end - next) / period;  // deadlines passed while this tick ran
        ++stats_.overruns;
        ++window_.overruns;
        stats_.missed_cycles += static_cast<std::uint64_t>(missed);
        trace::overrun(info.index, static_cast<std::uint64_t>(missed), end - following);
        following = next + (missed + 1) * period;
        if (end - storm_window_start > config_.overrun_storm_window_ns) {
          storm_window_start = end;
          storm_window_overruns = 0;
        }
        if (++storm_window_overruns == config_.overrun_storm_count) {
          ++stats_.overrun_storms;
          storm_pending = true;
        }
      }
      if (regrid_ns_ != kNoRegrid) {  // move_grid(): the next deadline on the new grid, the first one after this tick
        following = regrid_ns_ > end ? regrid_ns_ : regrid_ns_ + ((end - regrid_ns_) / period + 1) * period;
        regrid_ns_ = kNoRegrid;
      }
      next = following;

      if (end - window_start >= config_.report_interval_ns) {
        publish_report();
        window_start = end;
        window_ = Window{};
      }
      if (!keep_going || (config_.max_ticks != 0 && stats_.ticks >= config_.max_ticks)) break;
    }
    publish_report();
  }

  // Called from tick(): the loop moves onto the grid through deadline_ns (its deadlines become
  // deadline_ns + m period), the next deadline being the first of them after this tick ends, for a
  // station that learns another epoch while its loop runs (a rejoin). The move is no overrun and
  // skips no counted cycle. RT-safe.
  void move_grid(std::int64_t deadline_ns) { regrid_ns_ = deadline_ns; }

  // Totals. Read from the loop's thread, or from any thread after run() returned.
  const LoopStats& stats() const { return stats_; }
  const LoopConfig& config() const { return config_; }
  Clock& clock() { return clock_; }

  // Reader side of the report mailbox (one non-RT thread): copies the newest unread report,
  // returns false when there is none. Never blocks the loop; an unread older report is replaced
  // by the newer one. Wait-free.
  bool take_report(LoopReport& out) { return reports_.reader_take(out); }

 private:
  struct Window {
    std::uint64_t ticks = 0, overruns = 0;
    std::int64_t lat_min = 0, lat_max = 0, lat_sum = 0, exec_max = 0;
    void add(std::int64_t lat, std::int64_t exec) {
      if (ticks == 0 || lat < lat_min) lat_min = lat;
      if (ticks == 0 || lat > lat_max) lat_max = lat;
      if (exec > exec_max) exec_max = exec;
      lat_sum += lat;
      ++ticks;
    }
  };

  // Writer side of the report mailbox (the loop's thread). Wait-free, RT-safe.
  void publish_report() {
    LoopReport r;
    r.ticks = stats_.ticks;
    r.overruns = stats_.overruns;
    r.missed_cycles = stats_.missed_cycles;
    r.overrun_storms = stats_.overrun_storms;
    r.window_ticks = window_.ticks;
    r.window_overruns = window_.overruns;
    r.window_latency_min_ns = window_.lat_min;
    r.window_latency_max_ns = window_.lat_max;
    r.window_exec_max_ns = window_.exec_max;
    r.window_latency_avg_ns = window_.ticks ? static_cast<double>(window_.lat_sum) / static_cast<double>(window_.ticks) : 0.0;
    reports_.writer_publish(r);
  }

  static constexpr std::int64_t kNoRegrid = INT64_MIN;
  LoopConfig config_;
  Clock clock_;
  LoopStats stats_;
  std::int64_t regrid_ns_ = kNoRegrid;
  Window window_;
  LatestMailbox<LoopReport> reports_;
};

}  // namespace haptic::platform
