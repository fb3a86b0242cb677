#pragma once
// report: the last phase of `haptic-station run` (DESIGN.md, "The station process"). From what
// the phases returned: the conditions that degrade the run (each named in station-<id>.json and
// on stderr, each with its exit code, firmware/station/phase.hpp), station-<id>.json,
// station-<id>-trace.csv and station-<id>-state.csv. Metrics over an empty window are null.
// Not RT-safe.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/station/loop.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/probe.hpp"
#include "firmware/station/tick.hpp"

namespace haptic::firmware {

// Everything the phases produced, for the report (pointers: null when that phase did not run).
struct StationOutcome {
  const StationPlan* plan = nullptr;
  const ProbeResult* probe = nullptr;
  const BuildResult* build = nullptr;
  const RunPhaseResult* run = nullptr;
  const TickCounters* counters = nullptr;
  const TickRecords* records = nullptr;
  bool records_streamed = false;    // the run's RecordFiles wrote the CSV files (else: headers only)
  const net::Endpoint* endpoint = nullptr;
  std::string failure;              // the first phase failure ("" none)
  PhaseStatus failure_status = PhaseStatus::kOk;
  std::string device_name;
  std::string device_fault;         // latched device fault at the end of the run ("none" when none)
  std::string io_sched;             // scheduling of the endpoint's I/O thread
  double wall_time_s = 0;
  nlohmann::json lifecycle;         // rejoin, neighbour clock offsets and events (station/run.cpp)
  nlohmann::json recording;         // the session log's counters ([record] enabled)
};

// The degraded conditions of a run (each is also a key of station-<id>.json's "conditions").
struct RunConditions {
  bool device_missing = false;          // the configured device could not be started (exit 9)
  bool diverged = false;
  bool safe_state_latched = false;      // loop-boundary exception, or a latched device fault
  bool passivity_not_met = false;       // B_i used < eq. (18) on the measured bounds
  bool key_compromise = false;          // a neighbour's key in two live incarnations: both refused (exit 12)
  bool neighbour_isolated = false;      // the neighbour state check isolated a neighbour (exit 13)
  bool missed_cycles = false;           // the run loop skipped more than station.max_missed_cycles periods (exit 11)
  bool no_neighbour = false;            // none answered probing, or alone > station.max_no_neighbour_fraction
  bool ended_before_release = false;    // the run ended at or before the scripted release
  bool failed = false;                  // any other failure
  bool held_by_gate = false;            // the per-edge energy gate tripped: bounded by its bound, not by eq. (18) alone (exit 10)
  bool edge_drop_rule_acted = false;    // a packet over its index-delay bound dropped an edge (named; no exit code of its own)
  std::optional<double> no_neighbour_fraction;  // of the run ticks; null when none ran
  double ran_s = 0;                             // run time reached: the end of its last tick (periods skipped before it count)
  std::uint64_t missed_cycles_total = 0;        // periods the run loop skipped
  std::vector<std::string> key_compromise_messages;  // one per neighbour (firmware/station/neighbours.hpp)
  std::vector<std::string> isolation_messages;       // one per isolated neighbour (firmware/station/state_check.hpp)
  std::vector<std::string> names() const;       // the conditions that hold, as named in the summary
};
RunConditions run_conditions(const StationOutcome& o);

// The process exit code for these conditions (the first that holds, in the documented order).
int exit_code(const RunConditions& c);

// The station's verdict (run_verdict over its core's gate and edge drops; eq. 13 is the merge's):
// station-<id>.json's "verdict" and the words of its result line. "stable" when no core was built.
std::string station_verdict(const StationOutcome& o);

// station-<id>.json's content.
nlohmann::json station_summary(const StationOutcome& o, const RunConditions& c);

// Writes station-<id>.json, -trace.csv and -state.csv under plan.base_path; throws
// std::runtime_error naming the file it cannot write.
void write_station_outputs(const StationOutcome& o, const RunConditions& c);

}  // namespace haptic::firmware
