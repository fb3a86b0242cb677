// The run metrics (firmware/run/metrics.hpp) shared by the simulator and the multi-process merge
// (firmware/run/merge.hpp): empty windows give null, consensus times to the absolute threshold and
// to 10 % / 1 % of the error at release, and the merge of station files on their common ticks.
#include <CppUTest/TestHarness.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "firmware/run/merge.hpp"
#include "firmware/run/metrics.hpp"
#include "firmware/run/summary.hpp"
#include "firmware/station/tick.hpp"

using namespace haptic::firmware;
using nlohmann::json;

namespace {

MetricsWindows windows(double hold0, double hold1, double release) {
  MetricsWindows w;
  w.hold_start_s = hold0;
  w.hold_end_s = hold1;
  w.release_s = release;
  w.push_start_s = 0;
  return w;
}

CopiesSample err(double e) { return CopiesSample{e, 0.001}; }

// Error 2 mm up to the release at 1 s, then 2 mm x exp(-(t - 1) / 0.5), sampled every tick of 10 ms.
RunMetricsResult decaying_run(bool sample_before_release) {
  const double T = 0.01;
  RunMetrics m(windows(0.5, 1.0, 1.0), T);
  for (std::int64_t k = sample_before_release ? 0 : 100; k < 500; ++k) {
    const double t_next = static_cast<double>(k + 1) * T;
    m.add_copies(k, err(t_next <= 1.0 ? 2e-3 : 2e-3 * std::exp(-(t_next - 1.0) / 0.5)));
  }
  return m.result(500);
}

}  // namespace

TEST_GROUP(RunMetrics){};

TEST(RunMetrics, MetricsOverAnEmptyWindowAreNullNeverZero) {
  // Samples only before the hold window, no forces, no energies, nothing after the release.
  RunMetrics m(windows(1.0, 2.0, 2.0), 0.01);
  for (std::int64_t k = 0; k < 50; ++k) m.add_copies(k, err(1e-3));
  const RunMetricsResult r = m.result(50);
  CHECK_FALSE(r.hold_force_sum_N.has_value());
  CHECK_FALSE(r.hold_force_mean_N.has_value());
  CHECK_FALSE(r.hold_force_balance_ratio.has_value());
  CHECK_FALSE(r.deformation_hold_m.has_value());
  CHECK_FALSE(r.deformation_rise_time_s.has_value());
  CHECK_FALSE(r.consensus_time_s.has_value());
  CHECK_FALSE(r.consensus_time_10pct_s.has_value());
  CHECK_FALSE(r.port_energy_min_J.has_value());
  CHECK_FALSE(r.max_node_speed_m_per_s.has_value());
  const json j = metrics_json(r);
  for (const char* k : {"hold_force_sum_N", "hold_force_mean_N", "hold_force_balance_ratio", "deformation_hold_m", "consensus_time_s",
                        "consensus_time_10pct_s", "consensus_time_1pct_s", "port_energy_min_J", "controller_energy_max_J", "max_node_speed_m_per_s"})
    CHECK_TEXT(j[k].is_null(), k);
  // A run with no sample at all has no consensus error either.
  const json none = metrics_json(RunMetrics(windows(1.0, 2.0, 2.0), 0.01).result(0));
  CHECK(none["consensus_error_m"].is_null());
  CHECK(none["max_consensus_error_m"].is_null());
}

TEST(RunMetrics, HoldForceIsTheMeanOverTheTicksInTheHoldWindow) {
  RunMetrics m(windows(0.1, 0.2, 0.2), 0.01);
  const std::vector<Eigen::Vector3d> f = {{1, 0, 0}, {-0.9, 0, 0}};
  for (std::int64_t k = 0; k < 30; ++k) m.add_forces(k, f);  // ticks 10..19 start in [0.1, 0.2)
  const RunMetricsResult r = m.result(30);
  DOUBLES_EQUAL(0.1, *r.hold_force_sum_N, 1e-12);
  DOUBLES_EQUAL(0.95, *r.hold_force_mean_N, 1e-12);
  DOUBLES_EQUAL(0.1 / 0.95, *r.hold_force_balance_ratio, 1e-12);
}

