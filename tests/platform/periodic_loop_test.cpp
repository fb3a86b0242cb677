// Periodic loop: absolute deadlines, overrun detection with skip-ahead (no catch-up bursts),
// storm flag, stop via atomic, throttled reports, and no allocation in the per-tick path.
#include <time.h>

#include <atomic>
#include <memory>
#include <vector>

#include "platform/periodic_loop.hpp"
#include "platform/telemetry.hpp"
#include "tests/support/alloc_counter.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

using haptic::platform::LoopConfig;
using haptic::platform::LoopReport;
using haptic::platform::MonotonicClock;
using haptic::platform::PeriodicLoop;
using haptic::platform::TickInfo;

namespace {

// Deterministic clock: sleeping jumps to the deadline plus a fixed wake-up latency; the test's
// callback "runs" by advancing the time.
struct FakeClock {
  std::int64_t* now = nullptr;
  std::int64_t wake_latency_ns = 0;
  std::int64_t now_ns() const { return *now; }
  void sleep_until_ns(std::int64_t deadline) const {
    if (*now < deadline) *now = deadline + wake_latency_ns;
  }
};

constexpr std::int64_t kPeriod = 1'000'000;

struct Recorded {
  std::int64_t scheduled = 0, wake = 0, latency = 0, prev_exec = 0;
  std::uint64_t cycle = 0;
  bool storm = false;
};

}  // namespace

