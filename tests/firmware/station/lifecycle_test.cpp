// The station's lifecycle checks in-process over loopback (no root): two stations whose scenes
// differ refuse to couple and say which field differs; the clock-offset check flags a tick grid
// far from ours; the neighbour event log reports a silence and a return once each.
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "firmware/station/neighbours.hpp"
#include "firmware/station/probe.hpp"
#include "firmware/station/report.hpp"
#include "firmware/station/run.hpp"
#include "net/transport_udp.hpp"
#include "tests/firmware/scene/fixtures.hpp"

using namespace haptic::firmware;

namespace {

// Station `id` of paper-best (the star on 1) with `nodes` nodes. The hub's peers 3 and 4 point
// at a port nobody listens on; the transports' real ports are set by connect().
// `scene`: a [scene] table instead of station.nodes (nodes is then unused).
// (a fixed loss allowance: these tests are about fingerprints and clocks, and a measured one can warn
// when a loaded machine's probing loop skips ticks)
// `station_keys`: further [station] lines.
StationFile star_station_file(int id, int nodes, double probe_s, const std::string& scene = "", const std::string& station_keys = "") {
  std::string text = "[station]\nid = " + std::to_string(id) + (scene.empty() ? "\nnodes = " + std::to_string(nodes) : std::string()) +
                     "\nprobe_s = " + std::to_string(probe_s) + "\nloss_allowance_ticks = 1\nout_dir = \"/tmp\"\n" + station_keys + scene + "[device]\nkind = \"simulated\"\n[rt]\nlock_memory = false\n[net]\ntransport = \"udp\"\nbind = \"127.0.0.1:1\"\n"
                     "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\nrtt_min_probe_samples = 5\n";
  for (int j : id == 1 ? std::vector<int>{2, 3, 4} : std::vector<int>{1})
    text += "[[net.peers]]\nid = " + std::to_string(j) + "\naddress = \"127.0.0.1:9\"\n";
  return parse_station_file(text);
}

struct Station {
  std::unique_ptr<StationPlan> plan;
  std::unique_ptr<haptic::net::Endpoint> ep;
  haptic::net::UdpTransport* udp = nullptr;
};

// Plans a station (common epoch `start_at`), opens its endpoint on a kernel-chosen port.
Station open_station(const StationFile& f, double start_at) {
  RunOverrides o;
  o.start_at = start_at;
  o.quiet = true;
  PlanResult pr = plan_station(f, o, read_clocks());
  if (pr.status != PhaseStatus::kOk) FAIL(pr.error.c_str());
  Station s;
  s.plan = std::move(pr.plan);
  auto t = std::make_unique<haptic::net::UdpTransport>("127.0.0.1:0", std::vector<haptic::net::UdpPeer>{});
  s.udp = t.get();
  s.ep = std::make_unique<haptic::net::Endpoint>(s.plan->endpoint_config(), std::move(t));
  return s;
}

void connect(Station& a, Station& b) {
  a.udp->set_peer({static_cast<std::uint16_t>(b.plan->station_id), "127.0.0.1:" + std::to_string(b.udp->local_port())});
  b.udp->set_peer({static_cast<std::uint16_t>(a.plan->station_id), "127.0.0.1:" + std::to_string(a.udp->local_port())});
}

// Both stations probe at once (one on a helper thread), as two processes would.
std::pair<ProbeResult, ProbeResult> probe_both(Station& a, Station& b) {
  std::atomic<bool> stop{false};
  a.ep->start();
  b.ep->start();
  a.ep->begin_probing();
  b.ep->begin_probing();
  ProbeResult ra;
  std::thread t([&] { ra = probe_neighbours(*a.plan, *a.ep, stop); });
  ProbeResult rb = probe_neighbours(*b.plan, *b.ep, stop);
  t.join();
  a.ep->stop();
  b.ep->stop();
  return {std::move(ra), std::move(rb)};
}

// The common epoch: 1 s from now leaves time to plan both stations on a loaded machine.
double soon_s() { return static_cast<double>(read_clocks().monotonic_ns) * 1e-9 + 1.0; }

}  // namespace

TEST_GROUP(StationLifecycle){};

