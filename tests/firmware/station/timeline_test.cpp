// The station's one timeline (firmware/station/timeline.hpp): the time-to-tick rule probe, rejoin
// and run share, the phases on the common tick index, where a periodic loop starts, and the loop
// each phase runs on.
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <vector>

#include "firmware/station/phase_loop.hpp"
#include "firmware/station/timeline.hpp"
#include "platform/clock.hpp"

using namespace haptic::firmware;
namespace platform = haptic::platform;

namespace {
Timeline paper_timeline() {
  Timeline t;
  t.epoch_ns = 1'000'000'000'000;
  t.period_ns = 2'000'000;
  t.probe_ticks = 750;
  t.run_k0 = 1000;
  t.run_ticks = 10'000;
  return t;
}
}  // namespace

TEST_GROUP(Timeline){};

TEST(Timeline, a_deadline_on_the_grid_or_less_than_half_a_period_late_is_its_tick) {
  const Timeline t = paper_timeline();
  for (std::int64_t k : {0L, 1L, 749L, 750L, 1000L, 10999L}) {
    LONGS_EQUAL(k, t.tick_at(t.time_of(k)));
    LONGS_EQUAL(k, t.tick_at(t.time_of(k) + t.period_ns / 2 - 1));
    LONGS_EQUAL(k + 1, t.tick_at(t.time_of(k) + t.period_ns / 2));
    LONGS_EQUAL(k, t.tick_at(t.time_of(k) - t.period_ns / 2 + 1));
  }
  LONGS_EQUAL(t.time_of(t.run_k0), t.run_epoch_ns());
}

TEST(Timeline, probe_setup_and_run_partition_the_common_tick_index) {
  const Timeline t = paper_timeline();
  CHECK(t.phase_of(-1) == TickPhase::kBefore);
  CHECK(t.phase_of(0) == TickPhase::kProbe);
  CHECK(t.phase_of(t.probe_ticks - 1) == TickPhase::kProbe);
  CHECK(t.phase_of(t.probe_ticks) == TickPhase::kSetup);
  CHECK(t.phase_of(t.run_k0 - 1) == TickPhase::kSetup);
  CHECK(t.phase_of(t.run_k0) == TickPhase::kRun);
  CHECK(t.phase_of(t.run_end_k() - 1) == TickPhase::kRun);
  CHECK(t.phase_of(t.run_end_k()) == TickPhase::kAfter);
}

TEST(Timeline, a_loop_started_in_time_runs_its_phase_from_the_first_tick_and_a_late_one_joins_the_grid_a_period_ahead) {
  const Timeline t = paper_timeline();
  const std::int64_t P = t.period_ns;
  // in good time (the run after the set-up gap): the first tick, the loop sleeping until a period before it
  LONGS_EQUAL(t.run_k0, t.first_tick_from(t.run_k0, t.time_of(t.run_k0) - 40 * P));
  LONGS_EQUAL(t.time_of(t.run_k0 - 1), t.loop_start_ns(t.run_k0, t.time_of(t.run_k0) - 40 * P));
  // just past one period before it (probing, right after watching for a running session until then):
  // the loop's first deadline is within half a period of the first tick, still that tick
  LONGS_EQUAL(0, t.first_tick_from(0, t.time_of(-1) + 50'000));
  LONGS_EQUAL(0, t.first_tick_from(0, t.time_of(-1) + P / 2));
  // late (a rejoining station): a tick of the grid at least one period after now
  for (std::int64_t late_ns : {P / 2 + 1, P, 10 * P + 3 * P / 10, 5000 * P + P - 1}) {
    const std::int64_t now = t.time_of(t.run_k0 - 1) + late_ns;
    const std::int64_t k = t.first_tick_from(t.run_k0, now);
    CHECK(k > t.run_k0);
    CHECK(t.time_of(k) >= now + P);
    CHECK(t.time_of(k) < now + 3 * P);
    LONGS_EQUAL(t.time_of(k - 1), t.loop_start_ns(t.run_k0, now));
  }
}

TEST(Timeline, a_phase_loop_ticks_its_phase_on_the_grid_and_ends_with_it) {
  Timeline t;
  t.period_ns = 5'000'000;
  t.epoch_ns = platform::MonotonicClock().now_ns() + 4 * t.period_ns;
  t.probe_ticks = 4;
  t.run_k0 = 6;
  t.run_ticks = 8;
  platform::LoopConfig lc;
  lc.period_ns = t.period_ns;
  platform::PeriodicLoop<> loop(lc);
  std::atomic<bool> stop{false};
  std::vector<std::int64_t> ks;
  ks.reserve(64);
  run_phase(
      t, TickPhase::kRun, t.run_k0, loop,
      [&](std::int64_t k, const platform::TickInfo& info) {
        ks.push_back(k);
        LONGS_EQUAL(k, t.tick_at(info.scheduled_ns));
        return k < 40;  // a bound for a loop that would not end with its phase
      },
      stop);
  CHECK(!ks.empty());
  CHECK(ks.front() >= t.run_k0);  // no probe or set-up tick runs the run phase's function
  for (std::size_t i = 1; i < ks.size(); ++i) CHECK(ks[i] > ks[i - 1]);
  CHECK(ks.back() < t.run_end_k());       // nothing after the run (the loop ended with its phase)
  CHECK(ks.back() >= t.run_end_k() - 3);  // and it ran to its end (a loaded machine may skip a period)
}
