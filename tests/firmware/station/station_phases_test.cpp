// The phases of `haptic-station run` in-process over UDP on 127.0.0.1 (no root): a station
// alone, four stations on threads, and the conditions each exit code names. Runs are short
// (probing 0.3 s, run 0.4-1 s); nothing depends on timing beyond "packets flow on loopback".
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "drivers/device_factory.hpp"
#include "drivers/simulated_device.hpp"
#include "firmware/run/merge.hpp"
#include "firmware/sim/simulator.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/run.hpp"
#include "firmware/station/tick.hpp"
#include "platform/clock.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;
using namespace haptic::firmware;
using nlohmann::json;

namespace {

// Without an impairment the index guards are 2-3 ticks, which a loaded machine's scheduling can
// exceed now and then: tests of other conditions accept any share of ticks without a neighbour
// (AHubWhoseNeighboursLeaveEarlyExitsNoNeighbour checks that condition with the default limit).
constexpr const char* kShort =
    "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 1.0\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 0.5\nmax_no_neighbour_fraction = 1.0\n";

json station_json(const std::string& dir, int id) {
  std::ifstream in(dir + "/station-" + std::to_string(id) + ".json");
  return json::parse(in);
}

// A number of the summary, NaN when it is null or missing (so a failed run fails a check, not the binary).
double number(const json& v) { return v.is_number() ? v.get<double>() : std::nan(""); }

bool has(const json& list, const std::string& name) {
  for (const auto& v : list)
    if (v == name) return true;
  return false;
}

// No condition but, perhaps, an edge drop: without an impairment the index guards are 2-3 ticks,
// which a loaded machine's scheduling can exceed now and then (named, no exit code of its own).
bool no_condition_but_edge_drops(const json& conditions) {
  return conditions.empty() || (conditions.size() == 1 && conditions[0] == "edge_drop_rule_acted");
}

// The paper's star (1 is the hub): four run_station() calls on four threads with one common epoch.
// station_extra[i] is appended to station i+1's [station] section. `before(id, text, overrides)`, if
// given, runs on each station's thread before its run (overrides.start_at is the common epoch; it
// may change the overrides).
using BeforeRun = std::function<void(int, const std::string&, RunOverrides&)>;
std::vector<int> run_four(const std::string& dir, int session, const std::vector<std::string>& station_extra,
                          const std::vector<std::string>& net_extra = {"", "", "", ""}, const BeforeRun& before = nullptr) {
  const int base = test::station_port_base();
  const double epoch_s = static_cast<double>(read_clocks().monotonic_ns) * 1e-9 + 2.0;  // four plans (scene builds) fit in 2 s: at load 13 on 2 vCPUs 1 s was too short once ("ready too late for the common epoch")
  std::vector<int> codes(4, -1);
  std::vector<std::thread> threads;
  std::atomic<bool> stop{false};
  for (int i = 1; i <= 4; ++i) {
    test::StationText s;
    s.id = i;
    s.peers = i == 1 ? std::vector<int>{2, 3, 4} : std::vector<int>{1};
    s.port_base = base;
    s.session = session;
    s.out_dir = dir;
    s.station_extra = station_extra[static_cast<std::size_t>(i - 1)];
    s.net_extra = net_extra[static_cast<std::size_t>(i - 1)];
    threads.emplace_back([&codes, &stop, &before, i, text = s.text(), epoch_s] {
      RunOverrides o;
      o.quiet = true;
      o.start_at = epoch_s;
      if (before) before(i, text, o);
      codes[static_cast<std::size_t>(i - 1)] = run_station(parse_station_file(text), o, stop);
    });
  }
  for (auto& t : threads) t.join();
  return codes;
}

}  // namespace

TEST_GROUP(StationPhases){};