TEST(RunMetrics, ConsensusTimesToOneMillimetreAndToTenAndOnePercentOfTheErrorAtRelease) {
  const RunMetricsResult r = decaying_run(true);
  DOUBLES_EQUAL(2e-3, *r.consensus_error_at_release_m, 1e-15);
  // e(t) = 2 mm exp(-t/0.5) crosses 1 mm at 0.5 ln 2, 0.2 mm at 0.5 ln 10, 0.02 mm at 0.5 ln 100
  // (to within the 10 ms sampling).
  DOUBLES_EQUAL(0.5 * std::log(2.0), *r.consensus_time_s, 0.01);
  DOUBLES_EQUAL(0.5 * std::log(10.0), *r.consensus_time_10pct_s, 0.01);
  DOUBLES_EQUAL(0.5 * std::log(100.0), *r.consensus_time_1pct_s, 0.01);
  DOUBLES_EQUAL(0.01, *r.consensus_time_resolution_s, 1e-12);
}

TEST(RunMetrics, RelativeConsensusTimesAreNullWithoutASampleAtTheRelease) {
  const RunMetricsResult r = decaying_run(false);
  CHECK_FALSE(r.consensus_error_at_release_m.has_value());
  CHECK_FALSE(r.consensus_time_10pct_s.has_value());
  CHECK_FALSE(r.consensus_time_1pct_s.has_value());
  CHECK_TRUE(r.consensus_time_s.has_value());  // the absolute one needs no reference
}

TEST(RunMetrics, AnErrorThatComesBackAboveTheLevelCountsFromItsLastCrossing) {
  RunMetrics m(windows(0, 0, 1.0), 0.1);
  const double e[] = {2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3,  // to the release at 1 s
                      1e-4, 1e-4, 5e-4, 1e-4, 1e-4, 1e-4};                          // back above 10 % once, at 1.3 s
  for (std::int64_t k = 0; k < 16; ++k) m.add_copies(k, err(e[k]));
  const RunMetricsResult r = m.result(16);
  DOUBLES_EQUAL(0.0, *r.consensus_time_s, 1e-12);       // below 1 mm from the first sample after release
  DOUBLES_EQUAL(0.3, *r.consensus_time_10pct_s, 1e-9);  // last at or above 0.2 mm: the sample at 1.3 s
  CHECK_FALSE(r.consensus_time_1pct_s.has_value());     // 0.1 mm never gets below 20 um
}

TEST(RunMetrics, ADivergedRunHasNoConsensusTime) {
  RunMetrics m(windows(0, 0, 0.05), 0.1);
  for (std::int64_t k = 0; k < 5; ++k) m.add_copies(k, err(1e-6));
  m.add_divergence(0.3);
  const RunMetricsResult r = m.result(5);
  CHECK_TRUE(r.diverged);
  DOUBLES_EQUAL(0.3, *r.diverged_at_s, 0);
  CHECK_FALSE(r.consensus_time_s.has_value());
}

TEST(RunMetrics, CopiesSampleIsTheLargestNodeDistanceAndTheShapeDeformation) {
  Eigen::VectorXd x_d = Eigen::VectorXd::Zero(6);  // two nodes at the origin
  x_d[3] = 1.0;
  Eigen::VectorXd a = x_d, b = x_d;
  a[0] += 0.003;  // node 0 of copy a moved 3 mm in x
  b.array() += 0.5;  // copy b translated: no shape change
  const CopiesSample s = measure_copies({a.data(), b.data()}, x_d);
  DOUBLES_EQUAL(std::sqrt(0.75), s.consensus_error_m, 1e-12);  // node 1: the translation, the larger
  // mean copy: node 0 moved 1.5 mm more than node 1: deformation = rms distance from the mean displacement
  DOUBLES_EQUAL(0.75e-3, s.deformation_m, 1e-12);
}

// ---- the merge of station files --------------------------------------------------------------

