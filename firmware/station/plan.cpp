#include "firmware/station/plan.hpp"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cstdlib>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "firmware/model/graph.hpp"
#include "firmware/station/link_impairment.hpp"
#include "firmware/station/probe.hpp"
#include "firmware/station/records.hpp"
#include "firmware/session/recorder.hpp"
#include "platform/toml_config.hpp"
#include "net/transport_udp.hpp"
#include "net/wire.hpp"
#include "platform/clock.hpp"
#include "platform/toml_config.hpp"

namespace haptic::firmware {

using platform::config::number_text;

namespace {

constexpr std::size_t kMaxStateValues = 64'000'000;  // 512 MB of doubles in the state window: refuse above

using platform::clock_ns;

[[noreturn]] void bad(const std::string& what) { throw std::invalid_argument("config: " + what); }

// ScenarioSpec::validate() names the simulator's flags; a station file writes them as [station] keys.
std::string as_station_keys(std::string message) {
  static const std::pair<const char*, const char*> kKeys[] = {{"--topology", "station.topology"}, {"--nodes", "station.nodes"},
                                                              {"--duration", "station.duration_s"}, {"--release", "station.release_s"}, {"--delay-matrix", "station.delay_matrix"},
                                                              {"--push-end", "station.push_end_s"},
                                                              {"--resilient-f", "station.resilient_f"}, {"--edge-energy-bound", "station.edge_energy_bound_J"},
                                                              {"--edge-energy-hold-s", "station.edge_energy_hold_s"},
                                                              {"--state-check-kinematic-m", "station.state_check_kinematic_m"},
                                                              {"--tx-predict needs --consensus-passivity pspm", "station.tx_predict = true needs station.consensus_passivity = \"pspm\""}};
  for (const auto& [flag, key] : kKeys)
    for (auto at = message.find(flag); at != std::string::npos; at = message.find(flag, at)) message.replace(at, std::strlen(flag), key);
  return message;
}

// FNV-1a, 64 bit, over raw bytes.
struct Fnv1a {
  std::uint64_t h = 1469598103934665603ULL;
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ULL;
  }
  template <class T>
  void value(const T& v) {
    bytes(&v, sizeof v);
  }
  void sparse(const rt::SpatialMatrix& m) {
    value(m.width);
    for (int r = 0; r < m.S.outerSize(); ++r)
      for (rt::SparseRowMajor::InnerIterator it(m.S, r); it; ++it) {
        value(static_cast<std::int64_t>(r));
        value(static_cast<std::int64_t>(it.col()));
        value(it.value());
      }
  }
};

drivers::DeviceSelection device_selection(const StationFile& f, const BuiltScenario& built, int me) {
  drivers::DeviceSelection sel;
  sel.kind = f.device.kind;
  sel.safety.max_force_N = f.device.max_force_N;
  sel.safety.max_power_W = f.device.max_power_W;
  sel.safety.max_speed_m_per_s = f.device.max_speed_m_per_s;
  sel.safety.max_stale_reads = static_cast<std::uint32_t>(f.device.max_stale_reads);
  sel.safety.max_reads_before_first_sample = static_cast<std::uint32_t>(f.device.max_reads_before_first_sample);
  sel.safety.workspace_margin = f.device.workspace_margin;
  // a bare library name ("libHD.so") is for the dynamic loader's search; a path is the file's
  const bool lib_is_path = f.device.hd_library_path.find('/') != std::string::npos;
  sel.touch.hd_library_path = lib_is_path ? f.relative_to_file(f.device.hd_library_path) : f.device.hd_library_path;
  sel.touch.device_name = f.device.hd_device_name;
  sel.spacemouse.hidraw_path = f.device.hidraw_path;
  sel.usb_serial = f.device.usb_serial;
  sel.falcon.firmware_path = f.relative_to_file(f.device.falcon_firmware_path);
  sel.falcon.index = f.device.falcon_index;
  sel.falcon.homing_timeout_s = f.device.falcon_homing_timeout_s;
  sel.simulated.device = built.spec.device;
  sel.simulated.hand = built.spec.hand;
  sel.simulated.script = built.goal_script(me);
  const Eigen::Vector3d p0 = built.vp_start[static_cast<std::size_t>(me)];
  for (int a = 0; a < 3; ++a) sel.simulated.start_position_m[a] = p0[a];
  sel.simulated.max_force_N = f.device.sim_max_force_N;
  sel.simulated.workspace_radius_m = std::max(0.1, 2.0 * p0.norm() + built.spec.script.retract_depth_m);
  return sel;
}

}  // namespace

std::uint64_t record_ring_ticks(const StationPlan& p) {
  return p.file.record.ring_s > 0 ? static_cast<std::uint64_t>(std::max(1LL, std::llround(p.file.record.ring_s / p.built->spec.period_s))) : 0;
}

