#include "firmware/station/config.hpp"

#include "platform/toml_config.hpp"
#include "rt/set_position_modulation.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace haptic::firmware {

namespace {

using platform::config::bad;
using platform::config::boolean;
using platform::config::integer;
using platform::config::only_keys;
using platform::config::real;
using platform::config::text;
using platform::config::View;

void parse_station_section(View root, StationFile& f) {
  const View st = root["station"];
  if (!st) bad("[station]", "present (with at least id = 1..users)");
  only_keys(st, "station", {"id", "scenario", "users", "topology", "delay_matrix", "pushes", "push_seed", "allow_routed_peers", "run_subdir", "nodes", "duration_s", "seed", "period_min_s", "period_max_s", "delay_correlation", "push_start_s", "push_end_s", "release_s",
                            "start_clock", "start_at", "start_delay_s", "start_align_s", "probe_s", "setup_gap_s", "damping_margin", "consensus_passivity", "pspm_reservoir_J",
                            "loss_allowance_ticks", "loss_allowance_max_ticks", "solver", "tx_deadband_mm", "tx_max_interval_ticks", "tx_predict", "agreement_ticks", "damping_Ns_per_m", "io_priority",
                            "out_dir", "max_no_neighbour_fraction", "max_missed_cycles", "trace_every", "state_every", "clock_offset_max_ms", "clock_offset_refuse", "clock_offset_limit_ms",
                            "rejoin_probe_s", "record", "record_max_mb", "record_deflate", "record_ring_s", "view_port", "view_bind", "view_rate_hz", "age_slack_ticks", "edge_energy_bound_J", "edge_energy_leak_W",
                            "divergence_speed_m_per_s"});
  StationSection& s = f.station;
  if (!st["id"]) bad("station.id", "present: this station's user number, 1..users");
  s.id = static_cast<int>(integer(st["id"], "station.id", 1, 1, 64));
  s.scenario = text(st["scenario"], "station.scenario", s.scenario);
  s.users = static_cast<int>(integer(st["users"], "station.users", 0, 0, 64));
  if (s.users == 1) bad("station.users", "0 (the scenario's) or a number of users in [2, 64]");
  s.topology = text(st["topology"], "station.topology", "");
  s.delay_matrix = text(st["delay_matrix"], "station.delay_matrix", "");
  s.pushes = text(st["pushes"], "station.pushes", "spread");
  if (s.pushes != "spread" && s.pushes != "asymmetric") bad("station.pushes", "\"spread\" or \"asymmetric\"");
  s.push_seed = static_cast<std::uint64_t>(integer(st["push_seed"], "station.push_seed", 1, 0, 1ll << 40));
  s.allow_routed_peers = boolean(st["allow_routed_peers"], "station.allow_routed_peers", false);
  s.run_subdir = boolean(st["run_subdir"], "station.run_subdir", false);
  s.nodes = static_cast<int>(integer(st["nodes"], "station.nodes", 33, 4, 5000));
  s.duration_s = real(st["duration_s"], "station.duration_s", 0.0, 0.0, 3600.0, " (0 = the scenario's)");
  s.seed = static_cast<std::uint64_t>(integer(st["seed"], "station.seed", 1, 0, 1ll << 40));
  s.delay_correlation = real(st["delay_correlation"], "station.delay_correlation", 0.0, 0.0, 0.999999);
  s.period_min_s = real(st["period_min_s"], "station.period_min_s", 0.0, 0.0, 0.05, " (0 = the period)");
  s.period_max_s = real(st["period_max_s"], "station.period_max_s", 0.0, 0.0, 0.1, " (0 = the period)");
  s.push_start_s = real(st["push_start_s"], "station.push_start_s", -1, -1, 3600, " (-1 = the scenario's)");
  s.push_end_s = real(st["push_end_s"], "station.push_end_s", -1, -1, 3600, " (-1 = the scenario's)");
  s.release_s = real(st["release_s"], "station.release_s", -1, -1, 3600, " (-1 = the scenario's)");
  s.start_clock = text(st["start_clock"], "station.start_clock", "monotonic");
  if (s.start_clock != "monotonic" && s.start_clock != "realtime") bad("station.start_clock", "\"monotonic\" or \"realtime\"");
  s.start_at = real(st["start_at"], "station.start_at", 0.0, 0.0, 1e12, " (0 = now + start_delay_s)");
  s.start_delay_s = real(st["start_delay_s"], "station.start_delay_s", 2.0, 0.1, 600);
  s.start_align_s = real(st["start_align_s"], "station.start_align_s", 0.0, 0.0, 3600);
  s.probe_s = real(st["probe_s"], "station.probe_s", 1.5, 0.2, 60);
  s.setup_gap_s = real(st["setup_gap_s"], "station.setup_gap_s", 0.5, 0.05, 10);
  s.damping_margin = real(st["damping_margin"], "station.damping_margin", 0.05, 0, 10);
  s.consensus_passivity = text(st["consensus_passivity"], "station.consensus_passivity", "eq18");
  rt::parse_consensus_passivity(s.consensus_passivity, "station.consensus_passivity");  // named error at parse time
  s.pspm_reservoir_J = real(st["pspm_reservoir_J"], "station.pspm_reservoir_J", 0.001, 0, 1);
  s.loss_allowance_ticks = static_cast<int>(integer(st["loss_allowance_ticks"], "station.loss_allowance_ticks", -1, -1, 1000));
  s.loss_allowance_max_ticks = static_cast<int>(integer(st["loss_allowance_max_ticks"], "station.loss_allowance_max_ticks", 16, 0, 1000));
  s.edge_energy_bound_J = real(st["edge_energy_bound_J"], "station.edge_energy_bound_J", rt::kDefaultEdgeEnergyBoundJ, 0.0, 1e6, " (0 = off)");
  s.edge_energy_leak_W = real(st["edge_energy_leak_W"], "station.edge_energy_leak_W", rt::kDefaultEdgeEnergyLeakW, 0.0, 1.0, " (0 = no leak)");
  s.solver = text(st["solver"], "station.solver", "auto");
  if (s.solver != "auto" && s.solver != "auto-fixed" && s.solver != "direct" && s.solver != "iterative")
    bad("station.solver", "\"auto\", \"auto-fixed\", \"direct\" or \"iterative\"");
  s.tx_deadband_mm = real(st["tx_deadband_mm"], "station.tx_deadband_mm", 0.0, 0.0, 99.999);
  s.tx_max_interval_ticks = static_cast<int>(integer(st["tx_max_interval_ticks"], "station.tx_max_interval_ticks", 1, 1, 1000));
  if (st["tx_max_interval_ticks"] && s.tx_deadband_mm == 0)  // like sim's --tx-max-interval: nothing to hold without a band
    bad("station.tx_max_interval_ticks", "left out unless station.tx_deadband_mm > 0 (without a band every state is sent)");
  s.tx_predict = boolean(st["tx_predict"], "station.tx_predict", false);
  if (s.tx_predict && s.consensus_passivity != "pspm")
    bad("station.tx_predict", "false unless station.consensus_passivity = \"pspm\" (eq. 18 does not cover extrapolated neighbour data)");
  s.agreement_ticks = static_cast<int>(integer(st["agreement_ticks"], "station.agreement_ticks", 2, 0, 1000));
  s.damping_Ns_per_m = real(st["damping_Ns_per_m"], "station.damping_Ns_per_m", -1, -1, 1e6, " (-1 = from the measured bound)");
  if (s.damping_Ns_per_m < 0 && s.damping_Ns_per_m != -1) bad("station.damping_Ns_per_m", "-1 or a number in [0, 1e6]");
  s.io_priority = static_cast<int>(integer(st["io_priority"], "station.io_priority", 70, 0, 98));
  s.out_dir = text(st["out_dir"], "station.out_dir", ".");
  if (s.out_dir.empty()) bad("station.out_dir", "a non-empty directory path");
  s.max_no_neighbour_fraction = real(st["max_no_neighbour_fraction"], "station.max_no_neighbour_fraction", 0.1, 0.0, 1.0);
  s.max_missed_cycles = integer(st["max_missed_cycles"], "station.max_missed_cycles", 500, 0, 1000000000);
  s.divergence_speed_m_per_s = real(st["divergence_speed_m_per_s"], "station.divergence_speed_m_per_s", 50.0, 1e-6, 1e3);
  s.trace_every = static_cast<int>(integer(st["trace_every"], "station.trace_every", 1, 1, 100000));
  s.state_every = static_cast<int>(integer(st["state_every"], "station.state_every", 5, 1, 100000));
  s.clock_offset_max_ms = real(st["clock_offset_max_ms"], "station.clock_offset_max_ms", 20.0, 0.0, 1e6);
  s.clock_offset_refuse = boolean(st["clock_offset_refuse"], "station.clock_offset_refuse", false);
  s.clock_offset_limit_ms = real(st["clock_offset_limit_ms"], "station.clock_offset_limit_ms", 1000.0, 0.0, 10000.0);
  s.rejoin_probe_s = real(st["rejoin_probe_s"], "station.rejoin_probe_s", 0.4, 0.1, 10);
  s.age_slack_ticks = static_cast<int>(integer(st["age_slack_ticks"], "station.age_slack_ticks", 10, 0, 100000));
}

// An array of three numbers in [lo, hi] (absent: out unchanged).
void vec3(View n, const std::string& key, double lo, double hi, double out[3]) {
  if (!n) return;
  if (!n.is_array() || n.as_array()->size() != 3) bad(key, "an array of three numbers, e.g. [0.0, 0.0, 0.0]");
  for (std::size_t i = 0; i < 3; ++i) out[i] = real(n[i], key + "[" + std::to_string(i) + "]", 0, lo, hi);
}

void parse_scene_section(View root, StationFile& f) {
  const View sc = root["scene"];
  only_keys(sc, "scene", {"file", "unit_m", "density_kg_per_m3", "youngs_modulus_Pa", "max_elements"});
  SceneSection& s = f.scene;
  s.file = text(sc["file"], "scene.file", "");
  s.unit_m = real(sc["unit_m"], "scene.unit_m", 1.0, 1e-12, 1e3);
  s.density_kg_per_m3 = real(sc["density_kg_per_m3"], "scene.density_kg_per_m3", 0.0, 0.0, 1e6, " (0 = the paper ball's)");
  s.youngs_modulus_Pa = real(sc["youngs_modulus_Pa"], "scene.youngs_modulus_Pa", 0.0, 0.0, 1e12, " (0 = the paper ball's)");
  s.max_elements = static_cast<int>(integer(sc["max_elements"], "scene.max_elements", 200000, 4, 1000000));
  if (sc && s.file.empty()) bad("scene.file", "a mesh file (.msh, .node, .ele, .vtk, .obj, .stl, .off) when [scene] is present");
  if (!s.file.empty() && root["station"]["nodes"]) bad("station.nodes", "absent when scene.file is set (the mesh file gives the nodes)");
}

void parse_device_section(View root, StationFile& f) {
  const View dv = root["device"];
  only_keys(dv, "device", {"kind", "hd_library_path", "hd_device_name", "hidraw_path", "usb_serial", "falcon_firmware_path", "falcon_index",
                          "falcon_homing_timeout_s", "max_force_N", "max_power_W", "max_speed_m_per_s", "max_stale_reads",
                          "max_reads_before_first_sample", "workspace_margin", "sim_max_force_N", "damping_Ns_per_m", "coupling_stiffness_N_per_m",
                          "coupling_damping_Ns_per_m", "proxy_damping_Ns_per_m", "map_offset_m", "map_rotation_deg", "map_scale",
                          "ramp_in_s"});
  DeviceSection& d = f.device;
  d.kind = text(dv["kind"], "device.kind", "auto");
  if (d.kind != "auto" && d.kind != "touch" && d.kind != "falcon" && d.kind != "spacemouse" && d.kind != "simulated")
    bad("device.kind", "\"auto\", \"touch\", \"falcon\", \"spacemouse\" or \"simulated\"");
  d.hd_library_path = text(dv["hd_library_path"], "device.hd_library_path", "");
  d.hd_device_name = text(dv["hd_device_name"], "device.hd_device_name", "");
  d.hidraw_path = text(dv["hidraw_path"], "device.hidraw_path", "");
  d.usb_serial = text(dv["usb_serial"], "device.usb_serial", "");
  d.falcon_firmware_path = text(dv["falcon_firmware_path"], "device.falcon_firmware_path", "");
  d.falcon_index = static_cast<int>(integer(dv["falcon_index"], "device.falcon_index", 0, 0, 15));
  d.falcon_homing_timeout_s = real(dv["falcon_homing_timeout_s"], "device.falcon_homing_timeout_s", 30.0, 1e-3, 600);
  if (d.kind == "falcon" && d.falcon_firmware_path.empty())
    bad("device.falcon_firmware_path", "the Novint firmware file (loaded at every start; not shipped) when device.kind = \"falcon\"");
  d.max_force_N = real(dv["max_force_N"], "device.max_force_N", 1e9, 1e-6, 1e12);
  d.max_stale_reads = static_cast<int>(integer(dv["max_stale_reads"], "device.max_stale_reads", 5, 1, 100000));
  d.max_reads_before_first_sample =
      static_cast<int>(integer(dv["max_reads_before_first_sample"], "device.max_reads_before_first_sample", 500, 1, 10000000));
  d.workspace_margin = real(dv["workspace_margin"], "device.workspace_margin", 1.5, 1, 100);
  d.max_power_W = real(dv["max_power_W"], "device.max_power_W", 3.0, 0, 1000);
  d.max_speed_m_per_s = real(dv["max_speed_m_per_s"], "device.max_speed_m_per_s", 3.0, 1e-6, 1000);
  d.sim_max_force_N = real(dv["sim_max_force_N"], "device.sim_max_force_N", 3.3, 1e-6, 1000);
  // -1 = from the device / the scenario; anything else must be in range
  auto gain = [&](const char* k, bool zero_ok, double hi, const char* range) {
    const std::string key = std::string("device.") + k;
    const double v = real(dv[k], key, -1, -1, hi, " (-1 = from the device or the scenario)");
    if (v != -1 && !(v > 0 || (zero_ok && v == 0))) bad(key, std::string("-1 or a number in ") + range);
    return v;
  };
  d.damping_Ns_per_m = gain("damping_Ns_per_m", true, 1000, "[0, 1000]");
  d.coupling_stiffness_N_per_m = gain("coupling_stiffness_N_per_m", false, 1e6, "(0, 1e6]");
  d.coupling_damping_Ns_per_m = gain("coupling_damping_Ns_per_m", true, 1e4, "[0, 1e4]");
  d.proxy_damping_Ns_per_m = gain("proxy_damping_Ns_per_m", true, 1e4, "[0, 1e4]");
  vec3(dv["map_offset_m"], "device.map_offset_m", -100, 100, d.map_offset_m);
  vec3(dv["map_rotation_deg"], "device.map_rotation_deg", -360, 360, d.map_rotation_deg);
  d.map_scale = real(dv["map_scale"], "device.map_scale", 1.0, 1e-3, 100);
  d.ramp_in_s = real(dv["ramp_in_s"], "device.ramp_in_s", -1, -1, 60, " (-1 = 1 s for a real device, 0 for a simulated user)");
  if (d.ramp_in_s < 0 && d.ramp_in_s != -1) bad("device.ramp_in_s", "-1 or a number in [0, 60]");
}

void parse_platform_sections(View root, StationFile& f) {
  // [rt]
  const View rtv = root["rt"];
  only_keys(rtv, "rt", {"priority", "cpu", "lock_memory", "hold_dma_latency", "require_rt", "isolate_cpu"});
  f.rt.priority = static_cast<int>(integer(rtv["priority"], "rt.priority", 80, 1, 98));
  f.rt.cpu = static_cast<int>(integer(rtv["cpu"], "rt.cpu", -1, -1, 4095));
  f.rt.lock_memory = boolean(rtv["lock_memory"], "rt.lock_memory", true);
  f.rt.hold_dma_latency = boolean(rtv["hold_dma_latency"], "rt.hold_dma_latency", false);
  f.rt.require_rt = boolean(rtv["require_rt"], "rt.require_rt", false);
  f.rt.isolate_cpu = boolean(rtv["isolate_cpu"], "rt.isolate_cpu", true);
  platform::validate(f.rt);

  // [loop]
  const View lp = root["loop"];
  only_keys(lp, "loop", {"period_ns", "overrun_storm_count", "report_interval_ns"});
  f.loop.period_ns = integer(lp["period_ns"], "loop.period_ns", 2'000'000, 10'000, 1'000'000'000);
  f.loop.overrun_storm_count = static_cast<std::uint32_t>(integer(lp["overrun_storm_count"], "loop.overrun_storm_count", 10, 1, 1'000'000));
  f.loop.report_interval_ns = integer(lp["report_interval_ns"], "loop.report_interval_ns", 1'000'000'000, 1'000'000'000, 3'600'000'000'000);
  platform::validate(f.loop);

  // [gpio]
  const View gp = root["gpio"];
  only_keys(gp, "gpio", {"enabled", "chip", "tick_line", "packet_line", "consumer"});
  f.gpio.enabled = boolean(gp["enabled"], "gpio.enabled", false);
  f.gpio.chip = text(gp["chip"], "gpio.chip", "");
  f.gpio.tick_line = static_cast<int>(integer(gp["tick_line"], "gpio.tick_line", -1, -1, 65535));
  f.gpio.packet_line = static_cast<int>(integer(gp["packet_line"], "gpio.packet_line", -1, -1, 65535));
  f.gpio.consumer = text(gp["consumer"], "gpio.consumer", "haptic-station");

  // [telemetry]
  const View tm = root["telemetry"];
  only_keys(tm, "telemetry", {"path", "postmortem_dir", "postmortem_s", "max_dumps"});
  f.telemetry.path = text(tm["path"], "telemetry.path", "");
  f.telemetry.postmortem_dir = text(tm["postmortem_dir"], "telemetry.postmortem_dir", ".");
  f.telemetry.postmortem_s = real(tm["postmortem_s"], "telemetry.postmortem_s", 5.0, 0.1, 600);
  f.telemetry.max_dumps = static_cast<std::uint32_t>(integer(tm["max_dumps"], "telemetry.max_dumps", 8, 1, 100000));
}

void parse_net_keys(const toml::table& cd, View root, StationFile& f) {
  const std::string P = cd.contains("network") ? "network" : "net";
  const View nt = root[P];
  f.net_section = P;
  if (!nt) bad("[net]", "present (transport, addresses, key_file, peers: see net/config.hpp)");
  only_keys(nt, P, {"station_id", "transport", "bind", "listen", "interface", "session_id", "session_key", "shared_session_key", "key_file", "encoding",
                    "max_datagram_bytes", "io_busy_poll", "io_cpu", "tx_spin", "tx_spin_lead_us", "tx_spin_tail_us", "delay_queue_datagrams", "rtt_margin_fraction", "rtt_margin_s",
                    "rtt_min_probe_samples", "impairment", "peers", "listen_any", "max_sequence_ahead_ticks", "rx_rate_limit_per_s",
                    "envelope_radii", "demo_keys"});
  only_keys(nt["impairment"], P + ".impairment", {"preset", "seed", "trace_file", "blackout_start_s", "blackout_length_s"});
  f.net_station_id_set = static_cast<bool>(nt["station_id"]);
  f.impairment_seed_set = static_cast<bool>(nt["impairment"]["seed"]);
  f.impairment_preset = text(nt["impairment"]["preset"], P + ".impairment.preset", "none");
  if (nt["peers"] && nt["peers"].is_array()) {
    std::size_t i = 0;
    for (const auto& node : *nt["peers"].as_array()) {
      const std::string k = P + ".peers[" + std::to_string(i++) + "]";
      if (!node.is_table()) bad(k, "a table");
      const View p{node};
      only_keys(p, k, {"id", "station", "address", "mac", "mean_delay_ms", "public_key"});
      const View idv = p["id"] ? p["id"] : p["station"];
      f.peer_id_keys.push_back(p["id"] || !p["station"] ? "id" : "station");
      const int id = static_cast<int>(integer(idv, k + ".id", -1, 0, 65534));
      f.peer_mean_delay_set.emplace_back(id, static_cast<bool>(p["mean_delay_ms"]));
    }
  }
  if (f.net_station_id_set && integer(nt["station_id"], P + ".station_id", 0, 0, 65534) != f.station.id)
    bad(P + ".station_id", "absent or equal to station.id (" + std::to_string(f.station.id) + "): wire ids are the user numbers");
}

// station.record* (the session log, firmware/session/recorder.hpp) and station.view* (the live web view).
void parse_record_view_keys(View st, StationFile& f) {
  f.record.enabled = boolean(st["record"], "station.record", false);
  f.record.max_mb = real(st["record_max_mb"], "station.record_max_mb", 1024.0, 1.0, 1e6);
  f.record.deflate = static_cast<int>(integer(st["record_deflate"], "station.record_deflate", 0, 0, 9));
  f.record.ring_s = real(st["record_ring_s"], "station.record_ring_s", 0.0, 0.0, 86400.0);
  f.view.port = static_cast<int>(integer(st["view_port"], "station.view_port", 0, 0, 65535));
  f.view.bind = text(st["view_bind"], "station.view_bind", "127.0.0.1");
  in_addr bind_addr{};
  if (inet_pton(AF_INET, f.view.bind.c_str(), &bind_addr) != 1)
    bad("station.view_bind", "an IPv4 address of this machine, e.g. \"127.0.0.1\" (the default) or \"0.0.0.0\"");
  f.view.rate_hz = real(st["view_rate_hz"], "station.view_rate_hz", 30.0, 1.0, 60.0);
}

}  // namespace