namespace {

namespace fs = std::filesystem;

json station_json(int id, int users, double dt) {
  json j;
  j["station"] = id;
  j["users"] = users;
  j["scenario"] = "paper-best";
  j["dt_s"] = dt;
  j["transport"] = "udp";
  j["error"] = nullptr;
  j["x_d"] = {0.0, 0.0, 0.0, 1.0, 0.0, 0.0};
  j["metrics_windows"] = {{"release_s", 0.045}, {"hold_start_s", 0.02}, {"hold_end_s", 0.045}, {"push_start_s", 0.0}, {"consensus_threshold_m", 1e-3}};
  j["diverged"] = false;
  j["max_node_speed_m_per_s"] = 0.1 * id;
  j["ticks_run"] = 10;
  j["loop"] = {{"overruns", 0}, {"missed_cycles", 0}};
  j["rt"] = {{"fully_real_time", false}, {"warnings", json::array()}};
  j["stopped_by_signal"] = false;
  j["device"] = "simulated";
  j["wall_time_s"] = 1.0;
  j["passivity_condition_met"] = true;
  j["consensus_passivity"] = "pspm";
  j["solver"] = id == 1 ? "direct" : "iterative";
  j["solver_residual_energy_final_J"] = id == 1 ? 0.0 : 2e-12;
  j["solver_unconverged_ticks"] = 0;
  j["trace_every"] = 1;
  j["trace_marks_state_sent"] = true;
  j["links"] = json::array({{{"peer", 3 - id},
                             {"tx_packets_run", 10},
                             {"packets_per_s", 100.0 * id},
                             {"bytes_per_s", 1000.0 * id},
                             {"tx_impair_lost_run", 1},
                             {"tx_impair_duplicated_run", 0},
                             {"rx_packets_run", 9},
                             {"one_way_mean_ms", 4.0},
                             {"one_way_max_ms", 6.0},
                             {"index_delay_bound_ticks", 3},
                             {"assumed_round_trip_ticks", 8}}});
  return j;
}

// Two stations, ticks 0..ticks-1 traced (10 by default), states every 2 ticks; copy 2's node 0 is
// `gap(k)` m off in x. Station 1 sent its state (trace flag kTraceStateSent) at k = 0, 3, 6, 9, ...,
// station 2 at every tick.
std::string write_two_stations(const std::string& name, double (*gap)(std::int64_t), int ticks = 10) {
  const std::string dir = (fs::temp_directory_path() / name).string();
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (int id = 1; id <= 2; ++id) {
    const std::string base = dir + "/station-" + std::to_string(id);
    std::ofstream(base + ".json") << station_json(id, 2, 0.01).dump();
    std::ofstream tr(base + "-trace.csv");
    tr << "k,t_s,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,device_x_m,device_y_m,device_z_m,"
          "port_energy_J,controller_energy_J,vo_energy_J,contact,flags,max_speed_m_per_s,wake_latency_ns" << (id == 2 ? ",step_s\n" : "\n");
    for (int k = 0; k < ticks; ++k) {  // station 2 integrated with T_k = 9, 10, 11, 9, ... ms (station 1: a trace without step_s)
      tr << k << "," << (k + 1) * 0.01 << ",0,0,0," << (id == 1 ? 1.0 : -1.0) << ",0,0,0,0,0,0,0,0," << -0.001 * k << ",0,0.5,1," << (id == 2 || k % 3 == 0 ? kTraceStateSent : 0u) << ",0,0";
      if (id == 2) tr << "," << 0.01 + 0.001 * (k % 3 - 1);
      tr << "\n";
    }
    std::ofstream st(base + "-state.csv");
    st << "k,x0,x1,x2,x3,x4,x5\n";
    for (int k = 0; k < ticks; k += 2) st << k << "," << (id == 2 ? gap(k) : 0.0) << ",0,0,1,0,0\n";
  }
  return dir;
}

double shrinking_gap(std::int64_t k) { return k < 5 ? 4e-3 : 4e-3 / static_cast<double>(k * k); }

// The peak resident memory (kB) of a child process that merges `dir` (it starts as a copy of this
// one, so two children compare the merge's own growth).
long merge_peak_kB(const std::string& dir) {
  const pid_t pid = fork();
  if (pid == 0) {
    try {
      merge_run(dir);
    } catch (...) {
      _exit(1);
    }
    _exit(0);
  }
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  CHECK_TEXT(WIFEXITED(status) && WEXITSTATUS(status) == 0, ("the merge of " + dir + " failed").c_str());
  return ru.ru_maxrss;
}

}  // namespace