TEST(StationPhases, AStationAloneExitsNonZeroSayingNoNeighbourAnsweredAndReportsNullMetrics) {
  const std::string dir = test::fresh_dir("alone");
  test::StationText s;
  s.id = 2;
  s.peers = {1};
  s.port_base = test::station_port_base();
  s.session = 101;
  s.out_dir = dir;
  s.station_extra = kShort;
  std::atomic<bool> stop{false};
  RunOverrides o;
  o.quiet = true;
  o.start_at = static_cast<double>(read_clocks().monotonic_ns) * 1e-9 + 2.0;  // opening device and endpoint fits in 2 s, also at load 13
  LONGS_EQUAL(kExitNoNeighbour, run_station(parse_station_file(s.text()), o, stop));
  const json j = station_json(dir, 2);
  CHECK(has(j["conditions"], "no_neighbour"));
  CHECK(j["error"].get<std::string>().find("no neighbour answered") != std::string::npos);
  STRCMP_CONTAINS("nothing received at all", j["error"].get<std::string>().c_str());  // the counted cause
  CHECK_EQUAL(0u, j["drops"]["by_reason"]["zero_length"].get<std::uint64_t>());  // every reason listed
  LONGS_EQUAL(kExitNoNeighbour, j["exit_code"].get<int>());
  LONGS_EQUAL(0, j["ticks_run"].get<int>());
  CHECK(j["port_energy_min_J"].is_null());
  CHECK(j["max_node_speed_m_per_s"].is_null());
  CHECK(j["no_neighbour_fraction"].is_null());
  CHECK(j["damping_Ns_per_m"].is_null());
  CHECK(j["links"][0]["rtt_mean_ms"].is_null());
  CHECK(j["links"][0]["one_way_mean_ms"].is_null());
  CHECK(j["links"][0]["tx_packets_run"].get<int>() == 0);
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, FourStationsOnThreadsRunEveryPhaseAndExitZero) {
  const std::string dir = test::fresh_dir("four");
  const std::vector<int> codes = run_four(dir, 102, {kShort, kShort, kShort, kShort});
  for (int i = 1; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json j = station_json(dir, i);
    CHECK(no_condition_but_edge_drops(j["conditions"]));
    CHECK(j["passivity_condition_met"].get<bool>());
    CHECK_FALSE(j["diverged"].get<bool>());
    // every period of the 500 planned was a tick or a period the loaded host skipped (ticks_run counts
    // only the ticks; a 2-core CI host skipped up to 30 % of them); a skipped period just before the
    // first run tick is in the set-up's share
    CHECK(number(j["ticks_run"]) > 0);
    CHECK_TEXT(number(j["ticks_run"]) + number(j["host"]["missed_cycles"]) >= number(j["run_ticks_planned"]) - 2, j["host"].dump().c_str());
    CHECK(number(j["rx_offered"]) > 50);  // the neighbours' packets reached the core (about 500 when unloaded)
    // Measured from the tick's counter, not zero by construction. How large it is depends on how the
    // host schedules four stations' threads (it exceeded 0.5 once at nice 19 on a loaded machine),
    // so only "some tick had a neighbour within its bound" is checked, with rx_offered above.
    DOUBLES_EQUAL(number(j["no_neighbour_ticks"]) / number(j["ticks_run"]), number(j["no_neighbour_fraction"]), 1e-12);
    CHECK(number(j["no_neighbour_fraction"]) < 1.0);
    CHECK(number(j["probe_loop"]["ticks"]) > 0);  // the probing phase ran (150 ticks when on time)
    CHECK(j["error"].is_null());
  }
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, FourStationsUnderSetPositionModulationRunWithoutDampingAndReportTheirEdges) {
  // station.consensus_passivity = "pspm" (rt/set_position_modulation.hpp): B_i = 0 at every station,
  // eq. (14) by construction, every edge's account within its reservoir E0 = pspm_reservoir_J.
  const std::string dir = test::fresh_dir("pspm");
  const std::string pspm = std::string(kShort) + "consensus_passivity = \"pspm\"\npspm_reservoir_J = 0.002\n";
  const std::vector<int> codes = run_four(dir, 103, {pspm, pspm, pspm, pspm});
  for (int i = 1; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json j = station_json(dir, i);
    STRCMP_EQUAL("pspm", j["consensus_passivity"].get<std::string>().c_str());
    DOUBLES_EQUAL(0.0, number(j["damping_Ns_per_m"]), 0.0);
    CHECK(number(j["damping_min_Ns_per_m"]) > 0);  // what eq. (18) would have asked for
    CHECK(j["passivity_condition_met"].get<bool>());
    LONGS_EQUAL(0, j["edge_drop_events"].get<int>());  // no delay bound: nothing dropped
    CHECK_EQUAL(static_cast<std::size_t>(i == 1 ? 3 : 1), j["pspm_edges"].size());
    for (const auto& e : j["pspm_edges"]) CHECK(number(e["edge_energy_peak_J"]) <= 0.002 + 1e-12);
  }
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, UnderSetPositionModulationTheMergedRunAndTheSimulatorReportTheSameD2OfEq13) {
  // d^2 of eq. (13) (model::eq13_d2_J): the copies' energies, the consensus springs and, under pspm,
  // 2 E0 per link. The merge of four in-process stations' files and the simulator of the same plan
  // must report the same bound (the merge used to count the copies' energies only).
  const std::string dir = test::fresh_dir("pspm-d2");
  const std::string pspm = std::string(kShort) + "consensus_passivity = \"pspm\"\npspm_reservoir_J = 0.002\n";
  const std::vector<int> codes = run_four(dir, 113, {pspm, pspm, pspm, pspm});
  for (int c : codes) LONGS_EQUAL(kExitOk, c);
  const json merged = merge_run(dir);
  test::StationText st;
  st.id = 1;
  st.peers = {2, 3, 4};
  st.out_dir = dir;
  st.station_extra = pspm;
  const PlanResult plan = plan_station(parse_station_file(st.text()), RunOverrides{}, read_clocks());
  LONGS_EQUAL(static_cast<int>(PhaseStatus::kOk), static_cast<int>(plan.status));
  const SimResult sim = run_simulation(*plan.plan->built, SimOptions{});
  const double links = static_cast<double>(plan.plan->built->spec.topology.size());
  CHECK(sim.passivity_bound_J >= 2 * links * 0.002);  // the reservoirs are in it
  DOUBLES_EQUAL(sim.passivity_bound_J, number(merged["passivity_bound_J"]), 1e-9);
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, FourStationsWithThePredictiveDeadbandSendAStateAtLeastEveryIntervalAndNotEveryTick) {
  // station.tx_predict under pspm, band 1 um, max interval 20 (rt/tx_deadband.hpp), through the real
  // station's tick: each trace row marks whether the tick sent its state (kTraceStateSent); no gap
  // between two sends is longer than the interval, and not every tick sends a state.
  const std::string dir = test::fresh_dir("deadband");
  // probing sends at the deadband's pace: 20 round trips at every 20th tick need 1.2 s of it, and a
  // loaded host's stalls cost windows (17-19 round trips at 40 % of the periods skipped): 1.5 s
  std::string db = std::string(kShort);
  db.replace(db.find("probe_s = 0.3"), 13, "probe_s = 1.5");
  db += "consensus_passivity = \"pspm\"\ntx_deadband_mm = 0.001\ntx_max_interval_ticks = 20\ntx_predict = true\n"
                         "loss_allowance_max_ticks = 1000\n";  // pspm needs no loss allowance: a loaded machine's late probes must not refuse
  const std::vector<int> codes = run_four(dir, 110, {db, db, db, db});
  for (int i = 1; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json j = station_json(dir, i);
    CHECK(j["trace_marks_state_sent"].get<bool>());
    CHECK_TRUE(j["tx_deadband"]["position_m"].get<double>() > 0);
    LONGS_EQUAL(0, j["records"]["trace_rows_lost"].get<long>());  // a row per tick run: the gaps below are in ticks run
    std::ifstream tr(dir + "/station-" + std::to_string(i) + "-trace.csv");
    std::string line;
    std::getline(tr, line);  // header: k,t_s,...,flags (column 18),...
    // the gap between sends in ticks RUN (trace rows): a period the loop skipped on a loaded host
    // advances k without a tick that could send (k gap 21 seen with 6 missed cycles)
    long ticks = 0, sent = 0, last = -1, longest_gap = 0;
    while (std::getline(tr, line)) {
      std::vector<std::string> cols;
      std::size_t at = 0;
      for (std::size_t c; (c = line.find(',', at)) != std::string::npos; at = c + 1) cols.push_back(line.substr(at, c - at));
      cols.push_back(line.substr(at));
      const auto flags = static_cast<std::uint32_t>(std::stoul(cols[18]));
      ++ticks;
      if (flags & kTraceStateSent) {
        if (last >= 0) longest_gap = std::max(longest_gap, ticks - last);
        last = ticks;
        ++sent;
      }
    }
    CHECK_TEXT(ticks > 100, ("ticks traced: " + std::to_string(ticks)).c_str());
    CHECK_TEXT(longest_gap > 0 && longest_gap <= 20, ("longest gap: " + std::to_string(longest_gap)).c_str());
    // measured 26-29 % on a quiet machine, 79 % at load 6 (late packets change the copies' motion):
    // only "not every tick" is independent of the machine's load
    CHECK_TEXT(sent < ticks, ("sent " + std::to_string(sent) + " of " + std::to_string(ticks)).c_str());
  }
  std::filesystem::remove_all(dir);
}