TEST(StationLifecycle, StationsWithDifferentScenesRefuseToCoupleAndSayWhichFieldDiffers) {
  const double t0 = soon_s();
  Station a = open_station(star_station_file(1, 33, 0.3), t0), b = open_station(star_station_file(2, 27, 0.3), t0);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);
  CHECK(ra.status == PhaseStatus::kFailed);
  CHECK(rb.status == PhaseStatus::kFailed);
  STRCMP_CONTAINS("refusing to couple: neighbour fingerprint differs (station 2: scene nodes: 33 here, 27 at the peer; scene data (hash) differs",
                  ra.message.c_str());
  STRCMP_CONTAINS("refusing to couple: neighbour fingerprint differs (station 1: scene nodes: 27 here, 33 at the peer", rb.message.c_str());
  CHECK(ra.stats_at_end.wrong_scene_size > 0 || ra.stats_at_end.drops[haptic::net::DropReason::too_large] > 0);
}

TEST(StationLifecycle, StationsWithTheSameMeshButDifferentMaterialsRefuseAndSaySo) {
  const std::string dir = haptic::test::scratch_dir("lifecycle-material");
  haptic::test::write_text(dir + "/box.msh", haptic::test::msh2(haptic::test::kuhn_box(3, 0.06)));
  const auto scene = [&](int density) { return "[scene]\nfile = \"" + dir + "/box.msh\"\ndensity_kg_per_m3 = " + std::to_string(density) + "\n"; };
  const double t0 = soon_s();
  Station a = open_station(star_station_file(1, 0, 0.3, scene(1000)), t0), b = open_station(star_station_file(2, 0, 0.3, scene(2000)), t0);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);
  std::filesystem::remove_all(dir);
  CHECK(ra.status == PhaseStatus::kFailed);
  CHECK(rb.status == PhaseStatus::kFailed);
  STRCMP_CONTAINS("refusing to couple: neighbour fingerprint differs (station 2: scene material (hash) differs", ra.message.c_str());
  STRCMP_CONTAINS("refusing to couple: neighbour fingerprint differs (station 1: scene material (hash) differs", rb.message.c_str());
}

TEST(StationLifecycle, StationsWithDifferentCouplingLawsRefuseToCoupleAndSayWhichKeyDiffers) {
  // Same scene and gains; one runs eq. (18), the other the set-position modulation with the
  // predictive deadband: eq. (18)'s proof needs both ends of a link on the same law.
  const double t0 = soon_s();
  Station a = open_station(star_station_file(1, 33, 0.3), t0);
  Station b = open_station(star_station_file(2, 33, 0.3, "", "consensus_passivity = \"pspm\"\ntx_deadband_mm = 0.01\ntx_max_interval_ticks = 4\ntx_predict = true\n"), t0);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);
  CHECK(ra.status == PhaseStatus::kFailed);
  CHECK(rb.status == PhaseStatus::kFailed);
  STRCMP_CONTAINS("refusing to couple: neighbour fingerprint differs (station 2: consensus passivity (station.consensus_passivity): eq18 here, pspm at the peer; "
                  "predictive deadband (station.tx_predict): off here, on at the peer; transmission deadband (station.tx_deadband_mm, station.tx_max_interval_ticks; hash) differs",
                  ra.message.c_str());
  STRCMP_CONTAINS("(station 1: consensus passivity (station.consensus_passivity): pspm here, eq18 at the peer", rb.message.c_str());
}

TEST(StationLifecycle, StationsWithTheSameSceneProbeAndSeeNoClockOffset) {
  const double t0 = soon_s();
  Station a = open_station(star_station_file(1, 33, 0.6), t0), b = open_station(star_station_file(2, 33, 0.6), t0);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);  // the hub misses 3 and 4; the leaf has all it needs
  CHECK_TEXT(rb.status == PhaseStatus::kOk, rb.message.c_str());
  CHECK(!rb.clock.exceeded);
  CHECK_TEXT(rb.warnings.empty(), rb.warnings.empty() ? "" : rb.warnings[0].c_str());
  // One host, one epoch: the neighbour's tick grid is ours, within the estimate's uncertainty.
  CHECK(std::abs(rb.clock.grid_offset_s.at(0)) <= rb.clock.uncertainty_s.at(0));
}