TEST_GROUP(RunMerge){};

TEST(RunMerge, MergesStationFilesWithTheSimulatorsMetrics) {
  const std::string dir = write_two_stations("haptic-metrics-merge", shrinking_gap);
  const json s = merge_run(dir);
  // States at k = 0, 2, 4, 6, 8: the gap at the last one, 4 mm / 64.
  DOUBLES_EQUAL(4e-3 / 64, s["consensus_error_m"].get<double>(), 1e-12);
  DOUBLES_EQUAL(4e-3, s["max_consensus_error_m"].get<double>(), 1e-12);
  DOUBLES_EQUAL(4e-3, s["consensus_error_at_release_m"].get<double>(), 1e-12);  // k = 2 ends at 0.03 s, before 0.045 s
  // After the release: 4 mm at 0.05 s, 0.11 mm at 0.07 s, 0.0625 mm at 0.09 s.
  DOUBLES_EQUAL(0.005, s["consensus_time_s"].get<double>(), 1e-12);
  DOUBLES_EQUAL(0.005, s["consensus_time_10pct_s"].get<double>(), 1e-12);  // 0.4 mm
  CHECK_TRUE(s["consensus_time_1pct_s"].is_null());                         // 40 um: not reached
  DOUBLES_EQUAL(0.02, s["consensus_time_resolution_s"].get<double>(), 1e-12);
  // Forces +1 and -1 along x in the hold window [0.02, 0.045): balanced.
  DOUBLES_EQUAL(0.0, s["hold_force_sum_N"].get<double>(), 1e-12);
  DOUBLES_EQUAL(1.0, s["hold_force_mean_N"].get<double>(), 1e-12);
  DOUBLES_EQUAL(-0.018, s["port_energy_min_J"].get<double>(), 1e-12);  // two stations at k = 9
  DOUBLES_EQUAL(1.0, s["passivity_bound_J"].get<double>(), 1e-12);
  DOUBLES_EQUAL(0.2, s["max_node_speed_m_per_s"].get<double>(), 1e-12);
  CHECK_EQUAL(20u, s["packets"]["sent"].get<unsigned>());
  CHECK_EQUAL(18u, s["packets"]["delivered"].get<unsigned>());
  CHECK_EQUAL(2u, s["link_stats"].size());
  DOUBLES_EQUAL(0.1, s["link_stats"][0]["loss_rate"].get<double>(), 1e-12);
  CHECK_TRUE(s["bounds_consistent_all_links"].get<bool>());  // 3 + 3 <= 8
  // Per link (to <- from): the sender's rates, and the states it sent in the hold window [0.02, 0.045)
  // (k = 2..4) and after consensus (from 0.045 + 0.005 s: k = 5..9), from its trace's sent flags.
  for (const auto& l : s["link_stats"]) {
    const int from = l["from"].get<int>();
    DOUBLES_EQUAL(100.0 * from, l["packets_per_s"].get<double>(), 0);
    DOUBLES_EQUAL(1000.0 * from, l["bytes_per_s"].get<double>(), 0);
    CHECK_EQUAL(from == 1 ? 1u : 3u, l["sent_in_hold_window"].get<unsigned>());
    CHECK_EQUAL(from == 1 ? 2u : 5u, l["sent_after_consensus"].get<unsigned>());
  }
  CHECK_EQUAL(4u, s["packets"]["sent_in_hold_window"].get<unsigned>());
  CHECK_EQUAL(7u, s["packets"]["sent_after_consensus"].get<unsigned>());
  CHECK_TRUE(s["passivity_condition_met"].get<bool>());
  CHECK_EQUAL(std::string("pspm"), s["consensus_passivity"].get<std::string>());  // as the simulator's summary
  CHECK_EQUAL(std::string("stable"), s["verdict"].get<std::string>());  // station files without "gate": neither acted
  CHECK_EQUAL(0u, s["gate"]["energy_gate_trips"].get<unsigned>());
  // each station's solver of the linear step and the energy its residual put in
  CHECK_EQUAL(std::string("iterative"), s["solver"][1].get<std::string>());
  DOUBLES_EQUAL(2e-12, s["solver_residual_energy_final_J"][1].get<double>(), 0);
  // the steps T_k each station integrated with, from its trace (station 1's trace has none)
  CHECK_TRUE(s["stations"][0]["steps"].is_null());
  const json& steps = s["stations"][1]["steps"];
  DOUBLES_EQUAL(0.009, steps["min_s"].get<double>(), 1e-12);
  DOUBLES_EQUAL(0.011, steps["max_s"].get<double>(), 1e-12);
  DOUBLES_EQUAL(0.0099, steps["mean_s"].get<double>(), 1e-12);
  DOUBLES_EQUAL(-0.001, steps["integrated_minus_grid_s"].get<double>(), 1e-12);  // four 9 ms, three 11 ms
  CHECK_TRUE(fs::exists(dir + "/trace.csv") && fs::exists(dir + "/series.csv"));
  // The file contract: 20 trace rows + header, 5 series rows + header.
  std::ifstream tr(dir + "/trace.csv"), se(dir + "/series.csv");
  std::string line;
  int rows = 0;
  while (std::getline(tr, line)) ++rows;
  CHECK_EQUAL(21, rows);
  rows = 0;
  while (std::getline(se, line)) ++rows;
  CHECK_EQUAL(6, rows);
}