// haptic-lab check --probe: every station probes at the common epoch, reports each link's round
// trips and clock offset, and stops before coupling (no tick of the run, no device force).
TEST(StationPhases, ProbeOnlyMeasuresEveryLinkAndStopsBeforeCoupling) {
  const std::string dir = test::fresh_dir("probe-only");
  const std::vector<int> codes =
      run_four(dir, 112, {kShort, kShort, kShort, kShort}, {"", "", "", ""}, [](int, const std::string&, RunOverrides& o) { o.probe_only = true; });
  for (int i = 1; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json j = station_json(dir, i);
    CHECK(no_condition_but_edge_drops(j["conditions"]));
    DOUBLES_EQUAL(0.0, number(j["ticks_run"]), 0.0);  // stopped before the run
    CHECK(j["damping_Ns_per_m"].is_null());            // and before the core was built
    CHECK(j["lifecycle"].value("probe_only", false));
    for (const auto& l : j["links"]) {
      CHECK(number(l["rtt_samples"]) > 0);       // reachability: measured round trips
      CHECK(number(l["rtt_bound_ms_now"]) > 0);
    }
    CHECK_EQUAL(i == 1 ? 3u : 1u, j["lifecycle"]["clock_offsets"].size());  // one offset per neighbour
  }
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, AnUnknownConsensusPassivityIsAConfigErrorNamingTheKey) {
  try {
    parse_station_file("[station]\nid = 1\nconsensus_passivity = \"adaptive\"\n[net]\nsession_id = 1\n");
    FAIL("no error");
  } catch (const std::exception& e) {
    CHECK_TEXT(std::string(e.what()).find("station.consensus_passivity = \"adaptive\"") != std::string::npos, e.what());
  }
}

TEST(StationPhases, BothEndsOfEveryLinkUseTheSameRoundTripBoundTheLargerOfTheTwo) {
  // The hub adds 20 ms to every bound it measures (net.rtt_margin_s), so its own bounds are about
  // 10 ticks above the leaves'; each end learns the other's frozen bound while probing and both
  // use the larger, so the guards and eq. (18) at both ends agree on every link.
  const std::string dir = test::fresh_dir("agree");
  const std::vector<int> codes = run_four(dir, 107, {kShort, kShort, kShort, kShort}, {"rtt_margin_s = 0.024\n", "", "", ""});
  const json hub = station_json(dir, 1);
  int links_with_different_bounds = 0;  // where "the larger" decides something
  for (int i = 2; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json leaf = station_json(dir, i);
    const json& to_hub = leaf["links"][0];
    json from_hub;
    for (const auto& l : hub["links"])
      if (l["peer"] == i) from_hub = l;
    // The set-up makes the hub's bound the larger one (12 ticks of margin), but a loaded machine can
    // inflate a leaf's own bound past it (CI saw 30 against 20): either way both ends must use the
    // larger of the two own bounds, so that is what is checked, whichever end it came from.
    const int hub_own = from_hub["round_trip_bound_ticks_own"].get<int>(), leaf_own = to_hub["round_trip_bound_ticks_own"].get<int>();
    if (hub_own != leaf_own) ++links_with_different_bounds;
    CHECK_EQUAL(std::max(hub_own, leaf_own) + from_hub["loss_allowance_ticks"].get<int>(), from_hub["round_trip_bound_ticks"].get<int>());
    CHECK_EQUAL(from_hub["round_trip_bound_ticks_own"].get<int>(), to_hub["round_trip_bound_ticks_peer"].get<int>());
    CHECK_EQUAL(to_hub["round_trip_bound_ticks_own"].get<int>(), from_hub["round_trip_bound_ticks_peer"].get<int>());
    CHECK_EQUAL(from_hub["round_trip_bound_ticks"].get<int>(), to_hub["round_trip_bound_ticks"].get<int>());
    CHECK_EQUAL(from_hub["index_delay_bound_ticks"].get<int>(), to_hub["index_delay_bound_ticks"].get<int>());
  }
  CHECK(links_with_different_bounds > 0);  // the 12-tick margin: at least one link had two different bounds to choose from
  LONGS_EQUAL(kExitOk, codes[0]);
  std::filesystem::remove_all(dir);
}

namespace {

// The hub's link to leaf `leaf` in the hub's station JSON.
json hub_link(const json& hub, int leaf) {
  for (const auto& l : hub["links"])
    if (l["peer"] == leaf) return l;
  return json();
}

// Leaf 2 emulates the paper's link in its send path (5 % loss, 8 ms mean), so the hub measures loss
// on the direction 2 -> 1 only; the other links are loopback.
const std::vector<std::string> kLossyLeaf2 = {"", "[net.impairment]\npreset = \"paper\"\n", "", ""};
std::string longer_probe() {
  std::string s = kShort;
  return s.replace(s.find("probe_s = 0.3"), 13, "probe_s = 0.6");
}
const std::string kLongerProbe = longer_probe();

}  // namespace

TEST(StationPhases, EachStationMeasuresItsStepBoundsAndItsNeighboursEq18UsesTheTMaxItAnnounced) {
  // By default a station measures its step bounds while probing (this host's wake-up latency, at most
  // station.step_margin_max of the period), integrates the measured T_k within them and sends T^max in
  // its fingerprints; eq. (18) at each neighbour uses that T_j^max. The hub's T^max is set here
  // (station.period_max_s = 2.45 ms, above any measured one: the cap is 2.4 ms), so the leaves' B_i
  // must be eq. (18) at 2.45 ms.
  const std::string dir = test::fresh_dir("steps");
  const std::string hub_extra = std::string(kShort) + "period_max_s = 0.00245\n";
  const std::vector<int> codes = run_four(dir, 112, {hub_extra, kShort, kShort, kShort});
  const double T = 0.002;
  const json hub = station_json(dir, 1);
  DOUBLES_EQUAL(0.00245, hub["step_bounds"]["t_max_s"].get<double>(), 0);
  for (int i = 2; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json leaf = station_json(dir, i);
    const json& b = leaf["step_bounds"];
    CHECK_TRUE(b["measured"].get<bool>());
    CHECK(b["wakes_measured"].get<long long>() > 50);
    CHECK(b["t_min_s"].get<double>() < T && b["t_max_s"].get<double>() > T && b["t_max_s"].get<double>() <= 1.2 * T + 1e-12);
    // the leaf announced its bound, and the hub used it
    const json from_hub = hub_link(hub, i);
    DOUBLES_EQUAL(b["t_max_s"].get<double>(), from_hub["step_max_s_peer"].get<double>(), 1e-9);
    DOUBLES_EQUAL(b["t_max_s"].get<double>(), from_hub["step_max_s_used"].get<double>(), 1e-9);
    // the leaf used the hub's 2.45 ms in eq. (18): with the paper's gains (lambda_max P = 1000 N/m,
    // D = 5 I) beta = R/2 T_j^max 1000 + 1/2 (T_j^max / T_i^min - 1) 5
    const json& to_hub = leaf["links"][0];
    DOUBLES_EQUAL(0.00245, to_hub["step_max_s_used"].get<double>(), 1e-9);
    const double R = to_hub["assumed_round_trip_ticks"].get<double>(), t_max_j = 0.00245, t_min_i = b["t_min_s"].get<double>();
    const double beta = R / 2 * t_max_j * 1000 + 0.5 * (t_max_j / t_min_i - 1) * 5;
    DOUBLES_EQUAL(beta, leaf["damping_min_Ns_per_m"].get<double>(), 1e-9 * beta);
  }
  LONGS_EQUAL(kExitOk, codes[0]);
  std::filesystem::remove_all(dir);
}