TEST(StationLifecycle, ATickGridFarFromOursIsWarnedAboutOrRefused) {
  const double t0 = soon_s();
  // The leaf's epoch is 60 ms later than the hub's (a bad clock; above clock_offset_max_ms = 20 ms,
  // below the 100 ms net.max_sequence_ahead_ticks lets through); probing 1 s, so they overlap.
  Station a = open_station(star_station_file(1, 33, 1.0), t0), b = open_station(star_station_file(2, 33, 1.0), t0 + 0.06);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);
  CHECK_TEXT(rb.status == PhaseStatus::kOk, rb.message.c_str());
  CHECK(rb.clock.exceeded);
  DOUBLES_EQUAL(-0.06, rb.clock.grid_offset_s.at(0), 0.01);
  CHECK_TEXT(rb.warnings.size() == 1u, rb.warnings.size() > 1 ? rb.warnings[1].c_str() : "no warning");
  STRCMP_CONTAINS("station 1 runs its ticks ", rb.warnings[0].c_str());
  STRCMP_CONTAINS(" ms earlier than ours (+- ", rb.warnings[0].c_str());
  // With station.clock_offset_refuse = true the same measurement refuses to couple.
  ProbeResult refused = rb;
  refused.status = PhaseStatus::kOk;
  refused.warnings.clear();
  StationPlan strict = *b.plan;
  strict.file.station.clock_offset_refuse = true;
  check_clock(strict, strict.times.epoch_ns, refused);
  CHECK(refused.status == PhaseStatus::kFailed);
  STRCMP_CONTAINS("refusing to couple (station.clock_offset_refuse = true): clock offset above station.clock_offset_max_ms", refused.message.c_str());
}

TEST(StationLifecycle, AGridOffsetWithinTheLimitIsMappedAndOneBeyondItIsRefusedNamingBothStations) {
  const double t0 = soon_s();
  // The leaf's epoch is 300 ms later than the hub's (its clock 0.3 s behind); probing 1.2 s, so
  // they overlap for 0.9 s. Net's sequence ceiling (100 ms) is widened by station.clock_offset_limit_ms.
  Station a = open_station(star_station_file(1, 33, 1.2), t0), b = open_station(star_station_file(2, 33, 1.2), t0 + 0.3);
  connect(a, b);
  auto [ra, rb] = probe_both(a, b);
  CHECK_TEXT(rb.status == PhaseStatus::kOk, rb.message.c_str());
  DOUBLES_EQUAL(-0.3, rb.clock.grid_offset_s.at(0), 0.01);
  LONGS_EQUAL(1u, rb.clock.shift_ticks.size());
  CHECK_TEXT(std::abs(rb.clock.shift_ticks[0] + 150) <= 5, std::to_string(rb.clock.shift_ticks[0]).c_str());  // hub tick s = our tick s - 150
  CHECK(rb.clock.refusal.empty());
  // The hub (its probing fails: 3 and 4 never answer) sees the leaf's grid 300 ms behind: +150 ticks.
  const ClockCheck hub = check_clock_offsets(*a.plan, ra.stats_at_end, ra.grid, a.plan->times.epoch_ns);
  CHECK_TEXT(std::abs(hub.shift_ticks.at(0) - 150) <= 5, std::to_string(hub.shift_ticks.at(0)).c_str());
  // Beyond the limit (here 200 ms) the same measurement refuses, naming both stations and the offset.
  ProbeResult refused = rb;
  refused.status = PhaseStatus::kOk;
  StationPlan strict = *b.plan;
  strict.file.station.clock_offset_limit_ms = 200;
  check_clock(strict, strict.times.epoch_ns, refused);
  CHECK(refused.status == PhaseStatus::kFailed);
  STRCMP_CONTAINS("refusing to couple: clock offset beyond station.clock_offset_limit_ms = 200.0 ms: ", refused.message.c_str());
  const std::string grid_is = "station 1's tick grid is ";
  const std::size_t at = refused.message.find(grid_is);
  CHECK_TEXT(at != std::string::npos, refused.message.c_str());
  DOUBLES_EQUAL(300.0, std::stod(refused.message.substr(at + grid_is.size())), 10.0);  // "299.3 ms (+- 2.0 ms) ahead of ..." 
  STRCMP_CONTAINS(" ahead of station 2's", refused.message.c_str());
}

