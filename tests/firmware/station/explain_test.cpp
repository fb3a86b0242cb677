// Why a run failed (firmware/station/explain.hpp, outage.hpp), without sockets: a leaf's core is
// fed ticks by hand with the loop's TickInfo made up, so each cause is provoked exactly: a
// neighbour that goes silent, one whose packets arrive but too old, and this host starving
// (late wake-ups and overruns) in the span without a usable neighbour.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "firmware/station/explain.hpp"
#include "firmware/station/run.hpp"
#include "firmware/station/tick.hpp"
#include "platform/clock.hpp"
#include "tests/firmware/station/station_files.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic;
using namespace haptic::firmware;
using nlohmann::json;

namespace {

// A leaf (station 2, neighbour 1) whose core is ticked by hand: 100 ticks with the hub's data
// fresh, then 60 ticks in which the hub's data is `mode`: "silent" (no packet), "late" (packets
// 40 ticks old); with `starving`, those 60 ticks wake 5 ms late and each overruns. Then 40 fresh ticks.
struct Leaf {
  test::StationText s;
  PlanResult pr;
  BuildResult build;
  TickCounters cnt;
  RunPhaseResult run;
  StationOutcome o;
  RunConditions c;

  Leaf(const std::string& mode, bool starving) {
    s.id = 2;
    s.peers = {1};
    s.out_dir = "/tmp";
    pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
    build.status = PhaseStatus::kOk;
    build.passivity_condition_met = true;
    rt::StationConfig cfg = pr.plan->built->station_config(pr.plan->me);
    cfg.neighbors[0].index_delay_bound_ticks = 5;
    build.core = std::make_unique<rt::StationCore>(cfg);
    drive(mode, starving);
    o.plan = pr.plan.get();
    o.build = &build;
    o.run = &run;
    o.counters = &cnt;
    c = run_conditions(o);
  }

  void drive(const std::string& mode, bool starving) {
    rt::StationCore& core = *build.core;
    const int dofs = pr.plan->built->scene.dofs;
    const Eigen::VectorXd xj = pr.plan->built->scene.x_d, vj = Eigen::VectorXd::Zero(dofs);
    platform::TickInfo info;
    for (std::int64_t k = 0; k < 200; ++k) {
      const bool out = k >= 100 && k < 160;
      if (!out) core.rx(0).offer(k, 0, xj.data(), vj.data(), dofs);
      if (out && mode == "late") core.rx(0).offer(k - 40, 0, xj.data(), vj.data(), dofs);
      core.tick(k, pr.plan->built->vp_start[static_cast<std::size_t>(pr.plan->me)]);
      info.wake_latency_ns = out && starving ? 5'000'000 : 20'000;
      const bool usable = any_neighbour_within_bound(core, k);
      cnt.no_neighbour_ticks += usable ? 0 : 1;
      cnt.outages.on_tick(core, k, usable, info);
      run.whole_loop.wake_latency.add(info.wake_latency_ns);
      ++run.loop.ticks;
      if (out && starving) ++info.overruns, info.missed_cycles += 2, ++run.loop.overruns, run.loop.missed_cycles += 2;
      ++cnt.ticks_run;
      ++info.index;
    }
    run.first_run_k = pr.plan->times.run_k0;
    run.last_run_k = pr.plan->times.run_k0 + 199;
    cnt.outages.finish();
  }

  Explanation why() const { return explain_exit(o, c, exit_code(c)); }
};

std::string joined(const std::vector<std::string>& lines) {
  std::string t;
  for (const auto& l : lines) t += l + "\n";
  return t;
}

}  // namespace

TEST_GROUP(WhyARunFailed){};

TEST(WhyARunFailed, ANeighbourThatWentSilentIsNamedWithTheSpanAndThisHostKeptItsPeriod) {
  const Leaf leaf("silent", false);
  LONGS_EQUAL(kExitNoNeighbour, exit_code(leaf.c));
  const Explanation e = leaf.why();
  const std::string text = joined(e.lines);
  const json& span = e.json["no_neighbour_spans"]["longest"];
  LONGS_EQUAL(1, e.json["no_neighbour_spans"]["count"].get<int>());
  // data older than N̄ = 5 from tick 105 (the hub's last packet was tick 99) to tick 159
  LONGS_EQUAL(55, span["ticks"].get<int>());
  DOUBLES_EQUAL(0.210, span["from_s"].get<double>(), 1e-9);  // end of tick 104 = 105 x 2 ms
  DOUBLES_EQUAL(0.320, span["to_s"].get<double>(), 1e-9);    // end of tick 159
  STRCMP_EQUAL("silent", span["links"][0]["cause"].get<std::string>().c_str());
  LONGS_EQUAL(0, span["links"][0]["packets"].get<int>());
  LONGS_EQUAL(60, span["links"][0]["age_ticks"].get<int>());
  LONGS_EQUAL(5, span["links"][0]["nbar_ticks"].get<int>());
  CHECK_FALSE(span["host_starving"].get<bool>());
  STRCMP_CONTAINS("station 1 SILENT", text.c_str());
  STRCMP_CONTAINS("0.21-0.32 s of the run (55 ticks)", text.c_str());
  STRCMP_CONTAINS("60 ticks old against N̄ = 5", text.c_str());
  STRCMP_CONTAINS("this host kept its period in it", text.c_str());
  STRCMP_CONTAINS("limit station.max_no_neighbour_fraction = 10 %", text.c_str());
  STRCMP_CONTAINS("this host over the run loop: wake-up P99", text.c_str());
  CHECK_FALSE(e.json["host"]["starving"].get<bool>());
}

