#pragma once
// plan: the first phase of `haptic-station run` (DESIGN.md, "The station process"). Pure: the
// station file (+ command-line overrides, + one reading of the clocks) -> scenario and gains,
// common epoch and phase lengths, peer table, link settings, device selection, the scene
// fingerprint the station exchanges with its neighbours, output paths and record sizes. It opens
// no socket, starts no thread and creates no file; `run --check-config` is exactly this phase,
// so every configuration error `run` can report is reported here (exit 2), naming the key as it
// is written in the file. Nothing here is RT-safe.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/device_factory.hpp"
#include "firmware/station/device_coupling.hpp"
#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/timeline.hpp"
#include "net/config.hpp"

namespace haptic::firmware {

struct RunOverrides {
  double start_at = -1;      // --start-at (s on station.start_clock), < 0: from the file
  std::string out_dir;       // --out, "": from the file
  double duration_s = -1;    // --duration, < 0: from the file
  bool quiet = false;
  // haptic-station solo: one user, no network (no [net], no probing, no neighbour): the scenario
  // becomes make_solo's, station.id is 1 and the run starts as soon as the core is built.
  bool solo = false;
  double solo_anchor_N_per_m = 0;  // solo: ground springs on every node (make_solo), 0 = floating
  bool probe_only = false;   // --probe-only: plan, probe the neighbours (round trips, loss, clock offsets,
                             // fingerprints), report and stop; no coupling, no run (haptic-lab check)
  // For in-process tests only, never set by the command line: called on the RT thread before each
  // run tick with its run index (a test simulates a host stall by sleeping in it). Empty: not called.
  std::function<void(std::int64_t kr)> test_tick_hook;
};

// Applies the file's [station] keys to the scenario (throws std::invalid_argument naming the key).
ScenarioSpec station_scenario_spec(const StationFile& file, const RunOverrides& overrides);

// What two stations must agree on before they couple: net/'s fingerprint message (sent during
// probing; net::fingerprint_difference names each field that differs). Two stations with equal
// fingerprints run the same scene, period, gains, coupling law (station.consensus_passivity,
// station.tx_predict, the transmission deadband) and wire protocol.
using SceneFingerprint = net::Fingerprint;
SceneFingerprint scene_fingerprint(const BuiltScenario& built, std::int64_t period_ns);
// The fingerprint a station sends: the scene's, with the hash of the station file's options declared
// same-on-all-stations (StationFile::shared_options_hash, options.hpp) folded into gains_hash.
SceneFingerprint station_fingerprint(const BuiltScenario& built, const StationFile& f);
// The fingerprint in words, for session logs (station and simulator alike). Not RT-safe.
std::string fingerprint_text(const SceneFingerprint& f);

// Both clocks read once, so that the plan is a pure function of its inputs.
struct ClockReading {
  std::int64_t monotonic_ns = 0;
  std::int64_t realtime_ns = 0;
};
ClockReading read_clocks();

// The phases on the common tick index k (k = 0 at the epoch, the same on every station).
// The timeline (firmware/station/timeline.hpp: epoch, period, phase lengths, the time-to-tick rule)
// and what planning found out about it.
struct StationTimes : Timeline {
  double epoch_in_s = 0;         // epoch - now at planning
  // Started after the first half of its probing phase: the session is running, so the station
  // rejoins it (station/rejoin.hpp: learns the epoch from its neighbours, adopts a neighbour's
  // object state, then couples) instead of probing from k = 0.
  bool rejoin = false;
};

// Which configured peer is which neighbour of the scenario's topology.
struct PeerTable {
  std::vector<int> peer_to_nbr;    // net.peers index -> neighbour index
  std::vector<int> nbr_to_peer;    // neighbour index -> net.peers index
  std::vector<int> sender_to_nbr;  // [65536]: wire sender id -> neighbour index, -1 = none
};

struct StationPlan {
  StationFile file;
  RunOverrides overrides;
  std::shared_ptr<const BuiltScenario> built;  // shared: the core keeps pointers into it
  int station_id = 1;
  int me = 0;                       // 0-based user index
  const std::vector<int>& neighbours() const { return built->neighbors[static_cast<std::size_t>(me)]; }
  net::NetConfig net;               // link settings: impairment and seeds applied, tick period set
  PeerTable peers;
  StationTimes times;
  drivers::DeviceSelection device;  // what to open (the simulated user plays user `me`'s script)
  // b_d, gains and force limit from the figures the device kind publishes, eq. (26) checked; unset
  // for device.kind = "auto" (checked at start-up once the device is open)
  std::optional<DeviceCoupling> coupling;
  std::int64_t ramp_in_ticks = 0;   // device.ramp_in_s in ticks: the device force ramps in over these
  SceneFingerprint fingerprint;
  std::string out_dir;              // created by the run, checked creatable here
  std::string base_path;            // out_dir/station-<id>
  // The record windows (station/records.hpp), rows of kRecordWindowS each: independent of the
  // planned duration (the rows stream to the CSV files during the run).
  std::size_t trace_capacity = 0;   // trace rows
  std::size_t state_capacity = 0;   // state rows (x dofs values each)
  // The bytes the record windows hold (TickRecords::window_bytes of the two capacities).
  std::size_t record_window_bytes() const;
  bool ends_before_release = false; // the planned run ends at or before the scripted release
  std::vector<std::string> warnings;
  // station.clock_offset_limit_ms in whole ticks (rounded up): how far a neighbour's tick grid may
  // run ahead of ours and still be used (station/neighbours.hpp ClockCheck).
  std::int64_t clock_offset_limit_ticks() const;
  // The endpoint's configuration: net's, with its sequence ceiling (net.max_sequence_ahead_ticks)
  // widened by clock_offset_limit_ticks(), so probing measures a grid offset up to the limit.
  net::EndpointConfig endpoint_config() const;
};

struct PlanResult {
  PhaseStatus status = PhaseStatus::kConfigError;
  std::string error;                  // configuration error, naming the key as written
  std::unique_ptr<StationPlan> plan;  // set when status == kOk
};

// The plan phase. Never throws: every error becomes kConfigError with its message.
PlanResult plan_station(const StationFile& file, const RunOverrides& overrides, const ClockReading& now);

// Ticks the session log's ring keeps (station.record_ring_s / T, at least 1), 0 = the whole run. Pure.
std::uint64_t record_ring_ticks(const StationPlan& p);

// Seconds of trace and state rows the record windows hold: how long the writer thread may fall
// behind the tick before rows are lost (counted and reported).
inline constexpr double kRecordWindowS = 8.0;

// The individual checks (each throws std::invalid_argument naming the key; exposed for tests).
PeerTable plan_peer_table(const StationFile& file, const BuiltScenario& built, int me, const net::NetConfig& net);
// The payload envelope of net/ (net.envelope_radii object radii around the rest shape, the core's
// divergence speed). Not RT-safe.
void set_payload_envelope(const BuiltScenario& b, net::NetConfig& nc);
void check_address_families(const StationFile& file, const net::NetConfig& net);
// Network safety: a UDP peer must be on loopback or on a network one of this machine's interfaces
// is on (its address and netmask), unless station.allow_routed_peers = true (stations across
// routers, the Internet). A lab file's private-range addresses on a machine outside that lab
// would otherwise send packets out of its default route. Throws naming the peer's key and listing
// this machine's interface addresses. Not RT-safe (getifaddrs).
void check_peer_networks(const StationFile& file, const net::NetConfig& net);
// A UDP station binds an address of this machine: net.bind's address must be one of its interfaces'
// addresses (any 127.x.y.z, which Linux's loopback owns, and the wildcard, which net.listen_any
// governs, pass). Throws naming the key as written and listing this machine's addresses. Not RT-safe (getifaddrs).
void check_bind_address(const StationFile& file, const net::NetConfig& net);
void check_io_cpu(const StationFile& file, const net::NetConfig& net);
void check_tx_spin(const StationFile& file, const net::NetConfig& net);
void check_out_dir_creatable(const std::string& dir, const std::string& key);
StationTimes plan_times(const StationFile& file, const RunOverrides& overrides, const ScenarioSpec& spec, const ClockReading& now);

}  // namespace haptic::firmware