TEST(StationPhases, ALossyProbeRaisesTheLossAllowanceAndBothEndsOfTheLinkUseTheSame) {
  // Each end fixes its loss allowance from the probe loss it measured on its incoming direction
  // (station.loss_allowance_ticks = -1, the default) and sends it with its frozen round-trip bound;
  // both use the larger. The hub measures the 5 % loss of leaf 2's packets: its allowance for that
  // link is raised by it, and leaf 2 (whose incoming direction is not impaired) uses it too.
  const std::string dir = test::fresh_dir("lossy");
  const std::vector<int> codes = run_four(dir, 108, {kLongerProbe, kLongerProbe, kLongerProbe, kLongerProbe}, kLossyLeaf2);
  const json hub = station_json(dir, 1);
  LONGS_EQUAL(-1, hub["loss_allowance_ticks"].get<int>());  // measured, not configured
  // The hub's allowance for leaf 2 is the model's for the loss it measured (2 x the per-direction L,
  // run 500 ticks x 6 directed links), and above what the same probe without loss would give.
  const json lossy = hub_link(hub, 2);
  const ProbeLoss measured{lossy["probe_loss"]["lost"].get<long long>(), lossy["probe_loss"]["expected"].get<long long>(),
                           lossy["probe_loss"]["longest_gap"].get<long long>()};
  CHECK(measured.lost >= 3);  // 5 % of about 190
  CHECK(measured.expected > 100);
  // (capped at the default maximum, 16, which a loaded machine's stalls can reach)
  LONGS_EQUAL(std::min(16, round_trip_loss_allowance(measured, 500, 6)), lossy["loss_allowance_ticks_own"].get<int>());
  CHECK(lossy["loss_allowance_ticks_own"].get<int>() > round_trip_loss_allowance(ProbeLoss{0, measured.expected, 0}, 500, 6));
  for (int i = 2; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    const json from_hub = hub_link(hub, i), to_hub = station_json(dir, i)["links"][0];
    // both ends: the same allowance, the larger of the two, and each learned the other's
    CHECK_EQUAL(from_hub["loss_allowance_ticks_own"].get<int>(), to_hub["loss_allowance_ticks_peer"].get<int>());
    CHECK_EQUAL(to_hub["loss_allowance_ticks_own"].get<int>(), from_hub["loss_allowance_ticks_peer"].get<int>());
    CHECK_EQUAL(std::max(from_hub["loss_allowance_ticks_own"].get<int>(), to_hub["loss_allowance_ticks_own"].get<int>()),
                from_hub["loss_allowance_ticks"].get<int>());
    CHECK_EQUAL(from_hub["loss_allowance_ticks"].get<int>(), to_hub["loss_allowance_ticks"].get<int>());
    CHECK_EQUAL(from_hub["round_trip_bound_ticks"].get<int>(), to_hub["round_trip_bound_ticks"].get<int>());
    CHECK_EQUAL(from_hub["index_delay_bound_ticks"].get<int>(), to_hub["index_delay_bound_ticks"].get<int>());
  }
  LONGS_EQUAL(kExitOk, codes[0]);
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, WithTheDeadbandProbingSendsAtItsPaceAndCountsLossInPackets) {
  // tx_max_interval_ticks = 5: probing sends a state on every 5th tick only (a large scene's state
  // every tick would swamp the links), and each end counts its neighbours' probe packets at that pace:
  // about 200 / 5 packets to the freeze, none lost on loopback, where counting ticks would find 4 in
  // 5 missing. A sender's skipped periods do count (its paced send was delayed past the pace): a
  // loaded 2-core host skipped up to 25 % of them here, so the check is at half, far below 4 in 5.
  const std::string dir = test::fresh_dir("paced");
  const std::string paced = kLongerProbe + "tx_deadband_mm = 0.01\ntx_max_interval_ticks = 5\n";
  const std::vector<int> codes = run_four(dir, 114, {paced, paced, paced, paced});
  const json hub = station_json(dir, 1);
  for (int i = 2; i <= 4; ++i) {
    LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
    for (const json& link : {hub_link(hub, i), station_json(dir, i)["links"][0]}) {
      const long long expected = link["probe_loss"]["expected"].get<long long>(), lost = link["probe_loss"]["lost"].get<long long>();
      // 200 ticks to the freeze (less the round-trip bound's last ones) / 5, and on a loaded host one
      // more for each send a skipped period delayed (counted lost: 58 with 27 at 40 % of the periods skipped)
      CHECK_TEXT(expected >= 20 && expected <= 80, link["probe_loss"].dump().c_str());
      CHECK_TEXT(lost * 2 <= expected, link["probe_loss"].dump().c_str());  // not the 4 in 5 of a tick count
    }
  }
  LONGS_EQUAL(kExitOk, codes[0]);
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, AMeasuredLossAllowanceAboveTheConfiguredMaximumIsCappedThereAndMarked) {
  // 0 of about 190 lost needs 6 ticks, the 5 % of leaf 2's link 10 (measured: 11-13 of 190): with
  // a maximum of 7 the hub caps leaf 2's link there and marks it; both ends still agree.
  const std::string dir = test::fresh_dir("lossmax");
  const std::string hub = kLongerProbe + "loss_allowance_max_ticks = 7\n";
  const std::vector<int> codes = run_four(dir, 109, {hub, kLongerProbe, kLongerProbe, kLongerProbe}, kLossyLeaf2);
  LONGS_EQUAL(kExitOk, codes[0]);
  const json lossy = hub_link(station_json(dir, 1), 2), leaf = station_json(dir, 2)["links"][0];
  CHECK_TRUE(lossy["loss_allowance_capped"].get<bool>());
  LONGS_EQUAL(7, lossy["loss_allowance_ticks_own"].get<int>());
  CHECK(round_trip_loss_allowance(ProbeLoss{lossy["probe_loss"]["lost"].get<long long>(), lossy["probe_loss"]["expected"].get<long long>(),
                                            lossy["probe_loss"]["longest_gap"].get<long long>()}, 500, 6) > 7);  // what it measured
  LONGS_EQUAL(7, leaf["loss_allowance_ticks_peer"].get<int>());  // the capped value is the one sent
  CHECK_EQUAL(lossy["loss_allowance_ticks"].get<int>(), leaf["loss_allowance_ticks"].get<int>());
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, ARunEndingBeforeTheScriptedReleaseExitsWithItsOwnCode) {
  const std::string dir = test::fresh_dir("early");
  const std::string early =
      "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 0.4\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 0.5\nmax_no_neighbour_fraction = 1.0\n";
  const std::vector<int> codes = run_four(dir, 103, {early, early, early, early});
  for (int i = 1; i <= 4; ++i) {
    LONGS_EQUAL(kExitBeforeRelease, codes[static_cast<std::size_t>(i - 1)]);
    const json j = station_json(dir, i);
    CHECK(has(j["conditions"], "ended_before_release"));
    CHECK(j["warnings"][0].get<std::string>().find("before the scripted release") != std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, DampingBelowEq18OnTheMeasuredBoundsExitsPassivityNotMet) {
  const std::string dir = test::fresh_dir("passivity");
  const std::string low = std::string(kShort) + "damping_Ns_per_m = 0.5\n";  // far below eq. (18) for the hub
  const std::vector<int> codes = run_four(dir, 104, {low, kShort, kShort, kShort});
  LONGS_EQUAL(kExitPassivityNotMet, codes[0]);
  const json j = station_json(dir, 1);
  CHECK(has(j["conditions"], "passivity_condition_not_met"));
  CHECK_FALSE(j["passivity_condition_met"].get<bool>());
  CHECK(number(j["damping_Ns_per_m"]) < number(j["damping_min_Ns_per_m"]));
  for (int i = 2; i <= 4; ++i) CHECK_FALSE(has(station_json(dir, i)["conditions"], "passivity_condition_not_met"));
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, AStationWhoseCopyDivergesExitsDivergedAndNamesIt) {
  // The core's divergence check (rt::StationConfig::divergence_speed_m_per_s: a node faster than
  // this) with a bound the scripted push exceeds: the core enters its safe state, the run goes on
  // with zero force, and the station exits 4 (diverged comes before the latched safe state).
  const std::string dir = test::fresh_dir("diverged");
  const std::string tight = std::string(kShort) + "divergence_speed_m_per_s = 1e-4\n";
  const std::vector<int> codes = run_four(dir, 106, {kShort, tight, kShort, kShort});
  LONGS_EQUAL(kExitDiverged, codes[1]);
  const json j = station_json(dir, 2);
  CHECK(has(j["conditions"], "diverged"));
  CHECK(j["diverged"].get<bool>());
  CHECK(number(j["diverged_at_s"]) >= 0);
  LONGS_EQUAL(kExitDiverged, j["exit_code"].get<int>());
  std::filesystem::remove_all(dir);
}

// The report phase of a station whose per-edge energy gate tripped: the plan of a leaf from its
// station file, a core with the file's bound (1 uJ, no leak) driven by a neighbour whose copy sits
// 1 mm off (its P coupling puts energy in: the gate trips and acts as the damper). An honest run
// does not trip the default 0.1 J (ClosedLoop.the_honest_paper_best_run_never_trips...), so the
// gate is made to act here, deterministically, without sockets. The run is never "stable": exit 10,
// condition held_by_gate, verdict held_by_gate, and "gate" with the trips, the energy the gate
// removed (the links' figures added up) and the worst port energy.
TEST(StationPhases, AStationTheEnergyGateHeldExitsHeldByTheGateAndSaysWhatTheGateDid) {
  test::StationText s;
  s.id = 2;
  s.peers = {1};
  s.out_dir = test::fresh_dir("gate");
  s.station_extra = std::string(kShort) + "edge_energy_bound_J = 1e-6\nedge_energy_leak_W = 0\n";
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK_TEXT(pr.plan != nullptr, pr.error.c_str());
  const StationPlan& plan = *pr.plan;
  BuildResult build;
  build.status = PhaseStatus::kOk;
  build.passivity_condition_met = true;
  rt::StationConfig cfg = plan.built->station_config(plan.me);
  for (auto& n : cfg.neighbors) n.energy_bound_J = plan.file.station.edge_energy_bound_J, n.energy_release_J = 0.5e-6, n.energy_leak_W = 0;
  build.core = std::make_unique<rt::StationCore>(cfg);
  rt::StationCore& core = *build.core;
  const int dofs = plan.built->scene.dofs;
  Eigen::VectorXd xj = plan.built->scene.x_d, vj = Eigen::VectorXd::Zero(dofs);
  for (int p = 0; p < plan.built->scene.nodes; ++p) xj[3 * p] += 1e-3;
  TickCounters cnt;
  for (std::int64_t k = 0; k < 300; ++k) {
    core.rx(0).offer(k, 0, xj.data(), vj.data(), dofs);
    core.tick(k, plan.built->vp_start[static_cast<std::size_t>(plan.me)]);
    cnt.port_min_J = std::min(cnt.port_min_J, core.energy().port_J);
    ++cnt.ticks_run;
  }
  StationOutcome o;
  o.plan = &plan;
  o.build = &build;
  o.counters = &cnt;
  const RunConditions c = run_conditions(o);
  CHECK_TRUE(c.held_by_gate);
  LONGS_EQUAL(kExitHeldByGate, exit_code(c));
  const json j = station_summary(o, c);
  LONGS_EQUAL(kExitHeldByGate, j["exit_code"].get<int>());
  CHECK(has(j["conditions"], "held_by_gate"));
  STRCMP_EQUAL("held_by_gate", j["verdict"].get<std::string>().c_str());
  const json& g = j["gate"];
  CHECK(g["held_by_gate"].get<bool>());
  CHECK(number(g["energy_gate_trips"]) >= 1);
  DOUBLES_EQUAL(number(j["edge_energy_trips"]), number(g["energy_gate_trips"]), 0);
  CHECK(number(g["energy_gate_gated_ticks"]) >= number(g["energy_gate_trips"]));
  CHECK(number(g["energy_gate_removed_J"]) > 0);  // the damper took energy out of the copy
  DOUBLES_EQUAL(core.edge_gate().removed_J(0), number(g["energy_gate_removed_J"]), 0);
  DOUBLES_EQUAL(cnt.port_min_J, number(g["port_energy_min_J"]), 0);
  DOUBLES_EQUAL(number(j["port_energy_min_J"]), number(g["port_energy_min_J"]), 0);
  std::filesystem::remove_all(s.out_dir);
}

TEST(StationPhases, ALeafStartedAfterTheProbingPhaseRejoinsTheRunningSessionInProcess) {
  // The rejoin phase (firmware/station/rejoin.cpp) in-process: four stations start on the common epoch;
  // station 2's first run ends at run time 0.3 s (as if it had died), and it starts again with the
  // same epoch at run time 0.6 s (a new endpoint: a new incarnation): it probes 0.2 s, learns the
  // session's epoch, takes over the hub's object state and couples until the session's end.
  // The multi-process SIGKILL/restart test is station_run4_rejoin.
  const std::string dir = test::fresh_dir("rejoin");
  const std::string keys =
      "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 2.0\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 1.5\n"
      "max_no_neighbour_fraction = 1.0\nrejoin_probe_s = 0.2\nstate_every = 1\n";
  std::atomic<bool> stop{false};
  const std::vector<int> codes = run_four(dir, 111, {keys, keys, keys, keys}, {"", "", "", ""}, [&](int id, const std::string& text, const RunOverrides& o) {
    if (id != 2) return;
    RunOverrides first = o;
    first.duration_s = 0.3;
    run_station(parse_station_file(text), first, stop);  // ends before the release: exit 8
    haptic::platform::sleep_until_monotonic_ns(static_cast<std::int64_t>((o.start_at + 0.4 + 0.6) * 1e9));
  });
  const json j = station_json(dir, 2);
  CHECK_TEXT(j["lifecycle"].contains("rejoin"), j.dump().substr(0, 400).c_str());
  const json& rj = j["lifecycle"]["rejoin"];
  LONGS_EQUAL(1, rj["state_from_station"].get<int>());  // the hub's copy
  LONGS_EQUAL(1, rj["epoch_from_station"].get<int>());
  CHECK(std::abs(number(rj["epoch_shift_ms"])) < 20);   // one host, one clock: the same epoch
  CHECK(rj["coupled_at_tick"].get<long long>() > 0);
  CHECK(number(j["ticks_run"]) > 100);                   // it ran coupled until the session's end
  CHECK(codes[1] != kExitNoNeighbour && codes[1] != kExitRunFailed && codes[1] != kExitConfigError);
  // It took over the hub's copy: its first state row is within 1 mm of the hub's row of that tick.
  // (The hub holds the pushed shape from 0.3 s to the release at 1.5 s: a few ticks apart are alike.)
  const auto rows = [&](int id) {
    std::ifstream in(dir + "/station-" + std::to_string(id) + "-state.csv");
    std::vector<std::vector<double>> out;
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      std::vector<double> r;
      std::stringstream ss(line);
      for (std::string cell; std::getline(ss, cell, ',');) r.push_back(std::stod(cell));
      out.push_back(r);
    }
    return out;
  };
  const auto hub = rows(1), leaf = rows(2);
  CHECK(!leaf.empty());
  // the hub's row of that tick, or of the nearest tick it ran (a loaded host skips periods)
  const std::vector<double>* near = nullptr;
  for (const auto& h : hub)
    if (!leaf.empty() && (near == nullptr || std::abs(h[0] - leaf[0][0]) < std::abs((*near)[0] - leaf[0][0]))) near = &h;
  CHECK_TEXT(near != nullptr && std::abs((*near)[0] - leaf[0][0]) <= 10, "no hub row within 10 ticks of the leaf's first");
  double largest = 0;
  for (std::size_t c = 1; c + 2 < near->size(); c += 3)
    largest = std::max(largest, std::hypot((*near)[c] - leaf[0][c], (*near)[c + 1] - leaf[0][c + 1], (*near)[c + 2] - leaf[0][c + 2]));
  CHECK_TEXT(largest <= 1e-3, ("first rejoined state row " + std::to_string(largest * 1e3) + " mm from the hub's copy").c_str());
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, AHubWhoseNeighboursLeaveEarlyExitsNoNeighbour) {
  const std::string dir = test::fresh_dir("left");
  const std::string leaf =
      "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 0.3\npush_start_s = 0.05\npush_end_s = 0.1\nrelease_s = 0.2\nmax_no_neighbour_fraction = 1.0\n";
  const std::string hub = "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 1.2\npush_start_s = 0.05\npush_end_s = 0.1\nrelease_s = 0.2\n";
  const std::vector<int> codes = run_four(dir, 105, {hub, leaf, leaf, leaf});
  LONGS_EQUAL(kExitNoNeighbour, codes[0]);
  const json j = station_json(dir, 1);
  CHECK(has(j["conditions"], "no_neighbour"));
  CHECK(number(j["no_neighbour_fraction"]) > 0.5);
  for (int i = 2; i <= 4; ++i) LONGS_EQUAL(kExitOk, codes[static_cast<std::size_t>(i - 1)]);
  // It says why: the longest span without a usable neighbour covers the time after the leaves' 0.3 s
  // run to the hub's end (1.2 s; on a loaded host it may start earlier, with the leaves' last packets
  // arriving late in it), each leaf named with the age of its newest data (from before 0.3 s) against
  // N̄, SILENT when no packet of it arrived in the span, else LATE, and this host's figures.
  const json& span = j["explanation"]["no_neighbour_spans"]["longest"];
  CHECK_TEXT(number(span["from_s"]) < 0.6, span.dump().c_str());
  DOUBLES_EQUAL(1.2, number(span["to_s"]), 0.01);
  LONGS_EQUAL(3, static_cast<long>(span["links"].size()));
  const std::string lines = j["explanation"]["lines"].dump();
  for (const json& l : span["links"]) {
    const bool silent = number(l["packets"]) == 0;
    STRCMP_EQUAL(silent ? "silent" : "late", l["cause"].get<std::string>().c_str());
    CHECK_TEXT(number(l["age_ticks"]) >= 400 && number(l["age_ticks"]) > number(l["nbar_ticks"]), l.dump().c_str());  // 1.2 s - 0.3 s = 450 ticks
    const std::string named = "station " + std::to_string(l["peer"].get<int>()) + (silent ? " SILENT" : " LATE");
    STRCMP_CONTAINS(named.c_str(), lines.c_str());
  }
  STRCMP_CONTAINS("this host over the run loop: wake-up P99", lines.c_str());
  CHECK(j["host"]["wake_p99_ms"].is_number());
  std::filesystem::remove_all(dir);
}

// A host stall, simulated by the test hook (RunOverrides::test_tick_hook, not an option of the
// station): the hub's tick sleeps 1.2 s at its first run tick from 150 on (a loaded host may skip
// tick 150 itself). The hub names the stall (exit 11: how many periods, from when to when) and its
// leaves name the hub silent over the same span (exit 7) with their own host's figures in it.
TEST(StationPhases, AHostStallIsNamedByTheStalledStationAndItsNeighboursSeeItSilentOverTheSameSpan) {
  const std::string dir = test::fresh_dir("stall");
  const std::string keys = "probe_s = 0.3\nsetup_gap_s = 0.1\nduration_s = 2.0\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 0.5\n";
  const std::vector<int> codes = run_four(dir, 112, {keys, keys, keys, keys}, {"", "", "", ""}, [](int id, const std::string&, RunOverrides& o) {
    if (id == 1) o.test_tick_hook = [stalled = false](std::int64_t kr) mutable {
      if (kr < 150 || stalled) return;
      stalled = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1200));
    };
  });
  const json hub = station_json(dir, 1);
  CHECK_TEXT(codes[0] == kExitMissedCycles, hub["explanation"].dump().c_str());
  const json& stall = hub["explanation"]["longest_stall"];
  CHECK_TEXT(number(stall["periods"]) >= 550 && number(stall["periods"]) <= 700, stall.dump().c_str());
  DOUBLES_EQUAL(0.30, number(stall["from_s"]), 0.05);  // run tick 150
  STRCMP_CONTAINS("the longest stall: ", hub["explanation"]["lines"].dump().c_str());
  CHECK(hub["host"]["starving"].get<bool>());  // ~600 of ~1000 periods skipped
  for (int i = 2; i <= 4; ++i) {
    const json leaf = station_json(dir, i);
    const std::string who = "station " + std::to_string(i) + ": " + leaf["explanation"].dump();
    CHECK_TEXT(codes[static_cast<std::size_t>(i - 1)] == kExitNoNeighbour, who.c_str());
    const json& span = leaf["explanation"]["no_neighbour_spans"]["longest"];
    // it covers the stall (0.3-1.5 s, from N̄ after its start); on a loaded host it may begin earlier and
    // end later (the hub's I/O thread and the age guard catching up)
    CHECK_TEXT(number(span["from_s"]) < 0.45, who.c_str());
    CHECK_TEXT(number(span["to_s"]) > 1.4 && number(span["to_s"]) <= 2.0, who.c_str());  // to the stall's end (1.5 s) or later on a loaded host
    CHECK_TEXT(number(span["links"][0]["age_ticks"]) >= 550, who.c_str());  // the hub's newest data is from before the stall
    // none arrived: certain when the span began with the stall and this leaf kept its period; a leaf
    // whose own host starved in it (a 100 ms wake-up on a loaded host) reads the hub's last pre-stall
    // packet late, inside the span, and names the hub LATE with its own host STARVING
    const bool silent = number(span["links"][0]["packets"]) == 0;
    if (number(span["from_s"]) >= 0.29 && !span["host_starving"].get<bool>()) CHECK_TEXT(silent, who.c_str());
    STRCMP_EQUAL(silent ? "silent" : "late", span["links"][0]["cause"].get<std::string>().c_str());
    STRCMP_CONTAINS(silent ? "station 1 SILENT" : "station 1 LATE", leaf["explanation"]["lines"].dump().c_str());
    // the leaf's own host verdict in the span follows its own measurements
    const bool missed = number(span["overruns"]) > 0 || number(span["missed_cycles"]) > 0 || number(span["wake_max_ms"]) >= 2.0;
    CHECK_EQUAL(missed, span["host_starving"].get<bool>());
  }
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, AnExceptionAtTheLoopBoundaryEntersTheSafeStateAndIsReported) {
  test::StationText s;
  s.peers = {2, 3, 4};
  s.out_dir = test::fresh_dir("boundary");
  s.station_extra = kShort;
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK(pr.status == PhaseStatus::kOk);
  StationPlan plan = *pr.plan;
  plan.times.epoch_ns = read_clocks().monotonic_ns + 50'000'000 - plan.times.run_k0 * plan.times.period_ns;  // the run starts in 50 ms
  drivers::OpenedDevice dev = drivers::open_device(plan.device);
  std::atomic<bool> stop{false};
  std::int64_t ticks = 0;
  const RunTickFn tick = [&](std::int64_t, std::int64_t, const platform::TickInfo&) {
    const double push[3] = {1.0, 0, 0};
    dev.device->command_force(push);
    if (++ticks == 6) throw std::runtime_error("injected fault in tick 5");
  };
  const RunPhaseResult r = run_periodic(plan, dev.device.get(), tick, stop, RunObserver{});
  CHECK(r.loop_exception);
  CHECK(r.status == PhaseStatus::kFailed);
  CHECK(r.loop_exception_what.find("injected fault in tick 5") != std::string::npos);
  LONGS_EQUAL(6, ticks);  // the loop ended at the throwing tick
  dev.simulated->service(1.0, plan.built->spec.period_s);  // the backend takes the last commanded force
  double f[3] = {9, 9, 9};
  dev.simulated->last_output_force(f);
  DOUBLES_EQUAL(0.0, f[0], 0);  // zero force, not the tick's 1 N
  // the report names it and exits with the safe-state code
  StationOutcome o;
  o.plan = &plan;
  o.run = &r;
  o.failure = r.message;
  o.failure_status = r.status;
  const RunConditions c = run_conditions(o);
  CHECK(c.safe_state_latched);
  LONGS_EQUAL(kExitSafeState, exit_code(c));
  dev.device->stop();
  std::filesystem::remove_all(s.out_dir);
}