// A run the stations' energy gates held is never merged into a plain "stable": the merged summary
// adds up what each station's gate and edge-drop rule did, takes the merged run's worst port energy,
// and its verdict and result line say "held by the gate"; a station file from before "gate" counts
// its trips.
TEST(RunMerge, ARunTheGateHeldIsMergedAsHeldWithTheStationsFigures) {
  const std::string dir = write_two_stations("haptic-metrics-merge-gate", shrinking_gap);
  json s1 = station_json(1, 2, 0.01), s2 = station_json(2, 2, 0.01);
  s1["gate"] = {{"energy_gate_trips", 2}, {"energy_gate_gated_ticks", 50}, {"energy_gate_removed_J", 0.003}, {"edge_drop_events", 1},
                {"port_energy_min_J", -0.5}};
  s2["edge_energy_trips"] = 1;  // an older station file: no "gate"
  std::ofstream(dir + "/station-1.json") << s1.dump();
  std::ofstream(dir + "/station-2.json") << s2.dump();
  const json s = merge_run(dir);
  CHECK_EQUAL(std::string("held_by_gate"), s["verdict"].get<std::string>());
  const json& g = s["gate"];
  CHECK_EQUAL(3u, g["energy_gate_trips"].get<unsigned>());
  CHECK_EQUAL(50u, g["energy_gate_gated_ticks"].get<unsigned>());
  DOUBLES_EQUAL(0.003, g["energy_gate_removed_J"].get<double>(), 1e-15);
  CHECK_EQUAL(1u, g["edge_drop_events"].get<unsigned>());
  DOUBLES_EQUAL(-0.018, g["port_energy_min_J"].get<double>(), 1e-12);  // the merged run's, not a station's own
  CHECK_TRUE(g["held_by_gate"].get<bool>());
  const std::string line = merge_result_line(s);
  CHECK_TEXT(line.find("HELD BY THE GATE (3 energy-gate trips (50 gated ticks), 0.003 J removed by the gate, 1 edge drops; worst port energy -0.018 J)") !=
                 std::string::npos, line.c_str());
  s1.erase("gate");  // edge drops only: named, not "stable"
  s1["edge_drop_events"] = 4;
  s2.erase("edge_energy_trips");
  std::ofstream(dir + "/station-1.json") << s1.dump();
  std::ofstream(dir + "/station-2.json") << s2.dump();
  const json d = merge_run(dir);
  CHECK_EQUAL(std::string("stable_with_edge_drops"), d["verdict"].get<std::string>());
  CHECK_TEXT(merge_result_line(d).find("stable with EDGES DROPPED") != std::string::npos, merge_result_line(d).c_str());
}

