// The station's one timeline (firmware/station/timeline.hpp): the time-to-tick rule probe, rejoin
// and run share, the phases on the common tick index, where a periodic loop starts, and the one
// loop whose stages they are (firmware/station/loop.hpp).
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <chrono>
#include <limits>
#include <thread>
#include <vector>

#include "firmware/station/loop.hpp"
#include "firmware/station/timeline.hpp"
#include "platform/clock.hpp"
#include "rt/tx_deadband.hpp"

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

// Probing sends at the deadband's pace, at least that many ticks apart: a loaded host that skips the
// period a send was due in sends at the next tick it runs (a send only on k = 0 mod pace lost the
// whole interval), and never two within the pace.
TEST(Timeline, a_paced_send_whose_period_was_skipped_goes_out_at_the_next_tick_that_runs) {
  const std::int64_t pace = 20;
  haptic::rt::SendInterval every(pace), skipping(pace);
  std::vector<std::int64_t> sent;
  long on_the_grid = 0;  // what sending only on k = 0 mod pace would have sent
  for (std::int64_t k = 0; k < 400; ++k) {
    CHECK_EQUAL(k % pace == 0, every.take(k));  // nothing skipped: every pace-th tick
    const bool skipped = (k / 7) % 3 == 0;     // a third of the periods, in runs of 7
    if (skipped) continue;
    on_the_grid += k % pace == 0 ? 1 : 0;
    if (!skipping.take(k)) continue;
    if (!sent.empty()) {
      CHECK(k - sent.back() >= pace);
      for (std::int64_t j = sent.back() + pace; j < k; ++j) CHECK((j / 7) % 3 == 0);  // the first tick that ran once due
    }
    sent.push_back(k);
  }
  CHECK_TEXT(static_cast<long>(sent.size()) > on_the_grid, (std::to_string(sent.size()) + " vs " + std::to_string(on_the_grid)).c_str());
  haptic::rt::SendInterval each(1);
  for (std::int64_t k : {0, 1, 2, 5, 9}) CHECK(each.take(k));  // pace 1: every tick run
}