TEST(StationLifecycle, NeighbourSilenceAndReturnAreLoggedOnceEach) {
  Station a = open_station(star_station_file(2, 33, 0.3), soon_s());
  const std::int64_t run0 = a.plan->times.run_epoch_ns();
  PeerEventLog log(*a.plan, run0, 0.1);
  haptic::net::EndpointStats s;
  s.peers.resize(1);
  auto& p = s.peers[0];
  const double run0_s = static_cast<double>(run0) * 1e-9;
  p.up = true;
  p.up_events = 1;  // found while probing: not an event
  p.last_up_s = run0_s - 1.0;
  CHECK(log.poll(s).empty());
  p.up = false;
  p.down_events = 1;
  p.last_down_s = run0_s + 5.25;
  auto lines = log.poll(s);
  CHECK_EQUAL(1u, lines.size());
  STRCMP_EQUAL("neighbour 1 went silent at run time 5.250 s (no packet for net.peer_silence_s)", lines[0].c_str());
  CHECK(log.poll(s).empty());  // once
  p.up = true;
  p.up_events = 2;
  p.incarnation_changes = 1;
  p.incarnation = 1796000000000000002ull;
  p.last_up_s = run0_s + 8.2;
  lines = log.poll(s);
  CHECK_EQUAL(1u, lines.size());
  STRCMP_EQUAL("neighbour 1 is back at run time 8.200 s (restarted: new incarnation 1796000000000000002)", lines[0].c_str());
  CHECK(log.poll(s).empty());
  CHECK_EQUAL(2u, log.events());
}

// net/'s incarnation rule as the station reports it: a newer incarnation refused while the current
// one spoke is logged once; two live incarnations are logged once, whenever they happen (probing
// included), named in the report's conditions and exit 12 (before 11 and 7: the theft is the cause).
TEST(StationLifecycle, AKeyCompromiseIsLoggedOnceAndNamedInTheExitStatus) {
  Station a = open_station(star_station_file(2, 33, 0.3), soon_s());
  const std::int64_t run0 = a.plan->times.run_epoch_ns();
  PeerEventLog log(*a.plan, run0, 0.1);
  haptic::net::EndpointStats s;
  s.peers.resize(1);
  auto& p = s.peers[0];
  p.incarnation = 100;
  p.refused_incarnation = 200;
  auto lines = log.poll(s);
  CHECK_EQUAL(1u, lines.size());
  STRCMP_EQUAL("neighbour 1 announced a new incarnation 200 while its current one 100 still spoke: refused until the current one has "
               "been silent for net.peer_silence_s", lines[0].c_str());
  CHECK(key_compromise_messages(*a.plan, s).empty());
  p.key_compromise = true;
  p.key_compromise_s = static_cast<double>(run0) * 1e-9 - 0.5;  // while probing
  lines = log.poll(s);
  CHECK_EQUAL(1u, lines.size());
  STRCMP_CONTAINS("key compromise suspected: station 1 has two live incarnations (100 and 200)", lines[0].c_str());
  STRCMP_CONTAINS("run time -0.500 s", lines[0].c_str());
  CHECK(log.poll(s).empty());
  const auto m = key_compromise_messages(*a.plan, s);
  CHECK_EQUAL(1u, m.size());
  STRCMP_CONTAINS("key compromise suspected: station 1 has two live incarnations (100 and 200)", m[0].c_str());
  p.key_compromise_conflict = true;  // the same-incarnation proof names the sequence instead
  p.key_compromise_seq = 4242;
  STRCMP_CONTAINS("key compromise suspected: station 1 sent two different authentic datagrams with sequence 4242",
                  key_compromise_messages(*a.plan, s)[0].c_str());
  RunConditions c;
  c.key_compromise = true;
  c.no_neighbour = c.missed_cycles = c.held_by_gate = true;
  CHECK_EQUAL(12, exit_code(c));
  c.passivity_not_met = true;  // a safety stop keeps its code
  CHECK_EQUAL(6, exit_code(c));
  c.passivity_not_met = false;
  bool named = false;
  for (const auto& n : c.names()) named = named || n == "key_compromise_suspected";
  CHECK_TRUE(named);
}