// A station whose clock is 0.3 s behind (its epoch 0.3 s later on the common clock) couples: each
// end maps the other's sequence numbers onto its own grid by the offset measured while probing
// (station.clock_offset_limit_ms, default 1 s). Without the mapping the hub exits 3 and the leaf 7.
TEST(StationPhases, AStationWhoseClockIsOffByAThirdOfASecondRunsWithTheOthers) {
  const std::string dir = test::fresh_dir("clock");
  const std::string keys = "probe_s = 1.2\nsetup_gap_s = 0.1\nduration_s = 2.0\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 0.5\n"
                           "max_no_neighbour_fraction = 0.5\n";
  const std::vector<int> codes = run_four(dir, 109, {keys, keys, keys, keys}, {"", "", "", ""}, [](int id, const std::string&, RunOverrides& o) {
    if (id == 2) o.start_at += 0.3;
  });
  for (int i = 1; i <= 4; ++i) {
    const json j = station_json(dir, i);
    CHECK_TEXT(codes[static_cast<std::size_t>(i - 1)] == kExitOk, (std::to_string(i) + ": " + j["conditions"].dump() + " " + j["error"].dump()).c_str());
    CHECK(no_condition_but_edge_drops(j["conditions"]));
  }
  const json leaf = station_json(dir, 2), hub = station_json(dir, 1);
  DOUBLES_EQUAL(-300.0, number(leaf["lifecycle"]["clock_offsets"]["1"]["tick_grid_offset_ms"]), 10.0);
  CHECK(std::abs(number(leaf["lifecycle"]["clock_offsets"]["1"]["sequence_shift_ticks"]) + 150) <= 5);
  CHECK(std::abs(number(hub["lifecycle"]["clock_offsets"]["2"]["sequence_shift_ticks"]) - 150) <= 5);
  CHECK(number(leaf["rx_offered"]) > 300);  // the hub's packets reached the leaf's core (~850 of 1000 ticks overlap)
  CHECK(number(leaf["links"][0]["rx_accepted"]) > 300);
  std::filesystem::remove_all(dir);
}