namespace {

// The trace and state windows (station/records.hpp): kRecordWindowS of rows each, whatever the
// planned duration; the writer thread empties them every 20 ms.
void plan_records(StationPlan& p) {
  const StationSection& s = p.file.station;
  const double window_ticks = kRecordWindowS / p.built->spec.period_s;
  p.trace_capacity = static_cast<std::size_t>(std::ceil(window_ticks / s.trace_every)) + 2;
  p.state_capacity = static_cast<std::size_t>(std::ceil(window_ticks / s.state_every)) + 2;
  if (p.state_capacity * static_cast<std::size_t>(p.built->scene.dofs) > kMaxStateValues)
    bad("station.state_every too small for the nodes (the state rows of " + number_text(kRecordWindowS) + " s would be over 64e6 values)");
  const RecordSection& r = p.file.record;
  if (r.enabled && r.ring_s > 0) {
    const bool f32 = p.net.endpoint.wire.encoding == net::ValueEncoding::float32;
    const auto bytes = ring_bytes(record_ring_ticks(p), static_cast<int>(p.neighbours().size()), p.built->scene.dofs, f32);
    if (static_cast<double>(bytes) > r.max_mb * 1024 * 1024)
      bad("station.record_ring_s = " + number_text(r.ring_s) + " needs " + number_text(std::ceil(static_cast<double>(bytes) / (1024 * 1024))) +
          " MB at " + std::to_string(p.built->scene.nodes) + " nodes and " + std::to_string(p.neighbours().size()) +
          " neighbours, above station.record_max_mb = " + number_text(r.max_mb) + ": shorten the ring or raise the bound");
  }
}

void plan_release_warning(StationPlan& p) {
  const ScenarioSpec& spec = p.built->spec;
  if (spec.script.kind != UserScriptSpec::Kind::kPushHoldRelease || spec.duration_s > spec.script.release_s) return;
  p.ends_before_release = true;
  const std::string src = p.overrides.duration_s > 0 ? "--duration" : (p.file.station.duration_s > 0 ? "station.duration_s" : "the scenario's duration");
  p.warnings.push_back("the run (" + src + " = " + number_text(spec.duration_s) + " s) ends before the scripted release at station.release_s = " +
                       number_text(spec.script.release_s) + " s: the release metrics will be null and the exit code " + std::to_string(kExitBeforeRelease));
}

// station.resilient_f = F on a topology that is not (2F+1)-robust (firmware/model/graph.hpp): the rule
// still runs and bounds what a liar can do, but the honest stations need not agree; a station with at
// most F neighbours leaves all of them out. Said, not refused.
void plan_resilient_warning(StationPlan& p) {
  const ScenarioSpec& spec = p.built->spec;
  const int f = spec.resilient_f;
  if (f <= 0 || spec.users > model::kMaxRobustnessUsers) return;
  const int r = model::robustness(spec.topology, spec.users, "station.topology");
  if (r < 2 * f + 1)
    p.warnings.push_back("station.resilient_f = " + std::to_string(f) + " needs a " + std::to_string(2 * f + 1) + "-robust topology for the honest " +
                         "stations to agree; this one is " + std::to_string(r) + "-robust (haptic-topology --robustness " + std::to_string(2 * f + 1) + ")");
  if (static_cast<int>(p.neighbours().size()) <= f)
    p.warnings.push_back("station.resilient_f = " + std::to_string(f) + " with " + std::to_string(p.neighbours().size()) +
                         " neighbours: this station leaves every neighbour out, every tick (its copy is not coupled)");
}

// A device file named in [device] that is not there: the device will not start (exit 9 at start-up,
// never a simulated user); --check-config says so first, with the path as resolved.
void plan_device_file_warnings(StationPlan& p) {
  const DeviceSection& d = p.file.device;
  auto missing = [&](const std::string& key, const std::string& value, const std::string& resolved, const char* what) {
    std::error_code ec;
    if (value.empty() || std::filesystem::exists(resolved, ec)) return;
    p.warnings.push_back("device." + key + " = \"" + value + "\": no such file" + (resolved != value ? " (" + resolved + ", relative to the station file's folder)" : std::string()) +
                         ": " + what + " will not start (exit " + std::to_string(kExitDeviceMissing) + ")");
  };
  if (d.kind == "falcon") missing("falcon_firmware_path", d.falcon_firmware_path, p.device.falcon.firmware_path, "the Falcon");
  if ((d.kind == "touch" || d.kind == "auto") && d.hd_library_path.find('/') != std::string::npos)
    missing("hd_library_path", d.hd_library_path, p.device.touch.hd_library_path, "a Touch");
}

namespace {

// Probing sends a state every send_interval_ticks (the deadband's pace): before the round-trip bounds
// are taken it must send at least net.rtt_min_probe_samples of them, or no link can get its bound.
// A fresh start takes them at its freeze (probe_freeze_tick), a rejoin at the end of its probing;
// `key` names the setting (station.probe_s, station.rejoin_probe_s).
void check_probe_samples(const net::NetConfig& nc, const ScenarioSpec& spec, const std::string& key, std::int64_t probe_ticks, bool freezes) {
  const std::int64_t pace = send_interval_ticks(spec);
  const auto sent_by_bounds = [&](std::int64_t ticks) {
    const std::int64_t until = freezes ? probe_freeze_tick(ticks) : ticks;
    return until > 0 ? (until - 1) / pace + 1 : std::int64_t{0};
  };
  const std::int64_t sent = sent_by_bounds(probe_ticks);
  const auto need = static_cast<std::int64_t>(nc.endpoint.rtt.min_probe_samples);
  if (sent >= need) return;
  std::int64_t enough = probe_ticks;  // the fewest probing ticks that send the need-th state before the bounds
  while (sent_by_bounds(enough) < need) ++enough;
  const double probe_s = static_cast<double>(enough) * spec.period_s;
  bad(key + " = " + number_text(static_cast<double>(probe_ticks) * spec.period_s) + " s sends " + std::to_string(sent) +
      " probe states before the round-trip bounds " + (freezes ? "freeze" : "are taken") + " (one every " + std::to_string(pace) +
      " ticks: station.tx_max_interval_ticks), fewer than the " + std::to_string(need) +
      " round trips a link needs (net.rtt_min_probe_samples): probe for at least " + number_text(probe_s) + " s");
}

}  // namespace

// The network side of the plan (a station with neighbours): [net] parsed by net/, the peer table,
// addresses, the link impairments, the timeline with its probing and set-up gap, the endpoint's epoch.
void plan_network(StationPlan* p, const ClockReading& now) {
  const StationFile& f = p->file;
  const RunOverrides& o = p->overrides;
  const ScenarioSpec& spec = p->built->spec;
  p->net = net::parse_net_config(f.text, static_cast<std::uint32_t>(p->built->scene.dofs), f.path);
  p->net.endpoint.rtt.bound_policy = &model::round_trip_bound_s;  // the passivity budget's margin rule; net/ measures
  if (p->net.endpoint.wire.station_id != f.station.id)
    bad("the wire station id (" + f.net_section + ".station_id / station.id) must be station.id = " + std::to_string(f.station.id));
  p->peers = plan_peer_table(f, *p->built, p->me, p->net);
  check_address_families(f, p->net);
  check_peer_networks(f, p->net);
  check_bind_address(f, p->net);
  check_io_cpu(f, p->net);
  check_tx_spin(f, p->net);
  apply_station_impairments(f, spec, p->net);  // the simulator's link set-up and seed rule
  p->times = plan_times(f, o, spec, now);
  if (!p->times.rejoin) {
    check_probe_samples(p->net, spec, "station.probe_s", p->times.probe_ticks, true);
  } else {
    check_probe_samples(p->net, spec, "station.rejoin_probe_s", rejoin_probe_ticks(f.station.rejoin_probe_s, spec.period_s), false);
    p->warnings.push_back("started " + std::to_string(-p->times.epoch_in_s) + " s after the common epoch (" +
                          (o.start_at >= 0 ? std::string("--start-at") : std::string("station.start_at")) +
                          "), past half the probing phase: rejoining the running session");
  }
  p->net.endpoint.impairment_epoch_s = static_cast<double>(p->times.run_epoch_ns()) * 1e-9;
  p->net.endpoint.impairment_first_run_seq = static_cast<std::uint64_t>(p->times.run_k0);  // run packet k draws the simulator's fate k
  p->net.endpoint.tx_period_s = spec.period_s;  // tick-synchronous TX (net.tx_spin) needs the tick period
  // A common epoch given (start_at / --start-at): the session's sequence numbers follow the clock, so
  // the endpoint's sequence ceiling holds while probing too (without it an authentic far-future
  // sequence while probing made a station rejoin a session that did not exist). A station that
  // plans its own epoch must be able to find a session already running: no ceiling until its tick.
  if ((o.start_at >= 0 ? o.start_at : f.station.start_at) > 0) p->net.endpoint.sequence_epoch_ns = p->times.epoch_ns;
}

// `haptic-station solo`: no network (no [net] parsed, no peer, no endpoint) and a timeline without
// probing or set-up gap (run_k0 = 0); the epoch is provisional: the solo run sets it once its core is
// built (run.cpp). The plan's other checks (scene, device, eq. 26, records, out_dir) are the station's.
void plan_solo(StationPlan& p, const ClockReading& now) {
  p.net.transport = "none";
  p.times.period_ns = p.file.loop.period_ns;
  p.times.epoch_ns = now.monotonic_ns;
  p.times.probe_ticks = 0;
  p.times.run_k0 = 0;
  p.times.run_ticks = std::llround(p.built->spec.duration_s / p.built->spec.period_s);
}

// Every check and translation of the plan phase; throws std::invalid_argument naming the key.
std::unique_ptr<StationPlan> make_plan(const StationFile& f, const RunOverrides& o, const ClockReading& now) {
  auto p = std::make_unique<StationPlan>();
  p->file = f;
  p->overrides = o;
  const ScenarioSpec spec = station_scenario_spec(f, o);
  p->built = std::make_shared<const BuiltScenario>(build_scenario(spec));
  p->station_id = o.solo ? 1 : f.station.id;
  p->me = p->station_id - 1;
  if (o.solo) {
    plan_solo(*p, now);
  } else {
    plan_network(p.get(), now);
  }
  p->device = device_selection(f, *p->built, p->me);
  if (const auto caps = drivers::published_capabilities(p->device)) {
    p->coupling = device_coupling(f, spec, *caps);
    // at the steps the core will take (station.period_min_s/max_s); the same check runs at start-up on the opened device
    const auto me = static_cast<std::size_t>(p->me);
    check_device_coupling(*p->coupling, p->built->t_min_s[me], p->built->t_max_s[me]);
    workspace_map_config(f, *caps);  // a bad map is a configuration error here too
  } else if (const std::string absent = drivers::auto_device_absence(p->device); !absent.empty()) {
    std::string found = absent.substr(0, absent.size() - 1);
    std::replace(found.begin(), found.end(), '\n', ';');
    throw drivers::DeviceMissing("device.kind = \"auto\": no device to start on this machine (" + found +
                                 "; name the kind, or \"simulated\" for the scenario's scripted user)");
  } else {
    p->warnings.push_back("device.kind = \"auto\": eq. (26) on the device's damping is checked at start-up, once the device is open "
                          "(name the kind to have --check-config check it)");
  }
  plan_device_file_warnings(*p);
  p->ramp_in_ticks = ramp_in_ticks(f, spec.period_s);
  p->fingerprint = station_fingerprint(*p->built, f);
  p->net.endpoint.fingerprint = p->fingerprint;  // sent to every neighbour (net/)
  p->net.endpoint.io_priority = f.station.io_priority;  // the I/O thread's RtThread (SCHED_FIFO or 0)
  set_payload_envelope(*p->built, p->net);
  p->out_dir = o.out_dir.empty() ? f.station.out_dir : o.out_dir;
  if (f.station.run_subdir) {  // a folder per run: <UTC time of planning>-s<session id>
    const std::time_t secs = static_cast<std::time_t>(now.realtime_ns / 1'000'000'000);
    std::tm utc{};
    gmtime_r(&secs, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
    char sess[16];
    std::snprintf(sess, sizeof sess, "%08x", p->net.endpoint.wire.session_id);
    p->out_dir += std::string("/") + stamp + "-s" + sess;
  }
  check_out_dir_creatable(p->out_dir, o.out_dir.empty() ? "station.out_dir" : "--out");
  p->base_path = p->out_dir + "/station-" + std::to_string(p->station_id);
  plan_records(*p);
  plan_release_warning(*p);
  plan_resilient_warning(*p);
  if (f.device.kind == "simulated" && o.solo)
    p->warnings.push_back("device.kind = \"simulated\": a SIMULATED user touches the object by itself (the scenario's random script)");
  else if (f.device.kind == "simulated")
    p->warnings.push_back("device.kind = \"simulated\": a SIMULATED user plays user " + std::to_string(f.station.id) +
                          "'s scripted push/hold/release; the other stations feel it as if a person pushed");
  return p;
}

}  // namespace

// The neighbour state check's parameters from the station.state_check_* keys (0 m: that check off).
static rt::EdgeMonitorParams state_check_params(const StationSection& s) {
  rt::EdgeMonitorParams p;
  p.kinematic_bound_m = s.state_check_kinematic_m > 0 ? s.state_check_kinematic_m : rt::EdgeMonitorParams::kOff;
  p.kinematic_window_s = s.state_check_kinematic_window_s;
  p.max_gap_ticks = s.state_check_max_gap_ticks;
  p.max_checked_gap_ticks = s.state_check_max_checked_gap_ticks;
  if (p.max_checked_gap_ticks < p.max_gap_ticks)
    bad("station.state_check_max_checked_gap_ticks = " + std::to_string(p.max_checked_gap_ticks) +
        " must be at least station.state_check_max_gap_ticks = " + std::to_string(p.max_gap_ticks));
  p.disagreement_bound_m = s.state_check_disagreement_m > 0 ? s.state_check_disagreement_m : rt::EdgeMonitorParams::kOff;
  p.disagreement_window_s = s.state_check_disagreement_window_s;
  p.readmit_s = s.state_check_readmit_s;
  return p;
}

ScenarioSpec station_scenario_spec(const StationFile& f, const RunOverrides& o) {
  const StationSection& s = f.station;
  ScenarioSpec spec = make_scenario(s.scenario, "station.scenario");
  if (s.users != 0) set_user_count(spec, s.users, "station.users");
  if (!s.delay_matrix.empty()) {
    try {
      spec.delay_ms = model::parse_delay_matrix(s.delay_matrix, "delay_matrix", spec.users);
    } catch (const std::invalid_argument& e) {
      bad("station.delay_matrix: " + std::string(e.what()));
    }
  }
  spec.script.push_pattern = parse_push_pattern(s.pushes, "station.pushes");
  apply_script_kind(spec.script, s.script, s.push_seed, "station.script");
  spec.script.push_seed = s.push_seed;
  if (!s.topology.empty()) {
    try {
      spec.topology = model::parse_graph_1based(s.topology, spec.users, "topology");
    } catch (const std::invalid_argument& e) {
      bad("station.topology = \"" + s.topology + "\": " + e.what());
    }
  }
  spec.scene_nodes = s.nodes;
  if (!f.scene.file.empty()) {
    spec.scene_file.path = f.relative_to_file(f.scene.file);
    spec.scene_file.from_station_file = true;
    spec.scene_file.unit_m = f.scene.unit_m;
    spec.scene_file.density_kg_per_m3 = f.scene.density_kg_per_m3;
    spec.scene_file.youngs_modulus_Pa = f.scene.youngs_modulus_Pa;
    spec.scene_file.max_elements = f.scene.max_elements;
  }
  spec.seed = s.seed;
  if (s.period_min_s > spec.period_s) bad("station.period_min_s = " + number_text(s.period_min_s) + " must be at most the period " + number_text(spec.period_s) + " s (0 = measured while probing)");
  if (s.period_max_s > 0 && (s.period_max_s < spec.period_s || s.period_max_s >= 2 * spec.period_s))
    bad("station.period_max_s = " + number_text(s.period_max_s) + " must be in [period, 2 period) = [" + number_text(spec.period_s) + ", " + number_text(2 * spec.period_s) + ") s (0 = measured while probing)");
  spec.delay_correlation = s.delay_correlation;  // the emulated links' delay (scenario_link), as the simulator's
  // The keys (0: the nominal period here; the run measures its bounds while probing, StepSet in
  // probe.hpp, never beyond what eq. (26) allows the opened device, so this plan's check holds for them).
  spec.period_min_s = s.period_min_s;
  spec.period_max_s = s.period_max_s;
  const double dur = o.duration_s > 0 ? o.duration_s : s.duration_s;
  if (dur > 0) spec.duration_s = dur;
  if (s.push_start_s >= 0) spec.script.push_start_s = s.push_start_s;
  if (s.push_end_s >= 0) spec.script.push_end_s = s.push_end_s;
  if (s.release_s >= 0) spec.script.release_s = s.release_s;
  spec.damping_margin = s.damping_margin;
  spec.consensus_passivity = rt::parse_consensus_passivity(s.consensus_passivity, "station.consensus_passivity");
  spec.pspm_reservoir0_J = s.pspm_reservoir_J;
  spec.resilient_f = s.resilient_f;
  spec.receive_rule = rt::parse_rx_rule(s.receive_rule, "station.receive_rule");
  spec.loss_allowance_ticks = s.loss_allowance_ticks;
  spec.edge_energy_bound_J = s.edge_energy_bound_J;
  spec.edge_energy_leak_W = s.edge_energy_leak_W;
  spec.edge_energy_hold_s = s.edge_energy_hold_s;
  spec.return_ramp_s = s.return_ramp_s;
  spec.drop_fade_s = s.drop_fade_s;
  // pspm never drops an edge (rt::StationConfig refuses the check with it): the check runs with eq18 only
  if (spec.consensus_passivity != rt::ConsensusPassivity::kSetPositionModulation) spec.state_check = state_check_params(s);
  spec.divergence_speed_m_per_s = s.divergence_speed_m_per_s;
  spec.tx_deadband.position_deadband_m = s.tx_deadband_mm * 1e-3;
  spec.tx_deadband.max_interval_ticks = s.tx_max_interval_ticks;
  spec.tx_deadband.predictive = s.tx_predict;
  if (std::llabs(std::llround(spec.period_s * 1e9) - f.loop.period_ns) > 0)
    bad("loop.period_ns must equal the scenario's period " + std::to_string(std::llround(spec.period_s * 1e9)) + " ns (the paper's T = 2 ms)");
  if (o.solo) {  // one user, no links: station.id, users, topology and delays do not apply
    make_solo(spec, o.solo_anchor_N_per_m);
    apply_script_kind(spec.script, s.script, s.push_seed, "station.script");  // a script named in the file (or --script) over solo's random
  } else if (s.id > spec.users) bad("station.id must be in [1, " + std::to_string(spec.users) + "] for scenario " + spec.name);
  const auto& sc = spec.script;
  if (sc.kind == UserScriptSpec::Kind::kPushHoldRelease && !(sc.push_start_s < sc.push_end_s && sc.push_end_s < sc.release_s))
    bad("station.push_start_s < station.push_end_s < station.release_s must hold (got " + std::to_string(sc.push_start_s) + ", " +
        std::to_string(sc.push_end_s) + ", " + std::to_string(sc.release_s) + ")");
  try {
    spec.validate();
  } catch (const std::invalid_argument& e) {
    bad(as_station_keys(e.what()));
  }
  return spec;
}

std::string fingerprint_text(const SceneFingerprint& f) {
  return "protocol " + std::to_string(f.protocol_version) + ", nodes " + std::to_string(f.scene_nodes) + ", period_ns " + std::to_string(f.period_ns) +
         ", scene hash " + std::to_string(f.scene_hash) + ", gains hash " + std::to_string(f.gains_hash) + ", consensus law " +
         std::to_string(f.consensus_law) + ", tx_predict " + std::to_string(f.tx_predict) + ", tx deadband hash " + std::to_string(f.tx_deadband_hash);
}

SceneFingerprint scene_fingerprint(const BuiltScenario& b, std::int64_t period_ns) {
  SceneFingerprint fp;
  fp.protocol_version = net::kWireVersion;
  fp.scene_nodes = b.scene.nodes;
  fp.period_ns = period_ns;
  // scene_hash: high 32 bits the geometry (rest positions, tetrahedra, edges), low 32 bits the
  // material (M, B, K as assembled, ground/damping parameters), so a mismatch says which differs.
  Fnv1a geometry, material;
  geometry.bytes(b.scene.x_d.data(), sizeof(double) * static_cast<std::size_t>(b.scene.x_d.size()));
  for (const auto& t : b.scene.mesh.tets) geometry.value(t);
  for (const auto& e : b.scene.mesh.edges) geometry.value(e);
  material.sparse(b.scene.M);
  material.sparse(b.scene.B);
  material.sparse(b.scene.K);
  material.value(b.scene.params.damping_Ns_per_m);
  material.value(b.scene.params.ground_stiffness_N_per_m);
  fp.scene_hash = (geometry.h & 0xFFFFFFFF00000000ULL) | (material.h >> 32);
  Fnv1a g;
  g.value(b.spec.users);
  for (const auto& l : b.spec.topology) g.value(l);
  for (const auto& e : b.gains) {
    g.sparse(e.P);
    g.sparse(e.D);
  }
  g.value(b.spec.vp);
  fp.gains_hash = g.h;
  // The coupling law both ends must run alike (net::Fingerprint).
  fp.consensus_law = b.spec.consensus_passivity == rt::ConsensusPassivity::kSetPositionModulation ? net::kConsensusLawPspm : net::kConsensusLawEq18;
  fp.tx_predict = b.spec.tx_deadband.predictive ? 1 : 0;
  if (b.spec.tx_deadband.enabled()) {
    const double band[2] = {b.spec.tx_deadband.position_deadband_m, static_cast<double>(b.spec.tx_deadband.max_interval_ticks)};
    const std::uint64_t h = net::fingerprint_hash(band, sizeof band);
    fp.tx_deadband_hash = static_cast<std::uint16_t>((h ^ (h >> 16) ^ (h >> 32) ^ (h >> 48)) | 1u);  // 0 means off
  }
  return fp;
}

SceneFingerprint station_fingerprint(const BuiltScenario& b, const StationFile& f) {
  SceneFingerprint fp = scene_fingerprint(b, f.loop.period_ns);
  Fnv1a g;
  g.value(fp.gains_hash);
  g.value(f.shared_options_hash);
  fp.gains_hash = g.h;
  return fp;
}

ClockReading read_clocks() { return {clock_ns(CLOCK_MONOTONIC), clock_ns(CLOCK_REALTIME)}; }

void set_payload_envelope(const BuiltScenario& b, net::NetConfig& nc) {
  if (!(nc.envelope_radii > 0.0)) return;
  const Eigen::VectorXd& x = b.scene.x_d;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int p = 0; p < b.scene.nodes; ++p) c += x.segment<3>(3 * p);
  c /= b.scene.nodes;
  double radius = 0.0;
  for (int p = 0; p < b.scene.nodes; ++p) radius = std::max(radius, (x.segment<3>(3 * p) - c).norm());
  nc.endpoint.envelope_rest_x.assign(x.data(), x.data() + x.size());
  nc.endpoint.envelope_max_offset_m = nc.envelope_radii * radius;
  nc.endpoint.envelope_max_speed_m_per_s = b.station_config(0).divergence_speed_m_per_s;  // the core's own divergence bound
}

PeerTable plan_peer_table(const StationFile& f, const BuiltScenario& built, int me, const net::NetConfig& nc) {
  const auto& nbrs = built.neighbors[static_cast<std::size_t>(me)];
  const auto& peers = nc.endpoint.peers;
  PeerTable t;
  t.peer_to_nbr.assign(peers.size(), -1);
  t.nbr_to_peer.assign(nbrs.size(), -1);
  t.sender_to_nbr.assign(65536, -1);
  const std::string topo = f.station.topology.empty() ? "the topology of scenario " + built.spec.name : "station.topology = \"" + f.station.topology + "\"";
  for (std::size_t p = 0; p < peers.size(); ++p) {
    const int u = peers[p].station_id - 1;
    for (std::size_t n = 0; n < nbrs.size(); ++n)
      if (nbrs[n] == u) t.peer_to_nbr[p] = static_cast<int>(n);
    const std::string key = f.peer_key(p, "id");
    if (t.peer_to_nbr[p] < 0) bad(key + " = " + std::to_string(u + 1) + " is not a neighbour of station " + std::to_string(me + 1) + " in " + topo);
    const int first = t.nbr_to_peer[static_cast<std::size_t>(t.peer_to_nbr[p])];
    if (first >= 0) bad(key + " = " + std::to_string(u + 1) + " lists that station a second time (also " + f.peer_key(static_cast<std::size_t>(first), "id") + ")");
    t.nbr_to_peer[static_cast<std::size_t>(t.peer_to_nbr[p])] = static_cast<int>(p);
    t.sender_to_nbr[static_cast<std::size_t>(u + 1)] = t.peer_to_nbr[p];
  }
  for (std::size_t n = 0; n < nbrs.size(); ++n)
    if (t.nbr_to_peer[n] < 0)
      bad(f.net_section + ".peers lacks station " + std::to_string(nbrs[n] + 1) + ", a neighbour of station " + std::to_string(me + 1) + " in " + topo);
  return t;
}

void check_address_families(const StationFile& f, const net::NetConfig& nc) {
  if (nc.transport != "udp") return;
  socklen_t len = 0;
  const std::string bind_key = f.net_section + ".bind";
  const int family = net::parse_udp_address(nc.bind, bind_key, len).ss_family;
  for (std::size_t p = 0; p < nc.udp_peers.size(); ++p) {
    const std::string key = f.peer_key(p, "address");
    if (net::parse_udp_address(nc.udp_peers[p].address, key, len).ss_family != family)
      bad(key + " = \"" + nc.udp_peers[p].address + "\" must be the same address family (IPv4 or IPv6) as " + bind_key + " = \"" + nc.bind + "\"");
  }
}

namespace {
// Is `peer` on loopback or on the network of interface address `ifa` with mask `mask`? Not RT-safe.
bool same_network(const sockaddr_storage& peer, const sockaddr* ifa, const sockaddr* mask) {
  if (!ifa || !mask || ifa->sa_family != peer.ss_family) return false;
  const unsigned char *a = nullptr, *m = nullptr, *p = nullptr;
  std::size_t n = 0;
  if (peer.ss_family == AF_INET) {
    a = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in*>(ifa)->sin_addr);
    m = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in*>(mask)->sin_addr);
    p = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in*>(&peer)->sin_addr);
    n = 4;
  } else if (peer.ss_family == AF_INET6) {
    a = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in6*>(ifa)->sin6_addr);
    m = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in6*>(mask)->sin6_addr);
    p = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in6*>(&peer)->sin6_addr);
    n = 16;
  } else {
    return false;
  }
  for (std::size_t i = 0; i < n; ++i)
    if ((a[i] & m[i]) != (p[i] & m[i])) return false;
  return true;
}

