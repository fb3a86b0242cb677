#pragma once
// The station file of `haptic-station run --config FILE.toml` (toml++). Start-up only (not
// RT-safe). Sections [station], [scene], [device], [rt], [loop], [gpio], [telemetry], [trace] (no
// keys: LTTng-UST events are recorded while a session is active) and [net] or [network] (net/).
// Every key, its type, range, default and meaning is declared once in firmware/station/options.cpp
// (net/options.cpp for [net]) and listed in firmware/station/OPTIONS.md, generated from those
// declarations. A bad value or an unknown key throws std::invalid_argument naming the key as
// written and the accepted values.
#include <cstdint>
#include <string>
#include <string_view>

#include "drivers/device_factory.hpp"
#include "firmware/station/options.hpp"
#include "net/config.hpp"
#include "platform/gpio.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/rt_thread.hpp"
#include "platform/telemetry.hpp"
#include "rt/edge_energy.hpp"
#include "rt/edge_monitor.hpp"

namespace haptic::firmware {

struct StationSection {
  int id = 1;
  std::string scenario = "paper-best";
  int users = 0;
  std::string topology;
  std::string delay_matrix;
  std::string pushes = "spread";
  std::uint64_t push_seed = 1;
  std::string script;  // "" = the scenario's users' script
  bool allow_routed_peers = false;
  bool run_subdir = false;
  int nodes = 33;
  double duration_s = 0.0;
  std::uint64_t seed = 1;
  double period_min_s = 0, period_max_s = 0;  // bounds of the measured step T_k (0: measured while probing)
  double step_margin_max = 0.2;               // measured bounds: at most this fraction of the period either side
  double delay_correlation = 0;               // the emulated delay's AR(1) coefficient (net::LinkImpairment)
  double push_start_s = -1, push_end_s = -1, release_s = -1;
  std::string start_clock = "monotonic";
  double start_at = 0.0;
  double start_delay_s = 2.0;
  double start_align_s = 0.0;
  double probe_s = 1.5;
  double setup_gap_s = 0.5;
  double damping_margin = 0.05;
  std::string consensus_passivity = "eq18";
  std::string receive_rule = "newest";
  double pspm_reservoir_J = 0.001;
  int resilient_f = 0;  // rt/resilient.hpp: neighbours left out per tick (0: off)
  int loss_allowance_ticks = -1;      // -1: from the probe's measured loss
  int loss_allowance_max_ticks = 16;  // the paper links measure 8-12 (tools/run4); a loaded machine far more
  double edge_energy_bound_J = rt::kDefaultEdgeEnergyBoundJ;
  double edge_energy_leak_W = rt::kDefaultEdgeEnergyLeakW;
  double edge_energy_hold_s = rt::kDefaultEdgeEnergyHoldS;
  // The neighbour state check (rt/edge_monitor.hpp); 0 m = that check off.
  double state_check_kinematic_m = rt::kDefaultStateCheckKinematicM;
  double state_check_kinematic_window_s = 30.0;
  double state_check_disagreement_m = rt::kDefaultStateCheckDisagreementM;
  double state_check_disagreement_window_s = 0.2;
  double state_check_readmit_s = 2.0;
  int state_check_max_gap_ticks = 4;
  int state_check_max_checked_gap_ticks = 32;
  std::string solver = "auto";
  double tx_deadband_mm = 0;
  int tx_max_interval_ticks = 1;
  bool tx_predict = false;
  int agreement_ticks = 2;
  double damping_Ns_per_m = -1.0;
  int io_priority = 70;
  std::string out_dir = ".";
  double max_no_neighbour_fraction = 0.1;
  std::int64_t max_missed_cycles = 500;  // 1 s of periods at 2 ms (exit 11 above it)
  double divergence_speed_m_per_s = 50;
  int trace_every = 1;
  int state_every = 5;
  double clock_offset_max_ms = 20.0;
  bool clock_offset_refuse = false;
  double clock_offset_limit_ms = 1000.0;  // the grid offset used (sequences mapped) up to this; refused beyond
  double rejoin_probe_s = 0.4;
  double return_ramp_s = 2.0;
  double drop_fade_s = 0.5;
  int age_slack_ticks = 10;
};

struct SceneSection {
  std::string file;  // as written; resolved against the station file's folder by the plan
  double unit_m = 1.0;
  double density_kg_per_m3 = 0;
  double youngs_modulus_Pa = 0;
  int max_elements = 200000;
};

struct DeviceSection {
  std::string kind = "auto";
  std::string hd_library_path;
  std::string hd_device_name;
  std::string hidraw_path;
  std::string usb_serial;
  std::string falcon_firmware_path;
  int falcon_index = 0;
  double falcon_homing_timeout_s = 30.0;
  double max_force_N = 1e9;
  double max_power_W = 3.0;
  double max_speed_m_per_s = 3.0;
  int max_stale_reads = 5;
  int max_reads_before_first_sample = 500;
  double workspace_margin = 1.5;
  double damping_Ns_per_m = -1;
  double coupling_stiffness_N_per_m = -1;
  double coupling_damping_Ns_per_m = -1;
  double proxy_damping_Ns_per_m = -1;
  double map_offset_m[3] = {0, 0, 0};
  double map_rotation_deg[3] = {0, 0, 0};
  double map_scale = 1.0;
  double ramp_in_s = -1;
  double sim_max_force_N = 3.3;
};

struct RecordSection {
  bool enabled = false;
  double max_mb = 1024.0;
  int deflate = 0;
  double ring_s = 0;
};

struct ViewSection {
  int port = 0;
  std::string bind = "127.0.0.1";
  double rate_hz = 30.0;
};

struct StationFile {
  std::string path;           // where it came from ("" for text)
  std::string text;           // the whole TOML text (net/ parses its section from it)
  StationSection station;
  SceneSection scene;
  DeviceSection device;
  platform::RtConfig rt{};
  platform::LoopConfig loop{};
  platform::GpioConfig gpio{};
  platform::TelemetryConfig telemetry{};
  RecordSection record{};
  ViewSection view{};
  // [net]/[network] facts the station needs before net/ parses the section.
  bool net_station_id_set = false;
  bool impairment_seed_set = false;
  std::string impairment_preset = "none";
  std::vector<std::pair<int, bool>> peer_mean_delay_set;  // (peer wire id, mean_delay_ms given)
  // How the network keys are written in the file, for error messages: "net" or "network", and
  // per peer "id" or "station" ("net.peers[2].id", "network.peers[0].station").
  std::string net_section = "net";
  std::vector<std::string> peer_id_keys;
  // Hash of the options declared same-on-all-stations (options.hpp), part of the plan fingerprint.
  std::uint64_t shared_options_hash = 0;
  // Key of peer `index`'s field `field` as written in the file, e.g. "net.peers[2].address".
  std::string peer_key(std::size_t index, const std::string& field) const;
  // A file named by a key of this file: relative to this file's folder (as net.key_file and
  // scene.file), absolute or from text (path "") as written.
  std::string relative_to_file(const std::string& value) const;
};

// Parses and validates everything except the [net] section's values (net/ does those, with the
// scene size, in parse_net()). Throws std::invalid_argument naming the key and the range.
// `options`: the declarations it reads (station_options(); a test adds one to show that an option
// is one declaration).
// solo (`haptic-station solo`): [station] and [net] may be absent (a lab file's [net] is checked, not used).
StationFile parse_station_file(std::string_view toml_text, const std::vector<StationOption>& options = station_options(), bool solo = false);
// overrides: KEY=VALUE pairs from the command line (with_overrides, options.hpp), applied to the text.
// path "" (solo only): no file, the defaults and the overrides.
StationFile load_station_file(const std::string& path, const std::vector<std::pair<std::string, std::string>>& overrides = {}, bool solo = false);

}  // namespace haptic::firmware