// The set-up gap between probing and the run (no packets sent while the core is built) is no round
// trip: a neighbour's first run packets echo our last probe, held through the 0.5 s gap; those echoes
// are not samples (rtt_echoes_before_pause), so a clean run has no ~505 ms "round trip" and no
// false over-bound event per link.
TEST(StationPhases, TheGapBetweenProbingAndTheRunIsNoRoundTripAboveTheBound) {
  const std::string dir = test::fresh_dir("gap");
  const std::string keys = "probe_s = 0.4\nsetup_gap_s = 0.5\nduration_s = 1.0\npush_start_s = 0.1\npush_end_s = 0.3\nrelease_s = 0.5\n"
                           "max_no_neighbour_fraction = 1.0\n";
  run_four(dir, 110, {keys, keys, keys, keys});
  double set_aside = 0;
  for (int i = 1; i <= 4; ++i) {
    const json j = station_json(dir, i);
    for (const json& l : j["links"]) {
      const std::string who = std::to_string(i) + "->" + std::to_string(l["peer"].get<int>()) + ": rtt_max_ms " + l["rtt_max_ms"].dump();
      set_aside += number(l["rtt_echoes_before_pause"]);
      CHECK_TEXT(number(l["rtt_max_ms"]) < 400.0, who.c_str());  // not the 0.5 s gap (loopback: a few ms, ~120 at load 10)
    }
  }
  CHECK(set_aside >= 1);  // held echoes arrived and were set aside (on a link whose ends start their runs in step)
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, ExitCodesFollowTheDocumentedOrder) {
  RunConditions c;
  LONGS_EQUAL(kExitOk, exit_code(c));
  c.edge_drop_rule_acted = true;  // named, no code of its own
  LONGS_EQUAL(kExitOk, exit_code(c));
  c.held_by_gate = true;
  LONGS_EQUAL(kExitHeldByGate, exit_code(c));
  c.ended_before_release = true;
  LONGS_EQUAL(kExitBeforeRelease, exit_code(c));
  c.failed = true;
  LONGS_EQUAL(kExitRunFailed, exit_code(c));
  c.no_neighbour = true;
  LONGS_EQUAL(kExitNoNeighbour, exit_code(c));
  c.missed_cycles = true;  // the stall is the cause of what its neighbours saw: named before 7
  LONGS_EQUAL(kExitMissedCycles, exit_code(c));
  c.passivity_not_met = true;
  LONGS_EQUAL(kExitPassivityNotMet, exit_code(c));
  c.safe_state_latched = true;
  LONGS_EQUAL(kExitSafeState, exit_code(c));
  c.passivity_not_met = c.no_neighbour = c.failed = c.ended_before_release = false;  // a safety stop is never undone by the gate's code
  LONGS_EQUAL(kExitSafeState, exit_code(c));
  c.passivity_not_met = c.no_neighbour = c.failed = c.ended_before_release = true;
  c.diverged = true;
  LONGS_EQUAL(kExitDiverged, exit_code(c));
  c.device_missing = true;
  LONGS_EQUAL(kExitDeviceMissing, exit_code(c));
  LONGS_EQUAL(10u, c.names().size());
}