// The verdict's order: what acted or broke is named before "stable", the most severe first; a run
// whose ports took out more than d^2 with no gate to hold it is "not_passive" (eq. 13 broken).
TEST(RunMerge, TheVerdictNamesABrokenEq13UnlessTheGateHeldTheRunOrItDiverged) {
  GateSummary none, gate, drops;
  gate.trips = 1;
  drops.edge_drop_events = 1;
  CHECK_EQUAL(std::string("stable"), run_verdict(false, false, none, false));
  CHECK_EQUAL(std::string("not_passive"), run_verdict(false, false, none, true));
  CHECK_EQUAL(std::string("not_passive"), run_verdict(false, false, drops, true));
  CHECK_EQUAL(std::string("stable_with_edge_drops"), run_verdict(false, false, drops, false));
  CHECK_EQUAL(std::string("held_by_gate"), run_verdict(false, false, gate, true));  // the gate's clause gives the port energy
  CHECK_EQUAL(std::string("unstable"), run_verdict(false, true, none, true));
  CHECK_EQUAL(std::string("diverged"), run_verdict(true, true, gate, true));
  CHECK_TEXT(verdict_words("not_passive").find("NOT PASSIVE") != std::string::npos, verdict_words("not_passive").c_str());
}

// The merge flags what a reader of a failed lab run must not miss: a link whose index delay went
// over its guard (N > N̄) and a station whose host was starving (its station-<id>.json "host"), in
// summary.json "flags" and on the result line; a clean run has none.
TEST(RunMerge, ALinkOverItsIndexDelayBoundAndAStarvingHostAreFlagged) {
  const std::string dir = write_two_stations("haptic-metrics-merge-flags", shrinking_gap);
  CHECK_EQUAL(0u, merge_run(dir)["flags"].size());
  CHECK_TEXT(merge_result_line(merge_run(dir)).find("FLAGGED") == std::string::npos, merge_result_line(merge_run(dir)).c_str());
  json s1 = station_json(1, 2, 0.01), s2 = station_json(2, 2, 0.01);
  s2["links"][0]["max_index_delay_ticks"] = 74;  // station 2 held station 1's data 74 ticks, N̄ = 3
  s2["links"][0]["bound_violations"] = 5;
  s1["links"][0]["max_index_delay_ticks"] = 3;   // at its bound: not flagged
  s2["host"] = {{"loop", "run"}, {"ticks", 2000}, {"overruns", 30}, {"missed_cycles", 40}, {"wake_p99_ms", 4.2}, {"wake_max_ms", 13.6},
                {"period_ms", 2.0}, {"starving", true}};
  s1["host"] = {{"loop", "run"}, {"ticks", 2000}, {"overruns", 1}, {"missed_cycles", 1}, {"wake_p99_ms", 0.3}, {"wake_max_ms", 2.5},
                {"period_ms", 2.0}, {"starving", false}};
  std::ofstream(dir + "/station-1.json") << s1.dump();
  std::ofstream(dir + "/station-2.json") << s2.dump();
  const json s = merge_run(dir);
  CHECK_EQUAL(2u, s["flags"].size());
  STRCMP_EQUAL("link 2<-1: N max 74 > N̄ 3 (5 edge drops)", s["flags"][0].get<std::string>().c_str());
  STRCMP_EQUAL("station 2: host STARVING (wake-up P99 4.2 ms, max 13.6 ms, 30 overruns, 40 skipped periods in 2000 ticks)",
               s["flags"][1].get<std::string>().c_str());
  CHECK_TRUE(s["stations"][1]["host"]["starving"].get<bool>());
  STRCMP_CONTAINS("; FLAGGED: link 2<-1: N max 74 > N̄ 3 (5 edge drops); station 2: host STARVING", merge_result_line(s).c_str());
}