std::string address_text(const sockaddr* sa) {
  char buf[INET6_ADDRSTRLEN] = "?";
  if (sa->sa_family == AF_INET) inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(sa)->sin_addr, buf, sizeof buf);
  if (sa->sa_family == AF_INET6) inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(sa)->sin6_addr, buf, sizeof buf);
  return buf;
}
}  // namespace

void check_bind_address(const StationFile& f, const net::NetConfig& nc) {
  if (nc.transport != "udp") return;
  const std::string key = f.net_section + ".bind";
  socklen_t len = 0;
  const sockaddr_storage bind = net::parse_udp_address(nc.bind, key, len);
  const unsigned char* a = nullptr;
  std::size_t n = 0;
  if (bind.ss_family == AF_INET) {
    a = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in*>(&bind)->sin_addr);
    n = 4;
    if (a[0] == 127) return;  // Linux: the loopback interface owns all of 127.0.0.0/8
  } else if (bind.ss_family == AF_INET6) {
    a = reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in6*>(&bind)->sin6_addr);
    n = 16;
  } else {
    return;
  }
  if (std::all_of(a, a + n, [](unsigned char c) { return c == 0; })) return;  // the wildcard: net.listen_any decides
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) bad(std::string("cannot list this machine's interfaces (getifaddrs: ") + std::strerror(errno) + ") to check " + key);
  std::unique_ptr<ifaddrs, void (*)(ifaddrs*)> guard(list, freeifaddrs);
  std::string addrs;
  for (const ifaddrs* it = list; it; it = it->ifa_next) {
    if (!it->ifa_addr || it->ifa_addr->sa_family != bind.ss_family) continue;
    const unsigned char* b = bind.ss_family == AF_INET
                                 ? reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in*>(it->ifa_addr)->sin_addr)
                                 : reinterpret_cast<const unsigned char*>(&reinterpret_cast<const sockaddr_in6*>(it->ifa_addr)->sin6_addr);
    if (std::equal(a, a + n, b)) return;
    addrs += std::string(addrs.empty() ? "" : ", ") + it->ifa_name + " " + address_text(it->ifa_addr);
  }
  bad(key + " = \"" + nc.bind + "\" is not an address of this machine (its addresses: " + (addrs.empty() ? std::string("none") : addrs) +
      "): a station binds its own address (is this the lab PC the file was written for?)");
}