// A station the host stalled (SIGSTOP, swap) says so: more than station.max_missed_cycles periods
// skipped by its run loop is the condition "missed_cycles" and exit 11; not
// a safety stop (the systemd unit may restart it).
TEST(StationPhases, MissedCyclesOverTheBoundAreAConditionWithTheirOwnExitCode) {
  test::StationText s;
  s.peers = {2, 3, 4};
  s.out_dir = "/tmp";
  s.station_extra = "max_missed_cycles = 500\n";
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK_TEXT(pr.status == PhaseStatus::kOk, pr.error.c_str());
  RunPhaseResult run;
  ProbeResult probe;
  StationOutcome o;
  o.plan = pr.plan.get();
  o.run = &run;
  o.probe = &probe;
  run.loop.missed_cycles = 500;  // at the bound: not over it
  CHECK_FALSE(run_conditions(o).missed_cycles);
  CHECK(exit_code(run_conditions(o)) != kExitMissedCycles);  // (8: this outcome ran no ticks)
  probe.loop_missed_cycles = 5000;  // probing's start-up skips are not counted
  CHECK_FALSE(run_conditions(o).missed_cycles);
  run.loop.missed_cycles = 501;
  RunConditions c = run_conditions(o);
  CHECK(c.missed_cycles);
  LONGS_EQUAL(501, static_cast<long>(c.missed_cycles_total));
  LONGS_EQUAL(kExitMissedCycles, exit_code(c));
  CHECK(has(json(c.names()), "missed_cycles"));
  run.loop.missed_cycles = 1259;  // a 2.5 s SIGSTOP
  probe.loop_missed_cycles = 0;
  LONGS_EQUAL(kExitMissedCycles, exit_code(run_conditions(o)));
  for (const int code : kSafetyStopExitCodes) CHECK(code != kExitMissedCycles);
  s.station_extra = "max_missed_cycles = -1\n";
  try {
    parse_station_file(s.text());
    FAIL("a negative max_missed_cycles was accepted");
  } catch (const std::invalid_argument& e) {
    CHECK_TEXT(std::string(e.what()).find("station.max_missed_cycles") != std::string::npos, e.what());
  }
}

