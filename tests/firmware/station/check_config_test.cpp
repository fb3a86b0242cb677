// `haptic-station run --check-config` is the plan phase: it rejects every configuration `run`
// rejects before opening a socket, with exit code 2 and the key named as written in the file.
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "drivers/device_factory.hpp"
#include "firmware/station/run.hpp"
#include "net/keys.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;
using namespace haptic::firmware;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

struct Checked {
  int code = -1;
  std::string out, err;
};

Checked check(const std::string& text, RunOverrides o = {}) {
  Checked c;
  std::ostringstream out, err;
  c.code = check_station_config(parse_station_file(text), o, out, err);
  c.out = out.str();
  c.err = err.str();
  return c;
}

// The same file through run_station: it must stop at the same check with the same code.
int run_code(const std::string& text) {
  std::atomic<bool> stop{false};
  RunOverrides o;
  o.quiet = true;
  return run_station(parse_station_file(text), o, stop);
}

test::StationText hub() {
  test::StationText s;
  s.id = 1;
  s.peers = {2, 3, 4};
  s.out_dir = std::filesystem::temp_directory_path().string();
  return s;
}

void rejected_with_key(const std::string& text, const std::string& key) {
  const Checked c = check(text);
  LONGS_EQUAL(kExitConfigError, c.code);
  if (!contains(c.err, key)) FAIL(("expected the key " + key + " in: " + c.err).c_str());
  LONGS_EQUAL(kExitConfigError, run_code(text));
}

}  // namespace

TEST_GROUP(CheckConfig){};

TEST(CheckConfig, AValidFileIsAcceptedWithASummary) {
  const Checked c = check(hub().text());
  LONGS_EQUAL(kExitOk, c.code);
  CHECK(contains(c.out, "config ok: station 1 of 4"));
  CHECK(contains(c.out, "3 neighbour(s)"));
}

TEST(CheckConfig, APeerThatIsNotANeighbourIsRejectedNamingItsKey) {
  test::StationText s = hub();
  s.id = 2;
  s.peers = {3};
  rejected_with_key(s.text(), "net.peers[0].id = 3 is not a neighbour of station 2");
}

TEST(CheckConfig, APeerListedTwiceIsRejectedNamingBothEntries) {
  test::StationText s = hub();
  s.peers = {2, 3, 4, 2};
  rejected_with_key(s.text(), "net.peers[3].id = 2 lists that station a second time (also net.peers[0].id)");
}

TEST(CheckConfig, AMissingNeighbourIsRejected) {
  test::StationText s = hub();
  s.peers = {2, 3};
  rejected_with_key(s.text(), "net.peers lacks station 4");
}

TEST(CheckConfig, AnIPv6PeerOfAnIPv4BindIsRejectedNamingTheAddressKey) {
  test::StationText s = hub();
  s.peers = {};
  std::string t = s.text();
  t += "[[net.peers]]\nid = 2\naddress = \"127.0.0.1:50002\"\n[[net.peers]]\nid = 3\naddress = \"[::1]:50003\"\n[[net.peers]]\nid = 4\naddress = \"127.0.0.1:50004\"\n";
  rejected_with_key(t, "net.peers[1].address = \"[::1]:50003\" must be the same address family");
}

// 198.51.100.0/24 is TEST-NET-2 (RFC 5737): documentation only, assigned to no real machine.
TEST(CheckConfig, ABindAddressThisMachineDoesNotOwnIsRejectedNamingTheKey) {
  std::string t = hub().text();
  const auto at = t.find("bind = \"127.0.0.1:");
  CHECK(at != std::string::npos);
  t.replace(at, std::string("bind = \"127.0.0.1:").size(), "bind = \"198.51.100.7:");
  rejected_with_key(t, "net.bind = \"198.51.100.7:");
  CHECK(contains(check(t).err, "is not an address of this machine"));
}

// Linux's loopback interface owns all of 127.0.0.0/8 (getifaddrs lists only 127.0.0.1).
TEST(CheckConfig, AnyLoopbackBindAddressIsAccepted) {
  std::string t = hub().text();
  const auto at = t.find("bind = \"127.0.0.1:");
  CHECK(at != std::string::npos);
  t.replace(at, std::string("bind = \"127.0.0.1:").size(), "bind = \"127.0.0.2:");
  const Checked c = check(t);
  if (c.code != kExitOk) FAIL(c.err.c_str());
}