void check_peer_networks(const StationFile& f, const net::NetConfig& nc) {
  if (nc.transport != "udp" || f.station.allow_routed_peers) return;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) bad(std::string("cannot list this machine's interfaces (getifaddrs: ") + std::strerror(errno) + ") to check the peers' networks");
  std::unique_ptr<ifaddrs, void (*)(ifaddrs*)> guard(list, freeifaddrs);
  for (std::size_t i = 0; i < nc.udp_peers.size(); ++i) {
    const std::string key = f.peer_key(i, "address");
    socklen_t len = 0;
    const sockaddr_storage peer = net::parse_udp_address(nc.udp_peers[i].address, key, len);
    std::string nets;
    bool on_a_network = false;
    for (const ifaddrs* it = list; it; it = it->ifa_next) {
      if (!it->ifa_addr || (it->ifa_addr->sa_family != AF_INET && it->ifa_addr->sa_family != AF_INET6)) continue;
      on_a_network = on_a_network || same_network(peer, it->ifa_addr, it->ifa_netmask);
      nets += std::string(nets.empty() ? "" : ", ") + it->ifa_name + " " + address_text(it->ifa_addr);
    }
    if (!on_a_network)
      bad(key + " = \"" + nc.udp_peers[i].address + "\" is on no network of this machine's interfaces (" + nets +
          "): refusing to send packets to it through a router by accident (is this the lab PC the file was written for?); "
          "set station.allow_routed_peers = true for stations across routers");
  }
}