TEST(Timeline, a_deadline_on_the_grid_or_less_than_half_a_period_late_is_its_tick) {
  const Timeline t = paper_timeline();
  for (std::int64_t k : {-3000L, -2L, -1L, 0L, 1L, 749L, 750L, 1000L, 10999L}) {  // before the epoch too (a loop watching before probing)
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

TEST(Timeline, a_stage_started_in_time_runs_from_its_first_tick_and_a_late_one_joins_the_grid_a_period_ahead) {
  const Timeline t = paper_timeline();
  const std::int64_t P = t.period_ns;
  // in good time (the run after the set-up gap): the first tick
  LONGS_EQUAL(t.run_k0, t.first_tick_from(t.run_k0, t.time_of(t.run_k0) - 40 * P));
  // still half a period or more before it: that tick
  LONGS_EQUAL(0, t.first_tick_from(0, t.time_of(-1) + 50'000));
  LONGS_EQUAL(0, t.first_tick_from(0, t.time_of(-1) + P / 2));
  // late (a rejoining station): a tick of the grid at least one period after now
  for (std::int64_t late_ns : {P / 2 + 1, P, 10 * P + 3 * P / 10, 5000 * P + P - 1}) {
    const std::int64_t now = t.time_of(t.run_k0 - 1) + late_ns;
    const std::int64_t k = t.first_tick_from(t.run_k0, now);
    CHECK(k > t.run_k0);
    CHECK(t.time_of(k) >= now + P);
    CHECK(t.time_of(k) < now + 3 * P);
  }
}

namespace {

// A plan whose loop runs at a 5 ms period as an ordinary thread (no SCHED_FIFO, no mlockall in a test process).
StationPlan loop_plan(std::int64_t epoch_in_ns) {
  StationPlan plan;
  plan.file.loop.period_ns = 5'000'000;
  plan.file.rt.sched_fifo = false;
  plan.file.rt.lock_memory = false;
  plan.file.rt.cpu = -1;
  plan.times.period_ns = plan.file.loop.period_ns;
  plan.times.epoch_ns = platform::MonotonicClock().now_ns() + epoch_in_ns;
  plan.times.probe_ticks = 6;
  plan.times.run_k0 = 12;
  plan.times.run_ticks = 40;  // 200 ms: a late hand-over still meets run ticks on a loaded machine
  return plan;
}

struct Seen {
  std::vector<std::int64_t> k, scheduled_ns;
  std::vector<std::thread::id> thread;
  Seen() {
    k.reserve(256);
    scheduled_ns.reserve(256);
    thread.reserve(256);
  }
  void add(std::int64_t kk, const platform::TickInfo& info) {
    k.push_back(kk);
    scheduled_ns.push_back(info.scheduled_ns);
    thread.push_back(std::this_thread::get_id());
  }
};

// Stage `first` until it ends, then (at handover_at_ns: a build on this thread) the run stage of `plan`.
std::pair<Seen, Seen> probe_then_run(StationPlan& plan, LoopStage first, std::int64_t handover_at_ns, StationLoop& loop, RunPhaseResult& run) {
  Seen a, b;
  std::atomic<bool> stop{false};
  const StageTickFn first_tick = first.tick;
  first.tick = [&](std::int64_t k, const platform::TickInfo& info) {
    a.add(k, info);
    return first_tick(k, info);
  };
  loop.start(std::move(first), RunObserver{});
  CHECK(loop.wait_stage(0, RunObserver{}));
  platform::MonotonicClock().sleep_until_ns(handover_at_ns);
  const RunTickFn tick = [&](std::int64_t k, std::int64_t kr, const platform::TickInfo& info) {
    LONGS_EQUAL(k - plan.times.run_k0, kr);
    b.add(k, info);
  };
  const int i = loop.hand_over(run_stage(plan, tick, stop, false));
  run = loop.run_result(i, RunObserver{});
  return {a, b};
}

LoopStage probe_like_stage(const StationPlan& plan) {
  LoopStage s;
  s.timeline = plan.times;
  s.last_phase = TickPhase::kProbe;
  s.k_first = plan.times.tick_at(platform::MonotonicClock().now_ns());
  s.tick = [](std::int64_t, const platform::TickInfo&) { return true; };
  return s;
}

}  // namespace

TEST(Timeline, probe_set_up_and_run_are_stages_of_one_loop_on_one_grid) {
  StationPlan plan = loop_plan(4 * 5'000'000);
  std::atomic<bool> no_stop{false};
  StationLoop loop(plan, nullptr, no_stop);
  RunPhaseResult run;
  const auto [probe, ran] = probe_then_run(plan, probe_like_stage(plan), 0, loop, run);
  CHECK(run.status == PhaseStatus::kOk);
  CHECK(!probe.k.empty());
  CHECK(!ran.k.empty());
  for (std::int64_t k : probe.k) CHECK(k < plan.times.probe_ticks);  // the probe stage ends with probing
  CHECK(loop.stage(0).ended);                                         // and ended with it
  for (std::int64_t k : ran.k) CHECK(k >= plan.times.run_k0 && k < plan.times.run_end_k());
  LONGS_EQUAL(ran.k.front(), run.first_run_k);
  // One loop: one thread ran every tick, and every deadline (probe and run alike) is on one grid of
  // periods from the first, each the tick the timeline's rule names.
  for (const Seen* s : {&probe, &ran})
    for (std::size_t i = 0; i < s->k.size(); ++i) {
      CHECK(s->thread[i] == probe.thread.front());
      LONGS_EQUAL(0, (s->scheduled_ns[i] - probe.scheduled_ns.front()) % plan.times.period_ns);
      LONGS_EQUAL(s->k[i], plan.times.tick_at(s->scheduled_ns[i]));
    }
  // The stages' counters are their own shares of the loop's (set-up ticks in neither).
  const LoopCounts p = loop.stage(0).counts;
  LONGS_EQUAL(probe.k.size(), p.ticks);
  LONGS_EQUAL(ran.k.size(), run.loop.ticks);
}

TEST(Timeline, a_run_stage_handed_over_late_starts_at_the_next_tick_of_the_grid) {
  StationPlan plan = loop_plan(2 * 5'000'000);
  std::atomic<bool> no_stop{false};
  StationLoop loop(plan, nullptr, no_stop);
  RunPhaseResult run;
  // the build takes until three ticks into the run
  const auto [probe, ran] = probe_then_run(plan, probe_like_stage(plan), plan.times.time_of(plan.times.run_k0 + 3), loop, run);
  CHECK(!ran.k.empty());
  // the ticks it missed are not run late: the first is the tick of the hand-over (run_k0 + 3), or on
  // a loaded host the one before it, whose late wake-up (less than a period) came after the hand-over
  CHECK_TEXT(ran.k.front() >= plan.times.run_k0 + 2, std::to_string(ran.k.front() - plan.times.run_k0).c_str());
  for (std::size_t i = 0; i < ran.k.size(); ++i) LONGS_EQUAL(0, (ran.scheduled_ns[i] - probe.scheduled_ns.front()) % plan.times.period_ns);
}

TEST(Timeline, a_stage_on_another_epoch_moves_the_loop_onto_its_grid) {
  // A rejoining station: provisional probes on a timeline of its own, then the session's run on a
  // grid 1.7 ms off the provisional one.
  StationPlan plan = loop_plan(0);
  LoopStage own = probe_like_stage(plan);
  own.timeline.epoch_ns = platform::MonotonicClock().now_ns() + plan.times.period_ns;
  own.timeline.probe_ticks = 4;
  own.timeline.run_k0 = std::numeric_limits<std::int64_t>::max() / 4;
  own.k_first = 0;
  plan.times.epoch_ns = own.timeline.epoch_ns + 1'700'000 - 3 * plan.times.period_ns;  // the session runs already
  std::atomic<bool> no_stop{false};
  StationLoop loop(plan, nullptr, no_stop);
  std::atomic<bool> stop{false};
  Seen a, b;
  own.tick = [&](std::int64_t k, const platform::TickInfo& info) {
    a.add(k, info);
    return true;
  };
  loop.start(own, RunObserver{});
  CHECK(loop.wait_stage(0, RunObserver{}));
  const RunTickFn tick = [&](std::int64_t k, std::int64_t, const platform::TickInfo& info) { b.add(k, info); };
  const int i = loop.hand_over(run_stage(plan, tick, stop, true));
  const RunPhaseResult run = loop.run_result(i, RunObserver{});
  CHECK(run.status == PhaseStatus::kOk);
  CHECK(!b.k.empty());
  for (std::size_t j = 0; j < b.k.size(); ++j) {
    CHECK(b.thread[j] == a.thread.front());
    LONGS_EQUAL(plan.times.time_of(b.k[j]), b.scheduled_ns[j]);  // exactly on the session's grid
  }
}

TEST(Timeline, a_loop_whose_next_stage_never_comes_ends_when_told) {
  StationPlan plan = loop_plan(0);
  std::atomic<bool> no_stop{false};
  StationLoop loop(plan, nullptr, no_stop);
  loop.start(probe_like_stage(plan), RunObserver{});
  CHECK(loop.wait_stage(0, RunObserver{}));
  loop.finish();  // a failed build
  CHECK(loop.loop_ended());
}