TEST(CheckConfig, AnIoCpuThisProcessCannotUseIsRejected) {
  test::StationText s = hub();
  s.net_extra = "io_cpu = 1000\n";
  rejected_with_key(s.text(), "net.io_cpu = 1000");
}

TEST(CheckConfig, ATxSpinWindowLongerThanThePeriodIsRejected) {
  test::StationText s = hub();
  s.net_extra = "tx_spin = true\ntx_spin_lead_us = 2500\n";
  rejected_with_key(s.text(), "net.tx_spin_lead_us = 2500");
  s.net_extra = "tx_spin = true\ntx_spin_lead_us = 100\ntx_spin_tail_us = 1950\n";
  rejected_with_key(s.text(), "net.tx_spin_lead_us + net.tx_spin_tail_us = 2050");
  s.net_extra = "tx_spin = true\n";  // the shipped lead/tail fit a 2 ms tick
  LONGS_EQUAL(kExitOk, check(s.text()).code);
}

TEST(CheckConfig, AProbeTooShortForTheRoundTripsAtTheDeadbandsPaceIsRejectedNamingTheKeys) {
  // probing sends a state every tx_max_interval_ticks: 1.5 s (750 ticks, the bounds freeze at 500)
  // sends 17 at every 30th tick, fewer than the 20 round trips net.rtt_min_probe_samples asks for
  test::StationText s = hub();
  s.station_extra = "probe_s = 1.5\ntx_deadband_mm = 0.01\ntx_max_interval_ticks = 30\n";
  const Checked c = check(s.text());
  LONGS_EQUAL(kExitConfigError, c.code);
  STRCMP_CONTAINS("station.probe_s = 1.5 s sends 17 probe states before the round-trip bounds freeze (one every 30 ticks", c.err.c_str());
  STRCMP_CONTAINS("fewer than the 20 round trips a link needs (net.rtt_min_probe_samples): probe for at least 1.7", c.err.c_str());
  s.station_extra = "probe_s = 1.75\ntx_deadband_mm = 0.01\ntx_max_interval_ticks = 30\n";  // 875 ticks, freeze at 584: 20
  LONGS_EQUAL(kExitOk, check(s.text()).code);
  s.station_extra = "probe_s = 1.5\ntx_deadband_mm = 0.01\ntx_max_interval_ticks = 25\n";  // 20 at every 25th tick
  LONGS_EQUAL(kExitOk, check(s.text()).code);
}

TEST(CheckConfig, ARejoinProbeTooShortForTheRoundTripsAtTheDeadbandsPaceIsRejectedNamingTheKey) {
  // started 1 s after the common epoch: a rejoin, which takes its bounds at the end of
  // station.rejoin_probe_s; 0.4 s (200 ticks) sends 10 states at every 20th tick, fewer than 20
  RunOverrides o;
  o.start_at = static_cast<double>(read_clocks().monotonic_ns) * 1e-9 - 1.0;
  test::StationText s = hub();
  s.station_extra = "tx_deadband_mm = 0.01\ntx_max_interval_ticks = 20\n";
  const Checked c = check(s.text(), o);
  LONGS_EQUAL(kExitConfigError, c.code);
  STRCMP_CONTAINS("station.rejoin_probe_s = 0.4 s sends 10 probe states before the round-trip bounds are taken (one every 20 ticks", c.err.c_str());
  STRCMP_CONTAINS("probe for at least 0.762 s", c.err.c_str());
  s.station_extra += "rejoin_probe_s = 0.762\n";  // 381 ticks: the 20th state at tick 380
  const Checked ok = check(s.text(), o);
  LONGS_EQUAL(kExitOk, ok.code);
  CHECK_TEXT(contains(ok.out, "rejoining the running session"), ok.out.c_str());
}