// What the edges' safeguards did is added up like the other per-station counters: the resilient rule's
// resilient_excluded_ticks per link (the receiver's), per station and in total (only when a station had
// the rule on), the neighbour state check's isolations per link, per station and in summary.json
// "state_check", each isolation a flag on the result line; files without them add nothing.
TEST(RunMerge, TheResilientRulesExclusionsAndTheStateChecksIsolationsAreAddedUpAndEachIsolationIsFlagged) {
  const std::string dir = write_two_stations("haptic-metrics-merge-safeguards", shrinking_gap);
  const json plain = merge_run(dir);
  CHECK_FALSE(plain.contains("resilient_excluded_ticks") || plain.contains("state_check"));
  CHECK_TRUE(plain["stations"][0]["resilient_excluded_ticks"].is_null());
  json s1 = station_json(1, 2, 0.01), s2 = station_json(2, 2, 0.01);
  s1["links"][0]["resilient_excluded_ticks"] = 7;  // station 1 left station 2 out on 7 ticks
  s2["links"][0]["resilient_excluded_ticks"] = 5;
  s1["state_check"] = {{"isolations", 2},
                       {"neighbours", json::array({{{"station", 2}, {"isolations", 2}, {"readmissions", 1}, {"isolated_ticks", 300},
                                                    {"reason", "inconsistent_with_its_velocities"}}})}};
  s2["state_check"] = {{"isolations", 0}, {"neighbours", json::array({{{"station", 1}, {"isolations", 0}, {"readmissions", 0}, {"isolated_ticks", 0}}})}};
  std::ofstream(dir + "/station-1.json") << s1.dump();
  std::ofstream(dir + "/station-2.json") << s2.dump();
  const json s = merge_run(dir);
  CHECK_EQUAL(12u, s["resilient_excluded_ticks"].get<unsigned>());
  for (const auto& l : s["link_stats"]) {  // link to <- from: the receiver's counts
    const bool at_1 = l["to"].get<int>() == 1;
    CHECK_EQUAL(at_1 ? 7u : 5u, l["resilient_excluded_ticks"].get<unsigned>());
    CHECK_EQUAL(at_1 ? 2u : 0u, l["state_check_isolations"].get<unsigned>());
    CHECK_EQUAL(at_1 ? 300u : 0u, l["state_check_isolated_ticks"].get<unsigned>());
  }
  CHECK_EQUAL(7u, s["stations"][0]["resilient_excluded_ticks"].get<unsigned>());
  CHECK_EQUAL(2u, s["stations"][0]["state_check_isolations"].get<unsigned>());
  CHECK_EQUAL(2u, s["state_check"]["isolations"].get<unsigned>());
  CHECK_EQUAL(1u, s["state_check"]["readmissions"].get<unsigned>());
  CHECK_EQUAL(300u, s["state_check"]["isolated_ticks"].get<unsigned>());
  CHECK_EQUAL(1u, s["flags"].size());
  STRCMP_EQUAL("station 1 isolated station 2 2 time(s) (neighbour state check: inconsistent_with_its_velocities)", s["flags"][0].get<std::string>().c_str());
  STRCMP_CONTAINS("; FLAGGED: station 1 isolated station 2", merge_result_line(s).c_str());
}

// A merge reads the stations' files a row at a time: a run 100 times longer (200,000 traced ticks a
// station: held at once, ~180 MB of rows) merges in the same memory as a short one.
TEST(RunMerge, TheMergesMemoryDoesNotGrowWithTheRunsLength) {
  const std::string short_dir = write_two_stations("haptic-metrics-merge-short", shrinking_gap, 2000);
  const std::string long_dir = write_two_stations("haptic-metrics-merge-long", shrinking_gap, 200000);
  const long short_kB = merge_peak_kB(short_dir), long_kB = merge_peak_kB(long_dir);
  CHECK_TEXT(long_kB < short_kB + 8 * 1024,
             ("peak RSS " + std::to_string(long_kB) + " kB merging 200,000 ticks against " + std::to_string(short_kB) + " kB for 2,000").c_str());
  fs::remove_all(short_dir);
  fs::remove_all(long_dir);
}

TEST(RunMerge, AMissingOrFailedStationIsRefusedNamingIt) {
  const std::string dir = write_two_stations("haptic-metrics-merge-bad", shrinking_gap);
  fs::remove(dir + "/station-2.json");
  try {
    merge_run(dir);
    FAIL("merged without station-2.json");
  } catch (const MergeError& e) {
    CHECK_TEXT(std::string(e.what()).find("station-2.json") != std::string::npos, e.what());
  }
  json s2 = station_json(2, 2, 0.01);
  s2["error"] = "no neighbour answered";
  std::ofstream(dir + "/station-2.json") << s2.dump();
  try {
    merge_run(dir);
    FAIL("merged a station that reported an error");
  } catch (const MergeError& e) {
    CHECK_TEXT(std::string(e.what()).find("station 2 reported an error: no neighbour answered") != std::string::npos, e.what());
  }
}