void check_io_cpu(const StationFile& f, const net::NetConfig& nc) {
  const int cpu = nc.endpoint.io_cpu;
  if (cpu < 0) return;
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return;  // cannot tell: the endpoint reports it at start
  if (CPU_ISSET(cpu, &allowed)) return;
  std::string list;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &allowed)) {
      if (!list.empty()) list += ' ';
      list += std::to_string(c);
    }
  bad(f.net_section + ".io_cpu = " + std::to_string(cpu) + " must be -1 or a CPU this process may run on here (" + list + ")");
}

void check_tx_spin(const StationFile& f, const net::NetConfig& nc) {
  const auto& e = nc.endpoint;
  if (e.tx_spin && e.tx_direct)
    bad(f.net_section + ".tx_spin and " + f.net_section + ".tx_direct are both true: choose one (tx_direct: the tick "
        "sends its push itself; tx_spin: the I/O thread spins for it)");
  if (!e.tx_spin) return;
  const double period_us = static_cast<double>(f.loop.period_ns) * 1e-3;
  const double lead_us = e.tx_spin_lead_s * 1e6, tail_us = e.tx_spin_tail_s * 1e6;
  const std::string P = f.net_section;
  if (!(lead_us < period_us)) bad(P + ".tx_spin_lead_us = " + number_text(lead_us) + " must be shorter than the tick period (loop.period_ns = " + number_text(period_us) + " us)");
  if (!(lead_us + tail_us < period_us))
    bad(P + ".tx_spin_lead_us + " + P + ".tx_spin_tail_us = " + number_text(lead_us + tail_us) + " us must be shorter than the tick period (loop.period_ns = " +
        number_text(period_us) + " us)");
}