TEST(CheckConfig, TickSynchronousAndDirectTxTogetherAreRejectedNamingBoth) {
  test::StationText s = hub();
  s.net_extra = "tx_spin = true\ntx_direct = true\n";
  rejected_with_key(s.text(), "net.tx_spin and net.tx_direct are both true");
  s.net_extra = "tx_direct = true\n";
  LONGS_EQUAL(kExitOk, check(s.text()).code);
}

TEST(CheckConfig, AnOutDirThatCannotBeCreatedIsRejected) {
  const std::string dir = test::fresh_dir("outdir");
  const std::string file = dir + "/plain-file";
  std::ofstream(file) << "x";
  test::StationText s = hub();
  s.out_dir = file + "/sub";
  rejected_with_key(s.text(), "station.out_dir = \"" + file + "/sub\" cannot be created");
  // nothing was created by the check
  s.out_dir = dir + "/new/deeper";
  LONGS_EQUAL(kExitOk, check(s.text()).code);
  CHECK_FALSE(std::filesystem::exists(dir + "/new"));
  std::filesystem::remove_all(dir);
}

TEST(CheckConfig, KeysAreNamedAsWrittenUnderTheNetworkAlias) {
  std::string t = "[station]\nid = 2\nio_priority = 0\nout_dir = \"/tmp\"\n[network]\nlisten = \"127.0.0.1:50002\"\n";
  t += "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n";
  t += "peers = [{ station = 3, address = \"127.0.0.1:50003\" }]\n";
  rejected_with_key(t, "network.peers[0].station = 3 is not a neighbour");
}

TEST(CheckConfig, ScenarioKeysAreNamedAsWrittenNotAsFlags) {
  test::StationText s = hub();
  s.station_extra = "topology = \"1-2,3-4\"\n";
  rejected_with_key(s.text(), "station.topology must connect all users");
  s.station_extra = "push_end_s = 6\nrelease_s = 5\n";
  rejected_with_key(s.text(), "station.release_s");
  s.station_extra = "scenario = \"paper-bestest\"\n";
  rejected_with_key(s.text(), "station.scenario = \"paper-bestest\": unknown scenario");
}

TEST(CheckConfig, ARunThatEndsBeforeTheReleaseIsAWarningAtStart) {
  test::StationText s = hub();
  s.station_extra = "duration_s = 4\nrelease_s = 5\n";
  const Checked c = check(s.text());
  LONGS_EQUAL(kExitOk, c.code);
  CHECK(contains(c.out, "ends before the scripted release at station.release_s = 5"));
  RunOverrides o;
  o.duration_s = 2;
  s.station_extra = "release_s = 5\n";
  CHECK(contains(check(s.text(), o).out, "(--duration = 2 s) ends before"));
}

// station.resilient_f on the paper's star (1-robust) is a warning naming what it needs; without the
// per-edge energy bound it is refused under eq. (18), naming both keys (rt/README.md).
TEST(CheckConfig, AResilientRuleOnATopologyThatIsNotRobustEnoughIsAWarningAndWithoutTheEnergyBoundAnError) {
  test::StationText s = hub();
  s.station_extra = "resilient_f = 1\n";
  const Checked c = check(s.text());
  LONGS_EQUAL(kExitOk, c.code);
  CHECK_TEXT(contains(c.out, "station.resilient_f = 1 needs a 3-robust topology") && contains(c.out, "this one is 1-robust"), c.out.c_str());
  s.station_extra = "";
  CHECK_FALSE(contains(check(s.text()).out, "resilient_f"));
  s.station_extra = "resilient_f = 1\nedge_energy_bound_J = 0\n";
  rejected_with_key(s.text(), "station.resilient_f needs station.edge_energy_bound_J > 0");
}

TEST(CheckConfig, AStartLongAfterTheCommonEpochIsAConfigurationError) {
  RunOverrides o;
  o.start_at = 1.0;  // CLOCK_MONOTONIC 1 s after boot: long past
  const Checked c = check(hub().text(), o);
  LONGS_EQUAL(kExitConfigError, c.code);
  CHECK(contains(c.err, "--start-at"));
}

