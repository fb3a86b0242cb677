#include "firmware/station/options.hpp"

#include <algorithm>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "net/options.hpp"
#include "rt/edge_energy.hpp"

namespace haptic::firmware {

namespace {

using platform::config::OptionDecl;
using platform::config::OptionType;
using platform::config::OptionValue;

template <class T>
void assign(T& out, const OptionValue& v) {
  if constexpr (std::is_same_v<T, bool>) out = v.boolean;
  else if constexpr (std::is_integral_v<T>) out = static_cast<T>(v.integer);
  else if constexpr (std::is_floating_point_v<T>) out = v.real;
  else if constexpr (std::is_same_v<T, std::string>) out = v.text;
  else std::copy(std::begin(v.real3), std::end(v.real3), std::begin(out));  // double[3]
}

// The setter of field `Member` of part `Part` of the station file.
template <auto Part, auto Member>
void set_field(StationFile& f, const OptionValue& v) {
  assign((f.*Part).*Member, v);
}

#define HAPTIC_FIELD(part, member) &set_field<&StationFile::part, &decltype(StationFile::part)::member>

OptionDecl R(const char* s, const char* k, double def, double lo, double hi, const char* help) { return platform::config::real_option(s, k, def, lo, hi, help); }
OptionDecl I(const char* s, const char* k, double def, double lo, double hi, const char* help) { return platform::config::integer_option(s, k, def, lo, hi, help); }
OptionDecl B(const char* s, const char* k, bool def, const char* help) { return platform::config::boolean_option(s, k, def, help); }
OptionDecl T(const char* s, const char* k, const char* def, const char* help, const char* choices = "") {
  return platform::config::text_option(s, k, def, help, choices);
}
OptionDecl V(const char* s, const char* k, double lo, double hi, const char* help) { return platform::config::real3_option(s, k, 0, lo, hi, help); }


// [station]: the session (scenario, timing, passivity) and this station's outputs.
// A real-time station's largest built-in ball (the simulator's is kMaxSceneNodes).
constexpr int kMaxStationSceneNodes = 5000;
static_assert(kMaxStationSceneNodes <= kMaxSceneNodes);

const std::vector<StationOption> kStation = {
    {I("station", "id", 1, 1, 64, "this station's user number, 1..users of the scenario").must_be_given(), HAPTIC_FIELD(station, id)},
    {T("station", "scenario", "paper-best", "built-in scene, gains, topology, delays, user scripts"), HAPTIC_FIELD(station, scenario)},
    {I("station", "users", 0, 2, 64, "number of users; other than the scenario's: uniform 10 ms delays and a tree of degree <= 4 unless "
                                     "topology / delay_matrix are given").with_special(0).with_note(" (0 = the scenario's)"), HAPTIC_FIELD(station, users)},
    {T("station", "topology", "", "links, e.g. \"1-2,1-3,1-4\"; \"\" = the scenario's").same_on_all_stations(), HAPTIC_FIELD(station, topology)},
    {T("station", "delay_matrix", "", "mean one-way delays in ms, users x users, \"0,4;8,0\" (row i receives from j): the impairment "
                                      "emulator's means; \"\" = the scenario's").same_on_all_stations(), HAPTIC_FIELD(station, delay_matrix)},
    {T("station", "pushes", "spread", "user scripts' push directions: spread (cancel by construction) or asymmetric (tilted, unequal depths)",
       "spread|asymmetric").same_on_all_stations(), HAPTIC_FIELD(station, pushes)},
    {I("station", "push_seed", 1, 0, double(1ll << 40), "seed of the asymmetric pushes and of the random script"), HAPTIC_FIELD(station, push_seed)},
    {T("station", "script", "", "users' script: push-hold-release, random (hands wander through seeded keyframes all run) or hold; "
                                "\"\" = the scenario's", "|push-hold-release|random|hold").same_on_all_stations(), HAPTIC_FIELD(station, script)},
    {B("station", "allow_routed_peers", false, "false: every UDP peer must be on loopback or on a network of one of this machine's "
                                               "interfaces; true: peers across routers"), HAPTIC_FIELD(station, allow_routed_peers)},
    {B("station", "run_subdir", false, "outputs go to out_dir/<UTC time>-s<session_id>/ (created): a run never overwrites an earlier one"),
     HAPTIC_FIELD(station, run_subdir)},
    {I("station", "nodes", 33, kMinSceneNodes, kMaxStationSceneNodes, "scene size (33 = the paper's ball, else a lattice ball); absent with scene.file"), HAPTIC_FIELD(station, nodes)},
    {R("station", "duration_s", 0, 0, 3600, "run time from the run start").open_low().with_special(0).with_note(" (0 = the scenario's)"),
     HAPTIC_FIELD(station, duration_s)},
    {I("station", "seed", 1, 0, double(1ll << 40), "run seed: impairment link seeds as the simulator's"), HAPTIC_FIELD(station, seed)},
    {R("station", "delay_correlation", 0, 0, 1, "impaired links: AR(1) per packet of the emulated delay (sim --delay-correlation)").open_high(),
     HAPTIC_FIELD(station, delay_correlation)},
    {R("station", "period_min_s", 0, 0, 0.05, "lower bound of the measured step T_k (eq. 18's D term, eq. 26); outside: clamped and counted")
         .with_note(" (0 = measured while probing: the period less this host's wake-up latency bound)"), HAPTIC_FIELD(station, period_min_s)},
    {R("station", "period_max_s", 0, 0, 0.1, "upper bound of the measured step T_k, sent to the neighbours for their eq. (18)")
         .with_note(" (0 = measured while probing: the period plus this host's wake-up latency bound)"), HAPTIC_FIELD(station, period_max_s)},
    {R("station", "step_margin_max", 0.2, 0, 0.5, "measured step bounds: at most this fraction of the period either side (--check-config "
                                                  "checks eq. 26 there); 0: the nominal period, no variable step"), HAPTIC_FIELD(station, step_margin_max)},
    {R("station", "push_start_s", -1, 0, 3600, "user script: push start, s from the run start").with_special(-1).with_note(" (-1 = the scenario's)"),
     HAPTIC_FIELD(station, push_start_s)},
    {R("station", "push_end_s", -1, 0, 3600, "user script: push end").with_special(-1).with_note(" (-1 = the scenario's)"), HAPTIC_FIELD(station, push_end_s)},
    {R("station", "release_s", -1, 0, 3600, "user script: release").with_special(-1).with_note(" (-1 = the scenario's)"), HAPTIC_FIELD(station, release_s)},
    {T("station", "start_clock", "monotonic", "clock of start_at: monotonic (one host) or realtime (NTP/PTP-synced hosts)", "monotonic|realtime"),
     HAPTIC_FIELD(station, start_clock)},
    {R("station", "start_at", 0, 0, 1e12, "common epoch (s on start_clock) of tick k = 0 (probing starts)").with_note(" (0 = now + start_delay_s)"),
     HAPTIC_FIELD(station, start_at)},
    {R("station", "start_delay_s", 2, 0.1, 600, "with start_at = 0: the epoch is this long after now"), HAPTIC_FIELD(station, start_delay_s)},
    {R("station", "start_align_s", 0, 0, 3600, "with start_at = 0 and > 0: the epoch is the next multiple of this on start_clock after "
                                               "now + start_delay_s (stations started independently meet)"), HAPTIC_FIELD(station, start_align_s)},
    {R("station", "probe_s", 1.5, 0.2, 60, "probing phase with zero coupling"), HAPTIC_FIELD(station, probe_s)},
    {R("station", "setup_gap_s", 0.5, 0.05, 10, "from the end of probing to the run start (StationCore built meanwhile)"), HAPTIC_FIELD(station, setup_gap_s)},
    {R("station", "damping_margin", 0.05, 0, 10, "B_i = (1 + margin) x eq. (18) of the measured bounds"), HAPTIC_FIELD(station, damping_margin)},
    {T("station", "consensus_passivity", "eq18", "eq18: B_i from eq. (18) (the paper); pspm: passive set-position modulation per edge "
                                                 "(rt/set_position_modulation.hpp); same on all stations (in the fingerprint)", "eq18|pspm"), HAPTIC_FIELD(station, consensus_passivity)},
    {T("station", "receive_rule", "newest", "newest: the newest packet by sequence is used; paper: the packet that arrived last (Fig. 4), "
                                            "late data used; Nbar then adds the delay spread (each one-way guard doubles, +1 tick); same on all "
                                            "stations (in the fingerprint)", "newest|paper").same_on_all_stations(), HAPTIC_FIELD(station, receive_rule)},
    {R("station", "pspm_reservoir_J", 0.001, 0, 1, "with pspm: each edge's initial energy reservoir E0, J"), HAPTIC_FIELD(station, pspm_reservoir_J)},
    {I("station", "resilient_f", 0, 0, 16, "resilient consensus: each tick the F neighbours whose received object is farthest from "
                                           "this copy are left out (rt/resilient.hpp; with eq18 needs edge_energy_bound_J > 0; "
                                           "the topology should be (2F+1)-robust, else a warning)").with_note(" (0 = off)"),
     HAPTIC_FIELD(station, resilient_f)},
    {I("station", "loss_allowance_ticks", -1, 0, 1000, "ticks added to the measured round-trip bound (eq. 18); -1: from the loss measured "
                                                       "while probing (station/probe.hpp)").with_special(-1), HAPTIC_FIELD(station, loss_allowance_ticks)},
    {I("station", "loss_allowance_max_ticks", 16, 0, 1000, "a measured allowance above this is capped there, with a warning naming the link"),
     HAPTIC_FIELD(station, loss_allowance_max_ticks)},
    {R("station", "edge_energy_bound_J", rt::kDefaultEdgeEnergyBoundJ, 0, 1e6, "per-edge damage bound: an edge whose energy account exceeds "
                                                                              "it acts as a damper until the account fell to half of it")
         .with_note(" (0 = off)"), HAPTIC_FIELD(station, edge_energy_bound_J)},
    {R("station", "edge_energy_leak_W", rt::kDefaultEdgeEnergyLeakW, 0, 1, "energy that left the copy is taken off each edge's account "
                                                                          "up to this power").with_note(" (0 = no leak)"), HAPTIC_FIELD(station, edge_energy_leak_W)},
    {R("station", "edge_energy_hold_s", rt::kDefaultEdgeEnergyHoldS, 0, 3600, "the energy gate releases a tripped edge after it held it "
                                                                            "this long, doubled after each further trip, forgiving its account's excess "
                                                                            "over the release level (every trip stays counted: exit 10)")
         .with_note(" (0 = only when the account fell to half the bound)"), HAPTIC_FIELD(station, edge_energy_hold_s)},
    {R("station", "state_check_kinematic_m", rt::kDefaultStateCheckKinematicM, 0, 1,
       "neighbour state check (rt/edge_monitor.hpp): a neighbour whose reported positions moved this much more than its own reported "
       "velocities explain (at some node) is isolated: its edge acts as a damper").with_note(" (0 = off)"), HAPTIC_FIELD(station, state_check_kinematic_m)},
    {R("station", "state_check_kinematic_window_s", 30, 0.01, 3600, "the time over which that unexplained motion adds up (its leak's time constant)"),
     HAPTIC_FIELD(station, state_check_kinematic_window_s)},
    {I("station", "state_check_max_gap_ticks", 4, 1, 1000, "packets at most this many sequences apart add up their unexplained motion"),
     HAPTIC_FIELD(station, state_check_max_gap_ticks)},
    {I("station", "state_check_max_checked_gap_ticks", 32, 1, 1000,
       "a packet after a longer gap (up to this many sequences) is compared alone, against state_check_kinematic_m x (gap / "
       "state_check_max_gap_ticks)^2; further apart: not compared (re-anchored)"),
     HAPTIC_FIELD(station, state_check_max_checked_gap_ticks)},
    {R("station", "state_check_disagreement_m", rt::kDefaultStateCheckDisagreementM, 0, 1,
       "neighbour state check: a neighbour whose state (carried forward by its velocity) stays this far from this copy at some node, "
       "filtered over state_check_disagreement_window_s, is isolated; off by default: copies that diverged in an outage "
       "or an isolation would trip it on honest neighbours (5 mm: ~5x a clean run's)").with_note(" (0 = off)"), HAPTIC_FIELD(station, state_check_disagreement_m)},
    {R("station", "state_check_disagreement_window_s", 0.2, 0.002, 60, "the time constant of that filter"),
     HAPTIC_FIELD(station, state_check_disagreement_window_s)},
    {R("station", "state_check_readmit_s", 2, 0, 3600, "an isolated neighbour is re-admitted after its packets were truthful this long "
                                                      "(its own steps consistent, within 2 state_check_kinematic_m of this copy, at most half "
                                                      "state_check_disagreement_m); doubled after each further isolation"),
     HAPTIC_FIELD(station, state_check_readmit_s)},
    {T("station", "solver", "auto", "linear step: auto (both timed at start-up where it matters), auto-fixed (the simulator's size rule), "
                                    "direct or iterative (rt/step_solver)", "auto|auto-fixed|direct|iterative"), HAPTIC_FIELD(station, solver)},
    {R("station", "tx_deadband_mm", 0, 0, 100, "> 0: send a state only when some node moved more than this since the last one sent "
                                               "(rt/tx_deadband); 0 = every tick; same on all stations (in the fingerprint)").open_high(), HAPTIC_FIELD(station, tx_deadband_mm)},
    {I("station", "tx_max_interval_ticks", 1, 1, 1000, "with tx_deadband_mm: a state at least every this many ticks (the index-delay bounds "
                                                       "grow by (L + 1)(this - 1), L the loss allowance); same on all stations (in the fingerprint)"), HAPTIC_FIELD(station, tx_max_interval_ticks)},
    {B("station", "tx_predict", false, "with pspm: predictive deadband (extrapolated by velocity); same on all stations (in the fingerprint)"), HAPTIC_FIELD(station, tx_predict)},
    {I("station", "agreement_ticks", 2, 0, 1000, "eq. (18) uses Nbar_ij + Nbar_ji = 2 ceil(R_ij/2) + this"), HAPTIC_FIELD(station, agreement_ticks)},
    {R("station", "damping_Ns_per_m", -1, 0, 1e6, "fixed B_i (experiments below eq. 18)").with_special(-1).with_note(" (-1 = from the measured bound)"),
     HAPTIC_FIELD(station, damping_Ns_per_m)},
    {I("station", "io_priority", 70, 0, 98, "SCHED_FIFO priority of the endpoint's I/O thread; 0 = SCHED_OTHER"), HAPTIC_FIELD(station, io_priority)},
    {T("station", "out_dir", ".", "per-station outputs station-<id>.json, -trace.csv, -state.csv (a directory this process can create)"),
     HAPTIC_FIELD(station, out_dir)},
    {R("station", "max_no_neighbour_fraction", 0.1, 0, 1, "the run fails (exit 7) when more than this share of its ticks had no neighbour "
                                                          "within its bound"), HAPTIC_FIELD(station, max_no_neighbour_fraction)},
    {I("station", "max_missed_cycles", 500, 0, 1e9, "the run ends with exit 11 when its run loop skipped more than this many periods in all "
                                                  "(the host stalled the station: SIGSTOP, swap, a starved CPU); 500 = 1 s at 2 ms, four times "
                                                  "net.peer_silence_s; probing's skips are not counted"), HAPTIC_FIELD(station, max_missed_cycles)},
    {R("station", "divergence_speed_m_per_s", 50, 1e-6, 1e3, "a node faster than this: diverged (exit 4); also the envelope's speed bound"),
     HAPTIC_FIELD(station, divergence_speed_m_per_s)},
    {I("station", "trace_every", 1, 1, 100000, "every k-th tick into station-<id>-trace.csv"), HAPTIC_FIELD(station, trace_every)},
    {I("station", "state_every", 5, 1, 100000, "every k-th tick the whole x into station-<id>-state.csv"), HAPTIC_FIELD(station, state_every)},
    {R("station", "clock_offset_max_ms", 20, 0, 1e6, "bound on each neighbour's tick-grid offset beyond the measurement's uncertainty: warned about"),
     HAPTIC_FIELD(station, clock_offset_max_ms)},
    {B("station", "clock_offset_refuse", false, "refuse to couple (exit 3) when clock_offset_max_ms is exceeded"), HAPTIC_FIELD(station, clock_offset_refuse)},
    {R("station", "clock_offset_limit_ms", 1000, 0, 10000, "a neighbour's tick-grid offset is used up to this (its sequence numbers mapped onto "
                                                           "our grid) and refused beyond it (exit 3, naming both stations and the offset); "
                                                           "net.max_sequence_ahead_ticks is widened by it"), HAPTIC_FIELD(station, clock_offset_limit_ms)},
    {B("station", "record", false, "the session log out_dir/station-<id>.h5 (`haptic-station replay` re-runs it bit-exactly)"), HAPTIC_FIELD(record, enabled)},
    {R("station", "record_max_mb", 1024, 1, 1e6, "rows past this many MB are not written (the log says from which tick)"), HAPTIC_FIELD(record, max_mb)},
    {I("station", "record_deflate", 0, 0, 9, "HDF5 deflate level of the recorded packet values, 0 = none"), HAPTIC_FIELD(record, deflate)},
    {R("station", "record_ring_s", 0, 0, 86400, "> 0: keep only the last this many seconds (must fit record_max_mb)").with_note(" (0 = the whole run)"),
     HAPTIC_FIELD(record, ring_s)},
    {I("station", "view_port", 0, 0, 65535, "> 0: serve the live web view on this port"), HAPTIC_FIELD(view, port)},
    {T("station", "view_bind", "127.0.0.1", "IPv4 address the view listens on"), HAPTIC_FIELD(view, bind)},
    {R("station", "view_rate_hz", 30, 1, 60, "frames per second sent to each browser"), HAPTIC_FIELD(view, rate_hz)},
    {R("station", "rejoin_probe_s", 0.4, 0.1, 10, "a station started after its epoch's probing phase probes this long, then rejoins"),
     HAPTIC_FIELD(station, rejoin_probe_s)},
    {R("station", "return_ramp_s", 2.0, 0, 60, "a neighbour's data back after an outage (or a rejoin) pulls the copies together over this long "
                                              "instead of at once (rt/return_ramp.hpp)").with_note(" (0 = at once)"),
     HAPTIC_FIELD(station, return_ramp_s)},
    {R("station", "drop_fade_s", 0.5, 0, 10, "a neighbour whose data ages out (over its delay bound) is released over this long: its edge "
                                             "holds the last state it used and its stiffness fades to 0 (rt/drop_fade.hpp); an isolated "
                                             "or gated edge drops at once").with_note(" (0 = at once, the paper's)"),
     HAPTIC_FIELD(station, drop_fade_s)},
    {I("station", "age_slack_ticks", 10, 0, 100000, "age guard: a run packet is used only if its echo-based age bound is <= R_ij + this"),
     HAPTIC_FIELD(station, age_slack_ticks)},
};

// [scene]: a mesh file instead of the built-in ball.
const std::vector<StationOption> kScene = {
    {T("scene", "file", "", ".msh (Gmsh ASCII 2.2/4.1), .node/.ele (TetGen), .vtk (legacy ASCII), or a closed surface .obj/.stl/.off "
                            "(tetrahedralized by TetGen); relative to the station file's folder"), HAPTIC_FIELD(scene, file)},
    {R("scene", "unit_m", 1, 0, 1e3, "metres per file unit").open_low(), HAPTIC_FIELD(scene, unit_m)},
    {R("scene", "density_kg_per_m3", 0, 0, 1e6, "material density").with_note(" (0 = the paper ball's)"), HAPTIC_FIELD(scene, density_kg_per_m3)},
    {R("scene", "youngs_modulus_Pa", 0, 0, 1e12, "Young's modulus").with_note(" (0 = the paper ball's)"), HAPTIC_FIELD(scene, youngs_modulus_Pa)},
    {I("scene", "max_elements", 200000, 4, 1000000, "refuse bigger meshes (tetrahedra)"), HAPTIC_FIELD(scene, max_elements)},
};

// [device]: the haptic device (drivers/device_factory.hpp) and its mapping.
const char* kGain = " (-1 = from the device or the scenario)";
const std::vector<StationOption> kDevice = {
    {T("device", "kind", "auto", "auto (first Touch, else Falcon, else SpaceMouse; one must be connected), or the kind; a device that "
                                 "cannot be started is an error (exit 9); simulated: the scenario's scripted user (a warning)",
       "auto|touch|falcon|spacemouse|simulated"), HAPTIC_FIELD(device, kind)},
    {T("device", "hd_library_path", "", "OpenHaptics libHD.so; \"\" = $HAPTIC_HD_LIBRARY, else libHD.so"), HAPTIC_FIELD(device, hd_library_path)},
    {T("device", "hd_device_name", "", "OpenHaptics device configuration name; \"\" = the default device"), HAPTIC_FIELD(device, hd_device_name)},
    {T("device", "hidraw_path", "", "SpaceMouse hidraw node; \"\" = the first SpaceMouse found"), HAPTIC_FIELD(device, hidraw_path)},
    {T("device", "usb_serial", "", "this station's device by the serial `haptic-devices` lists, when two of one kind are on this PC"),
     HAPTIC_FIELD(device, usb_serial)},
    {T("device", "falcon_firmware_path", "", "Novint Falcon: the firmware file loaded at every start (not shipped; required for a Falcon)"),
     HAPTIC_FIELD(device, falcon_firmware_path)},
    {I("device", "falcon_index", 0, 0, 15, "which Falcon on USB (0 = the first)"), HAPTIC_FIELD(device, falcon_index)},
    {R("device", "falcon_homing_timeout_s", 30, 0, 600, "the user homes the grip within this").open_low(), HAPTIC_FIELD(device, falcon_homing_timeout_s)},
    {R("device", "max_force_N", 1e9, 0, 1e12, "extra output clamp below the device's own limit").open_low(), HAPTIC_FIELD(device, max_force_N)},
    {R("device", "max_power_W", 3, 0, 1000, "cap on F.v into the hand").with_note(" (0 = off)"), HAPTIC_FIELD(device, max_power_W)},
    {R("device", "max_speed_m_per_s", 3, 0, 1000, "a faster sample is out of range (safe state)").open_low(), HAPTIC_FIELD(device, max_speed_m_per_s)},
    {I("device", "max_stale_reads", 5, 1, 100000, "ticks without a new sample before the safe state"), HAPTIC_FIELD(device, max_stale_reads)},
    {I("device", "max_reads_before_first_sample", 500, 1, 10000000, "start-up grace before the first sample"),
     HAPTIC_FIELD(device, max_reads_before_first_sample)},
    {R("device", "workspace_margin", 1.5, 1, 100, "|p| beyond this x the workspace radius is out of range"), HAPTIC_FIELD(device, workspace_margin)},
    {R("device", "sim_max_force_N", 3.3, 0, 1000, "simulated device capability").open_low(), HAPTIC_FIELD(device, sim_max_force_N)},
    {R("device", "damping_Ns_per_m", -1, 0, 1000, "the device's damping b_d for eq. (26); required for a Touch or Falcon (none published)")
         .with_special(-1).with_note(kGain), HAPTIC_FIELD(device, damping_Ns_per_m)},
    {R("device", "coupling_stiffness_N_per_m", -1, 0, 1e6, "K_vc of the virtual coupling (Section III-C)").open_low().with_special(-1).with_note(kGain),
     HAPTIC_FIELD(device, coupling_stiffness_N_per_m)},
    {R("device", "coupling_damping_Ns_per_m", -1, 0, 1e4, "B_vc").with_special(-1).with_note(kGain), HAPTIC_FIELD(device, coupling_damping_Ns_per_m)},
    {R("device", "proxy_damping_Ns_per_m", -1, 0, 1e4, "b_v, extra damping of the virtual proxy").with_special(-1).with_note(kGain),
     HAPTIC_FIELD(device, proxy_damping_Ns_per_m)},
    {V("device", "map_offset_m", -100, 100, "workspace mapping p_obj = offset + scale R p_dev: the offset"), HAPTIC_FIELD(device, map_offset_m)},
    {V("device", "map_rotation_deg", -360, 360, "R = Rz(rz) Ry(ry) Rx(rx), degrees about the object's fixed axes"), HAPTIC_FIELD(device, map_rotation_deg)},
    {R("device", "map_scale", 1, 0, 100, "the scale; forces go back as scale R^T F").open_low(), HAPTIC_FIELD(device, map_scale)},
    {R("device", "ramp_in_s", -1, 0, 60, "the force ramps linearly from 0 over this time after the station couples").with_special(-1)
         .with_note(" (-1 = 1 s for a real device, 0 for a simulated user)"), HAPTIC_FIELD(device, ramp_in_s)},
};

// [rt], [loop], [gpio], [telemetry]: platform/'s configurations.
const std::vector<StationOption> kPlatform = {
    {I("rt", "priority", 80, 1, 98, "SCHED_FIFO priority of the tick thread"), HAPTIC_FIELD(rt, priority)},
    {I("rt", "cpu", -1, -1, 4095, "pin the tick thread to this core (-1: unpinned)"), HAPTIC_FIELD(rt, cpu)},
    {B("rt", "lock_memory", true, "mlockall and prefault"), HAPTIC_FIELD(rt, lock_memory)},
    {B("rt", "hold_dma_latency", false, "write 0 to /dev/cpu_dma_latency and keep it open"), HAPTIC_FIELD(rt, hold_dma_latency)},
    {B("rt", "require_rt", false, "refuse instead of falling back when a real-time setting fails"), HAPTIC_FIELD(rt, require_rt)},
    {B("rt", "isolate_cpu", true, "with cpu >= 0: every other thread of the process moved off that cpu"), HAPTIC_FIELD(rt, isolate_cpu)},
    {I("loop", "period_ns", 2000000, 10000, 1000000000, "tick period (must equal the scenario's T)"), HAPTIC_FIELD(loop, period_ns)},
    {I("loop", "overrun_storm_count", 10, 1, 1000000, "overruns in one window that make a storm"), HAPTIC_FIELD(loop, overrun_storm_count)},
    {I("loop", "report_interval_ns", 1000000000, 1000000000, 3600000000000.0, "throttle of the loop's reports"), HAPTIC_FIELD(loop, report_interval_ns)},
    {B("gpio", "enabled", false, "toggle GPIO lines per tick and per packet (scope timing)"), HAPTIC_FIELD(gpio, enabled)},
    {T("gpio", "chip", "", "gpiochip name, path, label or number"), HAPTIC_FIELD(gpio, chip)},
    {I("gpio", "tick_line", -1, -1, 65535, "line toggled each tick (required when enabled)"), HAPTIC_FIELD(gpio, tick_line)},
    {I("gpio", "packet_line", -1, -1, 65535, "line toggled per packet (-1 = none)"), HAPTIC_FIELD(gpio, packet_line)},
    {T("gpio", "consumer", "haptic-station", "label shown by gpioinfo"), HAPTIC_FIELD(gpio, consumer)},
    {T("telemetry", "path", "", "CSV file of the loop's telemetry; \"\" = no file, history only"), HAPTIC_FIELD(telemetry, path)},
    {T("telemetry", "postmortem_dir", ".", "where postmortem-*.csv go"), HAPTIC_FIELD(telemetry, postmortem_dir)},
    {R("telemetry", "postmortem_s", 5, 0.1, 600, "seconds of history dumped on a fault"), HAPTIC_FIELD(telemetry, postmortem_s)},
    {I("telemetry", "max_dumps", 8, 1, 100000, "post-mortem files per run"), HAPTIC_FIELD(telemetry, max_dumps)},
};

#undef HAPTIC_FIELD

std::vector<StationOption> make_station_options() {
  std::vector<StationOption> all = kStation;
  all.insert(all.end(), kScene.begin(), kScene.end());
  all.insert(all.end(), kDevice.begin(), kDevice.end());
  all.insert(all.end(), kPlatform.begin(), kPlatform.end());
  return all;
}

}  // namespace

const std::vector<StationOption>& station_options() {
  static const std::vector<StationOption> options = make_station_options();
  return options;
}

std::vector<OptionDecl> all_option_decls(const std::vector<StationOption>& station) {
  std::vector<OptionDecl> out;
  for (const StationOption& o : station) out.push_back(o.decl);
  const std::vector<OptionDecl>& net = net::net_options();
  out.insert(out.end(), net.begin(), net.end());
  return out;
}

void read_station_options(const toml::table& doc, StationFile& f, const std::vector<StationOption>& options) {
  const platform::config::View root{doc};
  std::vector<OptionDecl> decls;
  for (const StationOption& o : options) decls.push_back(o.decl);
  std::vector<std::string> sections;
  for (const OptionDecl& d : decls)
    if (std::find(sections.begin(), sections.end(), d.section) == sections.end()) sections.emplace_back(d.section);
  for (const std::string& s : sections) platform::config::only_keys(root[s], s, platform::config::section_keys(decls, s));
  std::uint64_t shared = 1469598103934665603ULL;
  for (const StationOption& o : options) {
    const OptionValue v = platform::config::read_option(root[o.decl.section][o.decl.key], o.decl, platform::config::option_key(o.decl));
    o.set(f, v);
    if (o.decl.shared) shared = platform::config::hash_option(shared, o.decl, v);
  }
  f.shared_options_hash = shared;
}

namespace {

// The table at the dotted path `section` ("net.impairment"), created when absent.
toml::table& table_at(toml::table& doc, const std::string& section) {
  toml::table* t = &doc;
  std::size_t at = 0;
  while (at <= section.size()) {
    const std::size_t dot = std::min(section.find('.', at), section.size());
    const std::string part = section.substr(at, dot - at);
    if (!t->contains(part)) t->insert(part, toml::table{});
    toml::table* next = (*t)[part].as_table();
    if (!next) platform::config::bad("[" + section + "]", "a table");
    t = next;
    at = dot + 1;
  }
  return *t;
}

}  // namespace

std::string with_overrides(std::string_view toml_text, const std::vector<std::pair<std::string, std::string>>& sets,
                           const std::vector<OptionDecl>& decls) {
  if (sets.empty()) return std::string(toml_text);
  toml::table doc = platform::config::parse_document(toml_text);
  const bool network_alias = !doc.contains("net") && doc.contains("network");
  for (const auto& [key, value] : sets) {
    const auto d = std::find_if(decls.begin(), decls.end(), [&](const OptionDecl& o) { return platform::config::option_key(o) == key; });
    if (d == decls.end() || std::strchr(d->section, '[')) throw std::invalid_argument("config: unknown key " + key + " (command line)");
    std::string section = d->section;
    if (network_alias && section.rfind("net", 0) == 0) section = "network" + section.substr(3);
    toml::table& t = table_at(doc, section);
    try {
      const toml::table one = toml::parse("v = " + value);
      one.get("v")->visit([&](const auto& node) { t.insert_or_assign(std::string(d->key), node); });
    } catch (const toml::parse_error&) {
      t.insert_or_assign(std::string(d->key), value);  // a bare word: the string, which the parser then checks
    }
  }
  std::ostringstream os;
  os << doc;
  return os.str();
}

std::string options_markdown(const std::vector<OptionDecl>& decls) {
  return "# Station file options\n\n"
         "Generated by `haptic-station options --markdown` from the one declaration of each option (firmware/station/options.cpp, "
         "net/options.cpp); test_station checks that this file equals the generated text. `haptic-station run` takes each of these "
         "but the `net.peers[]` keys as a command-line override of the file, e.g. `--station.probe_s 2`. `[network]` is an alias of "
         "`[net]` (with `listen` for `bind` and a peer's `station` for `id`). \"Same on all stations\": part of the plan fingerprint "
         "the stations compare while probing.\n\n" +
         platform::config::markdown_table(decls);
}

}  // namespace haptic::firmware
