#pragma once
// The station file of `haptic-station run --config FILE.toml` (toml++). Start-up only (not
// RT-safe). Every key has a documented default; a bad value or an unknown key throws
// std::invalid_argument naming the key and the allowed range.
//
//   [station]                        (firmware/)
//   id = 1                           # this station's user number, 1..users of the scenario (required)
//   scenario = "paper-best"          # built-in scene, gains, topology, delays, user scripts
//   users = 0                        # number of users 2..64; 0 = the scenario's (4). Other N: uniform 10 ms
//                                    # delays and a tree of degree <= 4 unless topology / delay_matrix are given
//   topology = ""                    # "" = the scenario's; else e.g. "1-2,1-3,1-4" (same on all stations)
//   delay_matrix = ""                # mean one-way delays in ms, users x users, "0,4;8,0" (row i receives from j):
//                                    # the impairment emulator's means; "" = the scenario's (same on all stations)
//   pushes = "spread"                # user scripts' push directions: "spread" (cancel by construction) or
//                                    # "asymmetric" (tilted, unequal depths; scenario.hpp) (same on all stations)
//   push_seed = 1                    # seed of the asymmetric pushes, [0, 2^40]
//   run_subdir = false               # true: outputs go to out_dir/<UTC time>-s<session_id>/ (created), so a new run
//                                    # or a restart never overwrites an earlier one (the lab PCs' systemd units)
//   allow_routed_peers = false       # false: every UDP peer must be on loopback or on a network one of this
//                                    # machine's interfaces is on (a lab file run on the wrong machine must not
//                                    # send packets out of its default route); true: peers across routers
//   nodes = 33                       # scene size (33 = the paper's ball), 4..5000
//   duration_s = 0                   # run time from the run start, (0, 3600]; 0 = the scenario's
//   seed = 1                         # run seed: impairment link seeds as the simulator's
//   delay_correlation = 0            # impaired links: AR(1) per packet of the emulated delay, [0, 1) (sim --delay-correlation)
//   period_min_s = 0                 # bounds of the measured step T_k the core integrates with (rt/README.md
//   period_max_s = 0                 # "Variable steps"): eq. (18)'s D term and eq. (26) use them; a wake-to-wake
//                                    # period outside is clamped and counted (steps_clamped); 0 = loop.period_ns
//   push_start_s = -1                # user script times (s from the run start); -1 = scenario's
//   push_end_s = -1
//   release_s = -1
//   start_clock = "monotonic"        # clock of start_at: "monotonic" (one host) | "realtime" (NTP/PTP-synced hosts)
//   start_at = 0.0                   # common epoch (s on start_clock) of tick k = 0 (probing starts); 0 = now + start_delay_s
//   start_delay_s = 2.0              # [0.1, 600]
//   start_align_s = 0                # with start_at = 0 and > 0: the epoch is the next multiple of this on
//                                    # start_clock after now + start_delay_s (stations started independently,
//                                    # e.g. by systemd, meet on the same epoch), [0, 3600]
//   probe_s = 1.5                    # probing phase with zero coupling, [0.2, 60]
//   setup_gap_s = 0.5                # from the end of probing to the run start (StationCore built meanwhile), [0.05, 10]
//   damping_margin = 0.05            # B_i = (1 + margin) x eq. (18) of the MEASURED bounds, [0, 10]
//   consensus_passivity = "eq18"     # "eq18": B_i from eq. (18) (the paper); "pspm": passive set-position modulation
//                                    # per edge (rt/set_position_modulation.hpp): B_i = 0 unless damping_Ns_per_m,
//                                    # no delay bound, eq. (14) by construction (same on all stations)
//   pspm_reservoir_J = 0.001         # with "pspm": each edge's initial energy reservoir E0, J, [0, 1]
//   loss_allowance_ticks = -1        # ticks added to the measured round-trip bound R_ij = Nbar_ij + Nbar_ji (eq. 18),
//                                    # [-1, 1000]; -1 = from the loss measured while probing: 2 L, L the scenario's
//                                    # loss-model allowance (model::loss_allowance_from_measured_loss) for the loss
//                                    # on the incoming direction (upper 97.5 % confidence bound); each end sends its
//                                    # value with its frozen round-trip bound and both use the larger (station/probe.hpp)
//   loss_allowance_max_ticks = 16    # a measured allowance above this is capped there, with a warning naming the
//                                    # link and its loss (links[].loss_allowance_capped in station-<id>.json), [0, 1000]
//   edge_energy_bound_J = 0.1        # per-edge damage bound: an edge whose energy account (eq. 14 split per edge)
//                                    # exceeds it acts as a damper until the account fell to half of it
//                                    # (net/README.md, "Bounded damage"), [0, 1e6]; 0 = off
//   edge_energy_leak_W = 0.001       # energy that left the copy (to the user, the object's damping) is taken off
//                                    # each edge's account up to this power, so a station that only receives does
//                                    # not fill its accounts in a long session (rt/README.md), [0, 1]; 0 = no leak
//   solver = "auto"                  # linear step: "auto" (150-2400 factor rows: both ticks timed at start-up on
//                                    # this machine, the faster used, station-<id>.json "solver_choice"; outside:
//                                    # as "auto-fixed"), "auto-fixed" (direct LDL^T below 600 factor rows: nodes, or
//                                    # 3 per node when a matrix is not isotropic; Jacobi-PCG above: no timing, the
//                                    # simulator's rule), "direct" or "iterative" (rt/step_solver; "solver")
//   tx_deadband_mm = 0               # > 0: send a state only when some node moved more than this since the
//                                    # last one sent (rt/tx_deadband), [0, 100); 0 = every tick
//   tx_max_interval_ticks = 1        # with tx_deadband_mm: a state at least every this many ticks; the
//                                    # index-delay bounds grow by this - 1 (eq. 18 damping follows), [1, 1000]
//   tx_predict = false               # with consensus_passivity = "pspm": predictive deadband (rt/tx_deadband.hpp):
//                                    # the band applies to the error against the last sent state extrapolated by
//                                    # its velocity, and held neighbour states are extrapolated the same way
//                                    # (same on all stations)
//   agreement_ticks = 2              # eq. (18) uses Nbar_ij + Nbar_ji = 2 ceil(R_ij/2) + this: covers the peer's
//                                    # guard ceil(R_ji/2) while the two ends' measured R differ by <= 2x this, [0, 1000]
//   damping_Ns_per_m = -1            # >= 0: fixed B_i (experiments below eq. 18); -1: from the measurement
//   io_priority = 70                 # SCHED_FIFO priority of the endpoint's I/O thread (inherited at its start),
//                                    # 0 = leave it SCHED_OTHER; [0, 98]; falls back with a warning without privileges
//   out_dir = "."                    # per-station outputs station-<id>.json, -trace.csv, -state.csv
//   divergence_speed_m_per_s = 50    # a node of the copy faster than this: diverged, the core's safe state (zero
//                                    # force) and exit 4; also the envelope's speed bound on neighbours' packets, [1e-6, 1e3]
//   max_no_neighbour_fraction = 0.1 # the run fails (exit 7) when more than this share of its ticks had no
//                                    # neighbour within its bound (all edges dropped), [0, 1]
//   max_missed_cycles = 500          # the run ends with exit 11 when its run loop skipped more than this many periods
//                                    # in all (the host stalled the station: SIGSTOP, swap, a starved CPU); 500 = 1 s
//                                    # at 2 ms, four times net.peer_silence_s, after which the neighbours have long
//                                    # declared this station silent; a loaded 2-core test machine skips 5-104 in an
//                                    # 8-15 s four-process run (the probing loop's skips, ~190 there, are not counted), [0, 1e9]
//   trace_every = 1                  # every k-th tick into station-<id>-trace.csv, [1, 100000]
//   state_every = 5                  # every k-th tick the whole x into station-<id>-state.csv, [1, 100000]
//   clock_offset_max_ms = 20         # bound on each neighbour's tick-grid offset (its epoch in our clock minus ours,
//                                    # from NTP-style echoes, net/README.md): a larger offset, beyond the measurement's
//                                    # own uncertainty (half the round trip), is warned about, [0, 1e6]
//   clock_offset_refuse = false      # true: refuse to couple instead (exit 3) when the bound is exceeded
//   clock_offset_limit_ms = 1000     # a neighbour's tick-grid offset is used up to this (its sequence numbers mapped onto
//                                    # our grid, station/neighbours.hpp) and refused beyond it, less its uncertainty (exit 3,
//                                    # naming both stations and the offset); the I/O thread's sequence ceiling
//                                    # (net.max_sequence_ahead_ticks) is widened by it, [0, 10000]
//   record = false                   # true: the session log out_dir/station-<id>.h5 (HDF5, firmware/session/log.hpp;
//                                    # `haptic-station replay` re-runs it bit-exactly)
//   record_max_mb = 1024             # rows past this many MB are not written (the log says from which tick), [1, 1e6]
//   record_deflate = 0               # HDF5 deflate level of the recorded packet values, 0 = none, [0, 9]
//   record_ring_s = 0                # > 0: keep only the last this many seconds (a ring of fixed size in the file:
//                                    # bounded memory and disk; for inspection, not replay; not deflated; its size
//                                    # must fit record_max_mb), 0 = the whole run, [0, 86400]
//   view_port = 0                    # > 0: serve the live web view (HTTP + WebSocket) on this port, [0, 65535]
//   view_bind = "127.0.0.1"          # interface the view listens on (localhost by default; another only by configuration)
//   view_rate_hz = 30                # frames per second sent to each browser, [1, 60]
//   rejoin_probe_s = 0.4             # a station started after its epoch's probing phase rejoins the running
//                                    # session: it probes this long (round trips, the neighbours' epoch), adopts the
//                                    # session's epoch and a neighbour's object state, then couples, [0.1, 10]
//   age_slack_ticks = 10             # age guard: a run packet is used only if it echoes one of our sends and its
//                                    # echo-based age bound is <= (R_ij + this) ticks (net/README.md), [0, 100000]
//   [scene]                          (firmware/scene: a mesh file instead of the built-in ball; station.nodes then absent)
//   file = ""                        # .msh (Gmsh ASCII 2.2/4.1), .node/.ele (TetGen), .vtk (legacy ASCII), or a closed
//                                    # surface .obj/.stl/.off (tetrahedralized by TetGen); relative to this file's folder
//   unit_m = 1.0                     # metres per file unit, (0, 1e3]
//   density_kg_per_m3 = 0            # material (rt::Material); 0 = the paper ball's (1.32 kg in its volume), [0, 1e6]
//   youngs_modulus_Pa = 0            # 0 = the paper ball's (mean edge spring 100 N/m), [0, 1e12]
//   max_elements = 200000            # refuse bigger meshes (tetrahedra), [4, 1e6]
//   [device]                         (drivers/: device_factory.hpp)
//   kind = "auto"                    # "auto" (first Touch, else Falcon, else SpaceMouse) | "touch" | "falcon" | "spacemouse" | "simulated".
//                                    # A device that cannot be started is an error (exit 9), never a silent simulated
//                                    # user; "simulated" (the scenario's scripted user) is a warning and in the summary
//   hd_library_path = ""             # the vendor's OpenHaptics libHD.so; "" = $HAPTIC_HD_LIBRARY, else "libHD.so"; a bare
//                                    # name goes to the loader's search path, a path with '/' is relative to this file's folder
//   hd_device_name = ""              # OpenHaptics device configuration name; "" = the default device
//   hidraw_path = ""                 # SpaceMouse hidraw node; "" = the first SpaceMouse found
//   usb_serial = ""                  # two devices of one kind on this PC: this station's, by the serial `haptic-devices`
//                                    # lists (the Falcon opened and the device watched for unplug); "" = the only one
//                                    # (two Touches without it are refused); a Touch also needs hd_device_name
//   falcon_firmware_path = ""        # Novint Falcon: the firmware file loaded at every start (not shipped); required;
//                                    # relative to this file's folder. A missing file (or library) is a --check-config warning
//   falcon_index = 0                 # which Falcon on USB (0 = the first 0403:cb48), [0, 15]
//   falcon_homing_timeout_s = 30     # the user homes the grip (all the way out, straight in) within this, (0, 600]
//   max_force_N = 1e9                # extra output clamp below the device's own limit, > 0
//   max_power_W = 3.0                # cap on F.v into the hand, [0, 1000], 0 disables
//   max_speed_m_per_s = 3.0          # a faster sample is out of range (safe state), (0, 1000]
//   max_stale_reads = 5              # ticks without a new sample before the safe state, [1, 100000]
//   max_reads_before_first_sample = 500  # start-up grace before the first sample, [1, 10000000]
//   workspace_margin = 1.5           # |p| beyond this x the device's workspace radius is out of range, [1, 100]
//   sim_max_force_N = 3.3            # simulated device capability, (0, 1000]
//   damping_Ns_per_m = -1            # the device's damping b_d for eq. (26), [0, 1000]; -1 = the figure the device
//                                    # publishes (simulated: the model's); REQUIRED for a Touch or Falcon (none published): measured
//   coupling_stiffness_N_per_m = -1  # K_vc of the virtual coupling (Section III-C), (0, 1e6]; -1 = the scenario's (200)
//   coupling_damping_Ns_per_m = -1   # B_vc, [0, 1e4]; -1 = the scenario's (0)
//   proxy_damping_Ns_per_m = -1      # b_v, extra damping of the virtual proxy, [0, 1e4]; -1 = the scenario's (2)
//                                    # eq. (26) on these is checked by --check-config and at start-up; the force limit is
//                                    # the device's (min of its capability and max_force_N)
//   map_offset_m = [0, 0, 0]         # workspace mapping, device -> object frame: p_obj = offset + scale R p_dev,
//   map_rotation_deg = [0, 0, 0]     # R = Rz(rz) Ry(ry) Rx(rx) (degrees, about the object's fixed axes),
//   map_scale = 1.0                  # (0, 100]; forces go back as scale R^T F (same power in both frames), so eq. (26)
//                                    # uses b_d / scale^2 and the force limit is F_max / scale in the object frame.
//                                    # `haptic-devices map` finds the offset (stylus held still at the object's centre).
//                                    # Positions beyond the device's workspace radius are clamped onto it (counted).
//   ramp_in_s = -1                   # the force sent to the device ramps linearly from 0 over this time after the
//                                    # station couples, [0, 60]; -1 = 1 s for a real device, 0 for a simulated user.
//                                    # At start the virtual proxy is placed at the mapped device position (projected
//                                    # onto the contact face when that position is inside the object)
//   [rt]       priority = 80 (1..98), cpu = -1, lock_memory = true, hold_dma_latency = false, require_rt = false,
//              isolate_cpu = true (with cpu >= 0: every other thread of the process moved off that cpu)
//   [loop]     period_ns = 2000000 (must equal the scenario's T), overrun_storm_count = 10 (>= 1),
//              report_interval_ns = 1000000000 (>= 1e9)
//   [gpio]     enabled = false, chip = "", tick_line = -1, packet_line = -1, consumer = "haptic-station"
//   [telemetry] path = "" (no file), postmortem_dir = ".", postmortem_s = 5.0, max_dumps = 8
//   [trace]    (no keys: LTTng-UST events are recorded while a session is active)
//   [net] or [network]               (net/config.hpp: keys, defaults and ranges there)
#include <cstdint>
#include <string>
#include <string_view>