void check_out_dir_creatable(const std::string& dir, const std::string& key) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p = fs::absolute(fs::path(dir), ec);
  if (ec) bad(key + " = \"" + dir + "\": " + ec.message());
  // The deepest existing ancestor must be a directory we may write into (or the directory itself).
  while (!fs::exists(p, ec) && p.has_parent_path() && p != p.parent_path()) p = p.parent_path();
  if (!fs::is_directory(p, ec)) bad(key + " = \"" + dir + "\" cannot be created: " + p.string() + " is not a directory");
  // Permission bits do not tell (root passes access() on /proc, where nothing can be created): make
  // and remove a directory there, as the run's outputs would be made.
  std::string probe = (p / ".haptic-check-XXXXXX").string();
  if (::mkdtemp(probe.data()) == nullptr)
    bad(key + " = \"" + dir + "\" cannot be " + (p == fs::absolute(fs::path(dir), ec) ? "written" : "created") + ": " + p.string() + ": " + std::strerror(errno));
  ::rmdir(probe.c_str());
}

StationTimes plan_times(const StationFile& f, const RunOverrides& o, const ScenarioSpec& spec, const ClockReading& now) {
  const StationSection& S = f.station;
  const double T = spec.period_s;
  StationTimes t;
  t.period_ns = f.loop.period_ns;
  const std::int64_t mono = now.monotonic_ns;
  const double start_at = o.start_at >= 0 ? o.start_at : S.start_at;
  if (start_at <= 0 && S.start_align_s > 0) {
    const std::int64_t clk_now = S.start_clock == "realtime" ? now.realtime_ns : mono;
    const auto align = static_cast<std::int64_t>(S.start_align_s * 1e9);
    const std::int64_t earliest = clk_now + static_cast<std::int64_t>(S.start_delay_s * 1e9);
    t.epoch_ns = ((earliest + align - 1) / align) * align - (clk_now - mono);
  } else if (start_at <= 0) {
    t.epoch_ns = mono + static_cast<std::int64_t>(S.start_delay_s * 1e9);
  } else if (S.start_clock == "realtime") {
    t.epoch_ns = static_cast<std::int64_t>(start_at * 1e9) - (now.realtime_ns - mono);
  } else {
    t.epoch_ns = static_cast<std::int64_t>(start_at * 1e9);
  }
  t.probe_ticks = std::llround(S.probe_s / T);
  t.run_k0 = t.probe_ticks + std::llround(S.setup_gap_s / T);
  t.run_ticks = std::llround(spec.duration_s / T);
  t.epoch_in_s = static_cast<double>(t.epoch_ns - mono) * 1e-9;
  // Started after half the probing phase: the session runs without us; rejoin it (a restart).
  // After the session's planned end there is nothing to rejoin.
  t.rejoin = mono > t.time_of(t.probe_ticks / 2);
  if (mono > t.time_of(t.run_end_k()))
    bad(std::string(o.start_at >= 0 ? "--start-at" : "station.start_at") + ": started " + std::to_string(-t.epoch_in_s) +
        " s after the common epoch, after the planned end of that session: nothing to rejoin; start earlier");
  return t;
}

PlanResult plan_station(const StationFile& file, const RunOverrides& overrides, const ClockReading& now) {
  PlanResult r;
  try {
    r.plan = make_plan(file, overrides, now);
    r.status = PhaseStatus::kOk;
  } catch (const drivers::DeviceMissing& e) {  // run's open phase would fail the same way: exit 9
    r.status = PhaseStatus::kDeviceMissing;
    r.error = e.what();
  } catch (const std::exception& e) {
    r.status = PhaseStatus::kConfigError;
    r.error = e.what();
  }
  return r;
}

std::size_t StationPlan::record_window_bytes() const { return TickRecords::window_bytes(trace_capacity, state_capacity, built->scene.dofs); }

std::int64_t StationPlan::clock_offset_limit_ticks() const {
  return static_cast<std::int64_t>(std::ceil(file.station.clock_offset_limit_ms * 1e-3 / built->spec.period_s));
}

net::EndpointConfig StationPlan::endpoint_config() const {
  net::EndpointConfig ec = net.endpoint;
  ec.max_sequence_ahead_ticks += static_cast<std::uint64_t>(clock_offset_limit_ticks());
  return ec;
}

}  // namespace haptic::firmware