TEST(CheckConfig, TheFingerprintNamesTheFieldsThatDiffer) {
  const BuiltScenario a = build_scenario(make_scenario("paper-best"));
  ScenarioSpec bigger = make_scenario("paper-best");
  bigger.scene_nodes = 27;
  ScenarioSpec stiffer = make_scenario("paper-best");
  stiffer.p_gain_N_per_m = 900;
  const SceneFingerprint fa = scene_fingerprint(a, 2'000'000);
  using haptic::net::fingerprint_difference;
  STRCMP_EQUAL("", fingerprint_difference(fa, scene_fingerprint(build_scenario(make_scenario("paper-best")), 2'000'000)).c_str());
  STRCMP_CONTAINS("scene nodes: 33 here, 27 at the peer", fingerprint_difference(fa, scene_fingerprint(build_scenario(bigger), 2'000'000)).c_str());
  STRCMP_EQUAL("gains or shared station options (hash) differs", fingerprint_difference(fa, scene_fingerprint(build_scenario(stiffer), 2'000'000)).c_str());
  STRCMP_EQUAL("period_ns: 2000000 here, 1000000 at the peer", fingerprint_difference(fa, scene_fingerprint(a, 1'000'000)).c_str());
  // The coupling law: another consensus passivity, predictive deadband or transmission deadband.
  ScenarioSpec pspm = make_scenario("paper-best");
  pspm.consensus_passivity = rt::ConsensusPassivity::kSetPositionModulation;
  STRCMP_EQUAL("consensus passivity (station.consensus_passivity): eq18 here, pspm at the peer",
               fingerprint_difference(fa, scene_fingerprint(build_scenario(pspm), 2'000'000)).c_str());
  ScenarioSpec band = pspm;
  band.tx_deadband.position_deadband_m = 1e-5;
  band.tx_deadband.max_interval_ticks = 4;
  ScenarioSpec predict = band;
  predict.tx_deadband.predictive = true;
  const SceneFingerprint fb = scene_fingerprint(build_scenario(band), 2'000'000);
  STRCMP_EQUAL("predictive deadband (station.tx_predict): off here, on at the peer",
               fingerprint_difference(fb, scene_fingerprint(build_scenario(predict), 2'000'000)).c_str());
  ScenarioSpec wider = band;
  wider.tx_deadband.position_deadband_m = 2e-5;
  STRCMP_EQUAL("transmission deadband (station.tx_deadband_mm, station.tx_max_interval_ticks; hash) differs",
               fingerprint_difference(fb, scene_fingerprint(build_scenario(wider), 2'000'000)).c_str());
}

// A session-log ring that cannot fit station.record_max_mb is refused at plan time, naming both
// keys (a ring never truncates: its size must be known to fit); a short ring is accepted.
TEST(CheckConfig, ARecordRingLargerThanTheSizeBoundIsRejectedNamingBothKeys) {
  test::StationText s = hub();
  s.station_extra = "record = true\nrecord_max_mb = 100\nrecord_ring_s = 600\n";
  rejected_with_key(s.text(), "station.record_ring_s = 600 needs");
  CHECK(contains(check(s.text()).err, "above station.record_max_mb = 100"));
  s.station_extra = "record = true\nrecord_max_mb = 100\nrecord_ring_s = 10\n";
  LONGS_EQUAL(kExitOk, check(s.text()).code);
}

namespace {
// The hub's file with its three peers at these addresses (net.peers[0] is station 2).
std::string hub_with_peer2_at(const std::string& address, const std::string& peer2_extra = "") {
  test::StationText s = hub();
  s.peers = {};
  std::string t = s.text();
  t += "[[net.peers]]\nid = 2\naddress = \"" + address + "\"\n" + peer2_extra;
  t += "[[net.peers]]\nid = 3\naddress = \"127.0.0.1:50003\"\n[[net.peers]]\nid = 4\naddress = \"127.0.0.1:50004\"\n";
  return t;
}
}  // namespace

// Each of these failed only later in `run` ("no neighbour", a key agreement error, an unnamed
// output error): the plan refuses them, naming the key as written.
TEST(CheckConfig, APeerOnPortZeroIsRejectedNamingItsAddressKey) {
  rejected_with_key(hub_with_peer2_at("127.0.0.1:0"), "net.peers[0].address = \"127.0.0.1:0\" must be a neighbour's address with its port");
}