// No silent stand-in: a configured device that cannot be started ends the run with its
// own exit code before any socket traffic; the station never plays a simulated user instead.
TEST(StationPhases, AMissingDeviceIsAnErrorNotASimulatedUser) {
  const std::string dir = test::fresh_dir("nodevice");
  test::StationText s;
  s.id = 2;
  s.peers = {1};
  s.port_base = test::station_port_base();
  s.session = 102;
  s.out_dir = dir;
  s.station_extra = kShort;
  s.device = "kind = \"touch\"\ndamping_Ns_per_m = 0.5\nhd_library_path = \"/nonexistent/libHD.so\"\n";
  std::atomic<bool> stop{false};
  RunOverrides o;
  o.quiet = true;
  LONGS_EQUAL(kExitDeviceMissing, run_station(parse_station_file(s.text()), o, stop));
  const json j = station_json(dir, 2);
  CHECK(has(j["conditions"], "device_missing"));
  const std::string err = j["error"].get<std::string>();
  CHECK_TEXT(err.find("/nonexistent/libHD.so") != std::string::npos, err.c_str());
  CHECK_TEXT(err.find("device.hd_library_path") != std::string::npos, err.c_str());  // the key that fixes it, as the file spells it
  CHECK_TEXT(err.find("device.kind = \"simulated\"") != std::string::npos, err.c_str());
  LONGS_EQUAL(0, j["ticks_run"].get<int>());
  std::filesystem::remove_all(dir);
}

TEST(StationPhases, ASimulatedUserIsAWarningAtStartAndRecordedInTheSummary) {
  test::StationText s;
  s.id = 3;
  s.peers = {1};
  s.out_dir = "/tmp";
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK(pr.status == PhaseStatus::kOk);
  bool warned = false;
  for (const auto& w : pr.plan->warnings) warned = warned || w.find("SIMULATED user plays user 3") != std::string::npos;
  CHECK(warned);
  s.device = "kind = \"touch\"\ndamping_Ns_per_m = 0.5\n";
  const PlanResult real = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK_TEXT(real.status == PhaseStatus::kOk, real.error.c_str());
  for (const auto& w : real.plan->warnings) CHECK(w.find("SIMULATED") == std::string::npos);
}

TEST(StationPhases, ALatchedDeviceFaultIsASafeStateCondition) {
  test::StationText s;
  s.peers = {2, 3, 4};
  s.out_dir = "/tmp";
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  StationOutcome o;
  o.plan = pr.plan.get();
  o.device_fault = "none";
  CHECK_FALSE(run_conditions(o).safe_state_latched);
  o.device_fault = "unplugged";
  CHECK(run_conditions(o).safe_state_latched);
}