#include "drivers/device_factory.hpp"
#include "net/config.hpp"
#include "platform/gpio.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/rt_thread.hpp"
#include "platform/telemetry.hpp"
#include "rt/edge_energy.hpp"

namespace haptic::firmware {

struct StationSection {
  int id = 1;
  std::string scenario = "paper-best";
  int users = 0;
  std::string topology;
  std::string delay_matrix;
  std::string pushes = "spread";
  std::uint64_t push_seed = 1;
  bool allow_routed_peers = false;
  bool run_subdir = false;
  int nodes = 33;
  double duration_s = 0.0;
  std::uint64_t seed = 1;
  double period_min_s = 0, period_max_s = 0;  // bounds of the measured step T_k (0: the period)
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
  double pspm_reservoir_J = 0.001;
  int loss_allowance_ticks = -1;      // -1: from the probe's measured loss
  int loss_allowance_max_ticks = 16;  // the paper links measure 8-12 (tools/run4); a loaded machine far more
  double edge_energy_bound_J = rt::kDefaultEdgeEnergyBoundJ;
  double edge_energy_leak_W = rt::kDefaultEdgeEnergyLeakW;
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
  // Key of peer `index`'s field `field` as written in the file, e.g. "net.peers[2].address".
  std::string peer_key(std::size_t index, const std::string& field) const;
  // A file named by a key of this file: relative to this file's folder (as net.key_file and
  // scene.file), absolute or from text (path "") as written.
  std::string relative_to_file(const std::string& value) const;
};

// Parses and validates everything except the [net] section's values (net/ does those, with the
// scene size, in parse_net()). Throws std::invalid_argument naming the key and the range.
StationFile parse_station_file(std::string_view toml_text);
StationFile load_station_file(const std::string& path);

}  // namespace haptic::firmware