TEST(CheckConfig, APeerAtThisStationsOwnAddressIsRejectedNamingItsAddressKey) {
  const std::string own = "127.0.0.1:" + std::to_string(hub().port_base + 1);
  rejected_with_key(hub_with_peer2_at(own), "net.peers[0].address = \"" + own + "\" must be another station's address, not this station's own net.bind");
  LONGS_EQUAL(kExitOk, check(hub_with_peer2_at("127.0.0.1:50002")).code);
}

TEST(CheckConfig, AnAllZeroPublicKeyIsRejectedNamingTheKey) {
  const std::string dir = test::fresh_dir("zero-key");
  net::write_new_key_file(dir + "/station-1.key");
  const std::string other = net::to_hex(net::generate_key_pair().public_key.data(), 32);
  auto file = [&](const std::string& peer2_key) {
    test::StationText s = hub();
    s.peers = {};
    std::string t = s.text();
    const auto at = t.find("shared_session_key");
    t.replace(at, t.find('\n', at) - at, "key_file = \"" + dir + "/station-1.key\"");
    t += "[[net.peers]]\nid = 2\naddress = \"127.0.0.1:50002\"\npublic_key = \"" + peer2_key + "\"\n";
    for (int p : {3, 4}) t += "[[net.peers]]\nid = " + std::to_string(p) + "\naddress = \"127.0.0.1:5000" + std::to_string(p) + "\"\npublic_key = \"" + other + "\"\n";
    return t;
  };
  rejected_with_key(file(std::string(64, '0')), "net.peers[0].public_key must be a valid public key");
  LONGS_EQUAL(kExitOk, check(file(net::to_hex(net::generate_key_pair().public_key.data(), 32))).code);
  std::filesystem::remove_all(dir);
}

TEST(CheckConfig, AMissingDelayTraceIsRejectedNamingTheKey) {
  test::StationText s = hub();
  s.net_extra = "[net.impairment]\npreset = \"paper\"\ntrace_file = \"/nonexistent/delays.txt\"\n";
  rejected_with_key(s.text(), "net.impairment.trace_file = \"/nonexistent/delays.txt\" must be a readable delay trace");
}

// Root passes access(W_OK) on /proc, where nothing can be created.
TEST(CheckConfig, AnOutDirUnderProcIsRejectedNamingTheKey) {
  test::StationText s = hub();
  s.out_dir = "/proc/haptic-station-test/out";
  rejected_with_key(s.text(), "station.out_dir = \"/proc/haptic-station-test/out\" cannot be created");
}

// One range for station.nodes: the parser's (the plan's scenario check said [7, 20000] besides, and 7
// failed as "lattice ball: no mesh for that target", naming no key).
TEST(CheckConfig, StationNodesHasOneRange) {
  for (const char* n : {"7", "6000"}) {
    test::StationText s = hub();
    s.station_extra = std::string("nodes = ") + n + "\n";
    try {
      parse_station_file(s.text());
      FAIL("accepted");
    } catch (const std::invalid_argument& e) {
      STRCMP_EQUAL("config: station.nodes must be an integer in [8, 5000]", e.what());
    }
  }
  test::StationText s = hub();
  s.station_extra = "nodes = 8\n";
  LONGS_EQUAL(kExitOk, check(s.text()).code);
}

// device.kind = "auto" on a machine with no Touch, Falcon or SpaceMouse: run's open phase exits 9;
// the plan now finds it first, with the same code (skipped where a device is plugged in).
TEST(CheckConfig, AutoWithNoDeviceOnThisMachineIsRefusedByThePlanWithExitNine) {
  test::StationText s = hub();
  s.device = "kind = \"auto\"\n";
  drivers::DeviceSelection sel;
  sel.kind = "auto";
  if (drivers::auto_device_absence(sel).empty()) return;  // a device is plugged in here
  const Checked c = check(s.text());
  LONGS_EQUAL(kExitDeviceMissing, c.code);
  CHECK(contains(c.err, "device.kind = \"auto\": no device to start on this machine"));
  LONGS_EQUAL(kExitDeviceMissing, run_code(s.text()));
}