TEST(WhyARunFailed, PacketsThatArriveTooOldAreLateNotSilent) {
  const Leaf leaf("late", false);
  LONGS_EQUAL(kExitNoNeighbour, exit_code(leaf.c));
  const Explanation e = leaf.why();
  const json& span = e.json["no_neighbour_spans"]["longest"];
  STRCMP_EQUAL("late", span["links"][0]["cause"].get<std::string>().c_str());
  CHECK(span["links"][0]["packets"].get<int>() > 0);
  CHECK(span["links"][0]["age_ticks"].get<int>() > 5);
  STRCMP_CONTAINS("station 1 LATE (", joined(e.lines).c_str());
}

TEST(WhyARunFailed, AHostThatWokeLateAndOverranInTheSpanIsNamedStarving) {
  const Leaf leaf("silent", true);
  const Explanation e = leaf.why();
  const json& span = e.json["no_neighbour_spans"]["longest"];
  CHECK(span["host_starving"].get<bool>());
  DOUBLES_EQUAL(5.0, span["wake_max_ms"].get<double>(), 1e-9);
  CHECK(span["overruns"].get<int>() >= 55);
  const std::string text = joined(e.lines);
  STRCMP_CONTAINS("this host was STARVING in it (latest wake-up 5 ms", text.c_str());
  // over the run: 120 of 320 periods skipped, P99 5 ms >= the 2 ms period
  CHECK(e.json["host"]["starving"].get<bool>());
  STRCMP_CONTAINS("wake-up P99 5 ms, max 5 ms, 60 overruns, 120 skipped periods in 200 ticks of 2 ms: STARVING", text.c_str());
}

TEST(WhyARunFailed, TheStarvingHostRuleIsOnePercentOfThePeriodsSkippedOrAWakeUpP99OfAPeriod) {
  CHECK_FALSE(platform::host_starving(0, 0, 0, 2'000'000));
  CHECK_FALSE(platform::host_starving(1000, 9, 1'999'999, 2'000'000));
  CHECK(platform::host_starving(1000, 11, 0, 2'000'000));  // 11 of 1011 periods skipped
  CHECK(platform::host_starving(1000, 0, 2'000'000, 2'000'000));
}

// A loaded host skips periods: the core ticks the grid's index, so the run covers them. Whether it
// reached the scripted release is where its last tick was on the grid, not its tick count times T
// (a CI host skipped 40 % of a 0.3 s run and read 0.178 s, before a release at 0.2 s).
TEST(WhyARunFailed, ARunWhoseHostSkippedPeriodsEndedAtItsLastTickNotAtItsTickCount) {
  Leaf leaf("silent", false);
  const double T = leaf.pr.plan->built->spec.period_s, release_s = leaf.pr.plan->built->spec.script.release_s;
  const auto release_k = static_cast<std::int64_t>(std::llround(release_s / T));
  const std::int64_t k0 = leaf.pr.plan->times.run_k0;
  leaf.cnt.ticks_run = release_k / 2;  // half the periods to the release skipped ...
  leaf.run.first_run_k = k0;
  leaf.run.last_run_k = k0 + release_k + 9;  // ... and the last tick ran after it
  RunConditions c = run_conditions(leaf.o);
  DOUBLES_EQUAL(static_cast<double>(release_k + 10) * T, c.ran_s, 1e-12);
  CHECK_FALSE(c.ended_before_release);
  leaf.cnt.ticks_run = release_k / 4;
  leaf.run.last_run_k = k0 + release_k / 2 - 1;  // the last tick half-way to the release: it ended before it
  c = run_conditions(leaf.o);
  CHECK(c.ended_before_release);
  DOUBLES_EQUAL(release_s / 2, c.ran_s, 1e-9);
  const std::string text = joined(explain_exit(leaf.o, c, kExitBeforeRelease).lines);
  STRCMP_CONTAINS(("the run ended at " + std::to_string(std::llround(release_s / 2)) + " s, before").c_str(), text.c_str());
}

TEST(WhyARunFailed, ExitZeroExplainsNothing) {
  Leaf leaf("silent", false);
  leaf.c = RunConditions{};
  CHECK(leaf.why().lines.empty());
}

// What the tick records for these explanations costs it no allocation (spans opened and closed,
// stalls noted), like the rest of the tick (RunTick.OneLoopIterationAllocatesNothing...).
TEST(WhyARunFailed, TheTicksOutageRecordAllocatesNothing) {
  CHECK(test::allocation_counter_works());
  const Leaf leaf("silent", false);
  OutageTracker t;
  platform::TickInfo info;
  std::uint64_t allocations = 0;
  {
    test::AllocationCounter counter;
    for (std::int64_t k = 0; k < 300; ++k) {
      info.wake_latency_ns = k * 1000;
      info.overruns = static_cast<std::uint64_t>(k / 10);
      info.missed_cycles = static_cast<std::uint64_t>(k / 5);
      t.on_tick(*leaf.build.core, 200 + k, k % 50 < 25, info);
    }
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
  LONGS_EQUAL(5, t.spans());  // the sixth is still open
  t.finish();
  LONGS_EQUAL(6, t.spans());
  LONGS_EQUAL(25, t.longest().ticks);
}