TEST_GROUP(PeriodicLoop) {
  std::int64_t now = 5'000'000'000;
  FakeClock clock{&now, 20'000};
  std::atomic<bool> stop{false};
  LoopConfig config;
  void setup() override {
    config.period_ns = kPeriod;
  }
};

TEST(PeriodicLoop, ticks_land_on_absolute_deadlines) {
  config.max_ticks = 10;
  PeriodicLoop<FakeClock> loop(config, clock);
  const std::int64_t start = now;
  std::vector<Recorded> seen;
  loop.run([&](const TickInfo& t) { seen.push_back({t.scheduled_ns, t.wake_ns, t.wake_latency_ns, t.prev_exec_ns, t.cycle, t.overrun_storm}); now += 100'000; return true; }, stop);
  LONGS_EQUAL(10, seen.size());
  for (std::size_t k = 0; k < seen.size(); ++k) {
    LONGS_EQUAL(start + static_cast<std::int64_t>(k + 1) * kPeriod, seen[k].scheduled);
    LONGS_EQUAL(20'000, seen[k].latency);
    LONGS_EQUAL(k, seen[k].cycle);
    LONGS_EQUAL(k == 0 ? -1 : 100'000, seen[k].prev_exec);
  }
  LONGS_EQUAL(10, loop.stats().ticks);
  LONGS_EQUAL(0, loop.stats().overruns);
  LONGS_EQUAL(20'000, loop.stats().wake_latency.max_ns);
  LONGS_EQUAL(100'000, loop.stats().exec_time.max_ns);
}

TEST(PeriodicLoop, overrun_is_counted_and_skipped_ahead_without_a_burst) {
  config.max_ticks = 10;
  PeriodicLoop<FakeClock> loop(config, clock);
  std::vector<Recorded> seen;
  loop.run([&](const TickInfo& t) {
    seen.push_back({t.scheduled_ns, t.wake_ns, t.wake_latency_ns, t.prev_exec_ns, t.cycle, t.overrun_storm});
    now += (t.index == 3) ? 2 * kPeriod + kPeriod / 2 : 100'000;  // tick 3 "sleeps" 2.5 periods
    return true;
  }, stop);
  LONGS_EQUAL(10, loop.stats().ticks);
  LONGS_EQUAL(1, loop.stats().overruns);
  LONGS_EQUAL(2, loop.stats().missed_cycles);  // the deadlines at +1T and +2T were skipped
  LONGS_EQUAL(seen[3].scheduled + 3 * kPeriod, seen[4].scheduled);
  LONGS_EQUAL(seen[3].cycle + 3, seen[4].cycle);
  // No burst: every tick after the overrun woke at its own (future) deadline, one period apart.
  for (std::size_t k = 4; k < seen.size(); ++k) LONGS_EQUAL(20'000, seen[k].latency);
  for (std::size_t k = 5; k < seen.size(); ++k) LONGS_EQUAL(kPeriod, seen[k].scheduled - seen[k - 1].scheduled);
}

TEST(PeriodicLoop, late_wake_up_past_the_next_deadline_is_an_overrun_too) {
  config.max_ticks = 3;
  clock.wake_latency_ns = kPeriod + kPeriod / 4;  // every wake-up 1.25 periods late
  PeriodicLoop<FakeClock> loop(config, clock);
  loop.run([&](const TickInfo&) { return true; }, stop);
  LONGS_EQUAL(3, loop.stats().overruns);
  LONGS_EQUAL(3, loop.stats().missed_cycles);
}

TEST(PeriodicLoop, overrun_storm_is_flagged_on_the_next_tick) {
  config.max_ticks = 8;
  config.overrun_storm_count = 3;
  PeriodicLoop<FakeClock> loop(config, clock);
  std::vector<bool> storm;
  loop.run([&](const TickInfo& t) { storm.push_back(t.overrun_storm); now += kPeriod + kPeriod / 2; return true; }, stop);
  LONGS_EQUAL(8, loop.stats().overruns);
  LONGS_EQUAL(1, loop.stats().overrun_storms);  // window of 1 s never rolls over in 8 ticks
  for (std::size_t k = 0; k < storm.size(); ++k) CHECK_EQUAL(k == 3, storm[k]);
}

TEST(PeriodicLoop, stops_through_the_atomic_flag_and_the_callback_result) {
  PeriodicLoop<FakeClock> loop(config, clock);
  loop.run([&](const TickInfo& t) { if (t.index == 5) stop.store(true, std::memory_order_release); return true; }, stop);
  LONGS_EQUAL(6, loop.stats().ticks);
  stop.store(false);
  PeriodicLoop<FakeClock> loop2(config, clock);
  loop2.run([&](const TickInfo& t) { return t.index < 2; }, stop);
  LONGS_EQUAL(3, loop2.stats().ticks);
}

TEST(PeriodicLoop, reports_are_throttled_to_one_per_interval) {
  config.max_ticks = 2500;  // 2.5 s of 1 ms ticks
  auto loop = std::make_unique<PeriodicLoop<FakeClock>>(config, clock);
  std::vector<LoopReport> reports;
  loop->run([&](const TickInfo&) {
    LoopReport r;
    if (loop->take_report(r)) reports.push_back(r);
    return true;
  }, stop);
  LONGS_EQUAL(2, reports.size());  // after 1 s and 2 s; the final one is still in the box
  CHECK(reports[0].window_ticks >= 999 && reports[0].window_ticks <= 1001);
  LONGS_EQUAL(20'000, reports[0].window_latency_max_ns);
  LoopReport last;
  CHECK(loop->take_report(last));
  LONGS_EQUAL(2500, last.ticks);
  CHECK_FALSE(loop->take_report(last));
}

TEST(PeriodicLoop, bad_configuration_names_the_key) {
  config.period_ns = 5;
  try {
    PeriodicLoop<FakeClock> loop(config, clock);
    FAIL("no exception for loop.period_ns = 5");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("loop.period_ns", e.what());
  }
}

TEST(PeriodicLoop, per_tick_path_does_not_allocate) {
  CHECK_TEXT(haptic::test::allocation_counter_works(), "allocation counter is not interposed in this binary");
  config.max_ticks = 3000;
  config.overrun_storm_count = 2;
  auto loop = std::make_unique<PeriodicLoop<FakeClock>>(config, clock);
  haptic::platform::TelemetryConfig tc;
  tc.postmortem_dir = "/tmp";
  auto telemetry = std::make_unique<haptic::platform::Telemetry>(tc);
  std::uint64_t allocations = 0;
  {
    haptic::test::AllocationCounter counter;
    loop->run([&](const TickInfo& t) {
      haptic::platform::TelemetryRecord rec;
      rec.tick = t.index;
      telemetry->record(rec);
      LoopReport r;
      loop->take_report(r);
      now += (t.index % 100 == 0) ? 2 * kPeriod : 50'000;  // overruns and storms on the way
      return true;
    }, stop);
    allocations = counter.allocations();
  }
  LONGS_EQUAL(3000, loop->stats().ticks);
  CHECK(loop->stats().overruns >= 30);
  LONGS_EQUAL(0, allocations);
}

TEST(PeriodicLoop, real_clock_tick_sleeping_past_the_deadline_skips_ahead) {
  constexpr std::int64_t period = 2'000'000;
  LoopConfig c;
  c.period_ns = period;
  c.max_ticks = 20;
  PeriodicLoop<> loop(c);
  std::vector<Recorded> seen;
  std::vector<std::int64_t> end_ns;
  seen.reserve(32);
  end_ns.reserve(32);
  haptic::test::AllocationCounter counter;
  loop.run([&](const TickInfo& t) {
    seen.push_back({t.scheduled_ns, t.wake_ns, t.wake_latency_ns, t.prev_exec_ns, t.cycle, false});
    if (t.index == 8) {
      timespec ts{0, 5'000'000};  // 2.5 periods
      nanosleep(&ts, nullptr);
    }
    end_ns.push_back(MonotonicClock{}.now_ns());
    return true;
  }, stop);
  LONGS_EQUAL(0, counter.allocations());
  LONGS_EQUAL(20, loop.stats().ticks);
  CHECK(loop.stats().overruns >= 1);
  CHECK(loop.stats().missed_cycles >= 2);
  // Skip-ahead: the tick after the sleeper is scheduled at least 3 periods later, on the grid.
  const std::int64_t gap = seen[9].scheduled - seen[8].scheduled;
  CHECK(gap >= 3 * period);
  LONGS_EQUAL(0, gap % period);
  // Never a burst: every deadline was in the future when the previous tick ended.
  for (std::size_t k = 1; k < seen.size(); ++k) CHECK(seen[k].scheduled > end_ns[k - 1]);
}
