// The station file of `haptic-station run`: defaults, unknown keys, bad values (each error names
// the key and the allowed range), the scenario overrides and eq. (18) from measured bounds.
#include <CppUTest/TestHarness.h>

#include "net/config.hpp"

#include <stdexcept>
#include <string>

#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "firmware/station/run.hpp"
#include "rt/gains.hpp"

using namespace haptic::firmware;

namespace {

const std::string kNet = R"(
[net]
transport = "udp"
bind = "127.0.0.1:47001"
shared_session_key = "5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d"
[[net.peers]]
id = 2
address = "127.0.0.1:47002"
[[net.peers]]
id = 3
address = "127.0.0.1:47003"
[[net.peers]]
id = 4
address = "127.0.0.1:47004"
)";

std::string error_of(const std::string& text) {
  try {
    (void)parse_station_file(text);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_GROUP(StationConfig){};

TEST(StationConfig, MinimalFileGetsTheDocumentedDefaults) {
  const StationFile f = parse_station_file("[station]\nid = 1\n" + kNet);
  LONGS_EQUAL(1, f.station.id);
  STRCMP_EQUAL("paper-best", f.station.scenario.c_str());
  DOUBLES_EQUAL(1.5, f.station.probe_s, 0);
  DOUBLES_EQUAL(0.5, f.station.setup_gap_s, 0);
  DOUBLES_EQUAL(0.05, f.station.damping_margin, 0);
  LONGS_EQUAL(-1, f.station.loss_allowance_ticks);  // from the probe's measured loss
  LONGS_EQUAL(16, f.station.loss_allowance_max_ticks);
  DOUBLES_EQUAL(0.1, f.station.edge_energy_bound_J, 0);
  LONGS_EQUAL(5, f.station.state_every);
  DOUBLES_EQUAL(-1, f.station.damping_Ns_per_m, 0);
  LONGS_EQUAL(2, f.station.agreement_ticks);
  LONGS_EQUAL(70, f.station.io_priority);
  STRCMP_EQUAL("auto", f.device.kind.c_str());
  LONGS_EQUAL(2'000'000, f.loop.period_ns);
  LONGS_EQUAL(80, f.rt.priority);
  CHECK_FALSE(f.rt.require_rt);
  STRCMP_EQUAL("none", f.impairment_preset.c_str());
}

TEST(StationConfig, UnknownKeysAreRejectedByName) {
  CHECK(contains(error_of("[station]\nid = 1\nrelase_s = 3\n" + kNet), "unknown key station.relase_s"));
  CHECK(contains(error_of("[station]\nid = 1\n[bogus]\nx = 1\n" + kNet), "unknown key bogus"));
  CHECK(contains(error_of("[station]\nid = 1\n[device]\nkin = \"simulated\"\n" + kNet), "unknown key device.kin"));
  CHECK(contains(error_of("[station]\nid = 1\n" + kNet + "adress = \"x\"\n"), "unknown key net.peers[2].adress"));
  CHECK(contains(error_of("[station]\nid = 1\n[rt]\npriority = 10\nprio = 3\n" + kNet), "unknown key rt.prio"));
}

TEST(StationConfig, BadValuesNameTheKeyAndTheRange) {
  std::string e = error_of("[station]\nid = 1\nprobe_s = 0.01\n" + kNet);
  CHECK(contains(e, "station.probe_s") && contains(e, "[0.2, 60]"));
  e = error_of("[station]\nid = 1\nsolver = \"cg\"\n" + kNet);
  CHECK(contains(e, "station.solver") && contains(e, "\"iterative\""));
  e = error_of("[station]\nid = 1\ntx_max_interval_ticks = 0\n" + kNet);
  CHECK(contains(e, "station.tx_max_interval_ticks") && contains(e, "[1, 1000]"));
  e = error_of("[station]\nid = 1\ntx_max_interval_ticks = 20\n" + kNet);  // no band: it would do nothing
  CHECK(contains(e, "station.tx_max_interval_ticks") && contains(e, "station.tx_deadband_mm"));
  e = error_of("[station]\nid = 1\ntx_predict = true\n" + kNet);
  CHECK(contains(e, "station.tx_predict") && contains(e, "pspm"));
  e = error_of("[station]\nid = 1\nedge_energy_bound_J = -0.5\n" + kNet);
  CHECK(contains(e, "station.edge_energy_bound_J") && contains(e, "[0, 1e+06]"));
  e = error_of("[station]\nid = 0\n" + kNet);
  CHECK(contains(e, "station.id") && contains(e, "[1, 64]"));
  e = error_of("[station]\nscenario = \"paper-best\"\n" + kNet);
  CHECK(contains(e, "station.id"));
  e = error_of("[station]\nid = 1\nstart_clock = \"tai\"\n" + kNet);
  CHECK(contains(e, "station.start_clock"));
  e = error_of("[station]\nid = 1\n[device]\nkind = \"phantom\"\n" + kNet);
  CHECK(contains(e, "device.kind"));
  e = error_of("[station]\nid = 1\n[rt]\npriority = 99\n" + kNet);
  CHECK(contains(e, "rt.priority") && contains(e, "[1, 98]"));
  e = error_of("[station]\nid = 1\ndamping_Ns_per_m = -3\n" + kNet);
  CHECK(contains(e, "station.damping_Ns_per_m"));
  e = error_of("[station]\nid = 1\n" + kNet + "[net.impairment]\npreset = \"paper\"\nsed = 3\n");
  CHECK(contains(e, "unknown key net.impairment.sed"));
  e = error_of("[station]\nid = 2\n[net]\nstation_id = 5\n");
  CHECK(contains(e, "net.station_id"));
  e = error_of("[station]\nid = 1\n");
  CHECK(contains(e, "[net]"));
  e = error_of("[station\nid = 1\n");
  CHECK(contains(e, "TOML parse error"));
}

TEST(StationConfig, ScenarioKeysApplyAndAreChecked) {
  StationFile f = parse_station_file("[station]\nid = 4\nduration_s = 8\npush_end_s = 2.5\nrelease_s = 5\nseed = 7\n" + kNet);
  ScenarioSpec s = station_scenario_spec(f, RunOverrides{});
  DOUBLES_EQUAL(8.0, s.duration_s, 0);
  DOUBLES_EQUAL(5.0, s.script.release_s, 0);
  DOUBLES_EQUAL(2.5, s.script.push_end_s, 0);
  LONGS_EQUAL(7, s.seed);
  RunOverrides o;
  o.duration_s = 3;
  DOUBLES_EQUAL(3.0, station_scenario_spec(f, o).duration_s, 0);

  f = parse_station_file("[station]\nid = 1\npush_end_s = 6\nrelease_s = 5\n" + kNet);
  CHECK_THROWS(std::invalid_argument, station_scenario_spec(f, RunOverrides{}));
  f = parse_station_file("[station]\nid = 1\n[loop]\nperiod_ns = 1000000\n" + kNet);
  CHECK_THROWS(std::invalid_argument, station_scenario_spec(f, RunOverrides{}));
  f = parse_station_file("[station]\nid = 5\n" + kNet);
  CHECK_THROWS(std::invalid_argument, station_scenario_spec(f, RunOverrides{}));
}

TEST(StationConfig, ThePapersReceiveRuleIsAKeyAndItsBoundsAddTheDelaySpread) {
  // station.receive_rule = "paper": the core uses the paper's rule, and the bounds from a measured
  // round trip add each direction's spread (at most the one-way guard, + 1): guard 6 -> 6 + 7.
  StationFile f = parse_station_file("[station]\nid = 1\nreceive_rule = \"paper\"\n" + kNet);
  const BuiltScenario b = build_scenario(station_scenario_spec(f, RunOverrides{}));
  CHECK(b.station_config(0).rx_rule == haptic::rt::RxRule::kMostRecentlyReceived);
  const MeasuredBounds paper = bounds_from_round_trips(b, 0, {10, 15, 3}, {1, 1, 1}, 0.05, -1);
  LONGS_EQUAL(6 + 7, paper.index_guard_ticks[0]);
  const BuiltScenario bn = build_scenario(station_scenario_spec(parse_station_file("[station]\nid = 1\n" + kNet), RunOverrides{}));
  CHECK(bn.station_config(0).rx_rule == haptic::rt::RxRule::kNewestBySequence);
  CHECK_TRUE(paper.damping_Ns_per_m > bounds_from_round_trips(bn, 0, {10, 15, 3}, {1, 1, 1}, 0.05, -1).damping_Ns_per_m);
  CHECK_TRUE(error_of("[station]\nid = 1\nreceive_rule = \"latest\"\n" + kNet).find("station.receive_rule") != std::string::npos);
}

TEST(StationConfig, DampingFromMeasuredRoundTripsIsEq18WithTheSymmetricGuardAndAgreementTick) {
  ScenarioSpec spec = make_scenario("paper-best");
  const BuiltScenario b = build_scenario(spec);
  // user 1 (0-based 0) has three neighbours
  const MeasuredBounds m = bounds_from_round_trips(b, 0, {10, 15, 3}, {1, 1, 1}, 0.05, -1);
  LONGS_EQUAL(11, m.round_trip_ticks[0]);
  LONGS_EQUAL(6, m.index_guard_ticks[0]);  // ceil(11/2)
  LONGS_EQUAL(8, m.index_guard_ticks[1]);
  LONGS_EQUAL(2, m.index_guard_ticks[2]);
  LONGS_EQUAL(14, m.assumed_sum_ticks[0]);
  std::vector<haptic::rt::Eq18Neighbor> nb;
  const int sums[3] = {14, 18, 6};  // 2 ceil(R/2) + 2 agreement ticks (the default)
  for (int n = 0; n < 3; ++n) nb.push_back({static_cast<double>(sums[n]), spec.period_s, &b.gains[static_cast<std::size_t>(b.neighbor_edge[0][static_cast<std::size_t>(n)])]});
  DOUBLES_EQUAL(haptic::rt::damping_min_eq18(spec.period_s, nb), m.damping_min_Ns_per_m, 1e-12);
  DOUBLES_EQUAL(1.05 * m.damping_min_Ns_per_m, m.damping_Ns_per_m, 1e-12);
  // larger measured round trips need more damping; an override is taken as is
  CHECK(bounds_from_round_trips(b, 0, {20, 25, 13}, {1, 1, 1}, 0.05, -1).damping_min_Ns_per_m > m.damping_min_Ns_per_m);
  DOUBLES_EQUAL(4.0, bounds_from_round_trips(b, 0, {10, 15, 3}, {1, 1, 1}, 0.05, 4.0).damping_Ns_per_m, 0);
  CHECK_THROWS(std::invalid_argument, bounds_from_round_trips(b, 0, {10}, {1}, 0.05, -1));
}

TEST(StationConfig, TheLabConfigsParse) {
  for (int i = 1; i <= 4; ++i) {
    const std::string path = std::string(HAPTIC_SOURCE_DIR) + "/firmware/deploy/lab-4-stations/station-" + std::to_string(i) + ".toml";
    const StationFile f = load_station_file(path);
    LONGS_EQUAL(i, f.station.id);
    const ScenarioSpec s = station_scenario_spec(f, RunOverrides{});
    LONGS_EQUAL(4, s.users);
    // No usable key ships: the [network] section is refused until a real key is put in.
    try {
      haptic::net::parse_net_config(f.text, 99);
      FAIL("the shipped lab configuration's key was accepted");
    } catch (const std::invalid_argument& e) {
      // its own key file is not there (or, once made, the peers' public keys are placeholders)
      const std::string what = e.what();
      CHECK_TEXT(what.find("network.key_file") != std::string::npos || what.find(".public_key") != std::string::npos, e.what());
    }
    CHECK(f.text.find("key_file") != std::string::npos);
    CHECK(f.text.find("REPLACE-with-station-") != std::string::npos);  // public keys are placeholders
  }
}

TEST(StationConfig, AgreementTickCoversAPeerWhoseRoundTripIsTwoTicksLonger) {
  const BuiltScenario b = build_scenario(make_scenario("paper-best"));
  // station 1 measured R = 14 to station 2 (after the allowance), station 2 measured R = 16 back
  const MeasuredBounds at1 = bounds_from_round_trips(b, 0, {13, 5, 5}, {1, 1, 1}, 0.05, -1, 1);
  const MeasuredBounds at2 = bounds_from_round_trips(b, 1, {15}, {1}, 0.05, -1, 1);
  const int enforced = at1.index_guard_ticks[0] + at2.index_guard_ticks[0];  // 7 + 8
  CHECK(enforced <= at1.assumed_sum_ticks[0]);
  CHECK(enforced <= at2.assumed_sum_ticks[0]);
  // without the agreement tick station 1's eq. (18) would assume less than is enforced
  CHECK(enforced > bounds_from_round_trips(b, 0, {13, 5, 5}, {1, 1, 1}, 0.05, -1, 0).assumed_sum_ticks[0]);
}

TEST(StationConfig, AViewBindThatIsNotAnIPv4AddressIsRejectedNamingTheKey) {
  // an interface name: libwebsockets would take it and, when it does not exist, retry silently
  CHECK(contains(error_of("[station]\nid = 1\nview_port = 46001\nview_bind = \"eth0\"\n" + kNet), "station.view_bind must be an IPv4 address"));
  CHECK(contains(error_of("[station]\nid = 1\nview_port = 46001\nview_bind = \"\"\n" + kNet), "station.view_bind"));
  STRCMP_EQUAL("0.0.0.0", parse_station_file("[station]\nid = 1\nview_port = 46001\nview_bind = \"0.0.0.0\"\n" + kNet).view.bind.c_str());
}