StationFile parse_station_file(std::string_view toml_text) {
  const toml::table doc = platform::config::parse_document(toml_text);
  const toml::table& cd = doc;
  const View root{cd};
  only_keys(root, "", {"station", "scene", "device", "rt", "loop", "gpio", "telemetry", "trace", "net", "network"});
  if (cd.contains("net") && cd.contains("network")) bad("[network]", "absent when [net] is present (one network section)");

  StationFile f;
  f.text = std::string(toml_text);

  parse_station_section(root, f);
  parse_scene_section(root, f);
  parse_device_section(root, f);
  parse_platform_sections(root, f);
  parse_record_view_keys(root["station"], f);
  only_keys(root["trace"], "trace", {});
  // [net] / [network]: only key names here; values are net/'s (net/config.hpp).
  parse_net_keys(cd, root, f);
  return f;
}

std::string StationFile::peer_key(std::size_t index, const std::string& field) const {
  const std::string f = field == "id" && index < peer_id_keys.size() ? peer_id_keys[index] : field;
  return net_section + ".peers[" + std::to_string(index) + "]." + f;
}

std::string StationFile::relative_to_file(const std::string& value) const {
  return platform::config::path_beside(value, path);
}

StationFile load_station_file(const std::string& path) {
  StationFile f = parse_station_file(platform::config::read_file(path));
  f.path = path;
  return f;
}

}  // namespace haptic::firmware
