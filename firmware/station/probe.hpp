#pragma once
// probe and build: the second and third phases of `haptic-station run` (DESIGN.md, "The station
// process"). probe sends the rest state every tick of k in [0, probe_ticks) and measures the round
// trip to each neighbour from its own echoed send stamps (net/); build turns the measured bounds
// into B_i (eq. 18), checks eq. (26) with the device's b_d and builds rt::StationCore with its
// factorizations, on the calling (non-RT) thread, before the run phase starts: the core is handed
// to the RT thread once, when that thread is created. Neither is RT-safe.
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "firmware/station/device_coupling.hpp"
#include "firmware/station/loop.hpp"
#include "firmware/model/probe_loss.hpp"
#include "firmware/model/step_bounds.hpp"
#include "firmware/station/neighbours.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/solver_choice.hpp"
#include "net/endpoint.hpp"
#include "rt/station.hpp"
#include "rt/tx_deadband.hpp"

namespace haptic::firmware {

// This station's step bounds and its neighbours' T_j^max for eq. (18). Ours: station.period_min_s /
// period_max_s where given, else measured (model::measured_step_bounds: from the largest wake-up
// latency of the probing ticks before the freeze, at most station.step_margin_max of the period and
// at most what eq. (26) allows the opened device, so the plan's check at the period holds; a
// rejoining station, whose neighbours built their cores on its earlier incarnation's bounds, takes
// the nominal period, inside any bounds it had), fixed at the freeze and sent in our fingerprints.
// Theirs: as announced in their fingerprints, or, when it did not arrive, 2 T (the most a station
// file allows), with a warning.
struct StepSet {
  // The largest margin eq. (26) allows the opened device (eq26_largest_step_margin_s; set before
  // probing; the measured bounds never go beyond it); infinity: not limited.
  double eq26_margin_max_s = std::numeric_limits<double>::infinity();
  double max_wake_latency_s = 0;          // measured over the probing ticks before the freeze
  std::int64_t wakes = 0;                 // how many
  model::StepBounds own{};                // T_i^min, T_i^max
  bool fixed = false, measured = false;   // fixed at the freeze; from the measurement (not the keys)
  std::vector<double> peer_t_max_s;       // per neighbour, announced (0: did not arrive)
  std::vector<double> t_max_j_s;          // per neighbour, what eq. (18) uses
  std::string text;                       // one line for the log: the bounds and where they came from
};

struct ProbeResult {
  PhaseStatus status = PhaseStatus::kFailed;
  std::string message;                          // why it failed ("" when ok)
  // Per neighbour, in ticks: the round-trip bound both ends use, the larger of ours and the
  // neighbour's (each: measured max x (1 + margin) + margin_s, fixed when its probing froze), and
  // the two it came from (peer: -1 when its bound did not arrive: then ours alone).
  std::vector<std::uint32_t> rtt_bound_ticks;
  std::vector<std::int64_t> own_rtt_bound_ticks, peer_rtt_bound_ticks;
  bool all_bounds_at_freeze = false;            // every neighbour had a bound when probing froze
  // Per neighbour, the loss allowance (ticks added to the round-trip bound, so to Nbar_ij + Nbar_ji):
  // ours, fixed with our bound (station.loss_allowance_ticks, or -1 there: from the probe loss we
  // measured on the incoming direction, probe_loss), the neighbour's (-1: did not arrive) and the
  // one both ends use, the larger. loss_allowance_capped: ours exceeded station.loss_allowance_max_ticks
  // and was capped there (a warning says so).
  ProbeLossCounter loss_counter;
  std::vector<ProbeLoss> probe_loss;
  std::vector<int> own_loss_allowance_ticks, peer_loss_allowance_ticks, loss_allowance_ticks;
  std::vector<bool> loss_allowance_capped;
  // A neighbour (station id) that already runs the session (a packet with sequence number >= our
  // run_k0) before or while we probe: we are a restarted station whose fresh epoch (a relative
  // station.start_delay_s) is not the session's; the caller rejoins instead (0: none).
  int running_session_from = 0;
  std::vector<int> missing;                     // neighbours (station ids) without a bound
  std::uint64_t push_failures = 0;
  std::uint64_t loop_ticks = 0, loop_overruns = 0, loop_missed_cycles = 0;  // the loop's counters over the probing stage
  std::int64_t first_probe_k = -1;              // epoch index of the first probing tick (0 when on time)
  net::EndpointStats stats_at_end{};            // the endpoint's statistics when probing ended
  NeighbourGrid grid;                           // each neighbour's tick grid, from the probes it sent
  ClockCheck clock;                             // tick-grid offsets against ours (station.clock_offset_max_ms)
  std::vector<std::string> warnings;            // e.g. a clock offset above the bound (not refused)
  // The step bounds T^min <= T_k <= T^max (eq. 18, 26, the core's steps; StepSet).
  StepSet steps;
};

// The probing stage of the station's loop (loop.hpp), into r (which must outlive the loop): from
// the tick due at now_ns (ticks before the epoch only watch for a neighbour already running the
// session, which ends the stage: r.running_session_from) to the end of probing, the rest state
// every tick k in [0, probe_ticks) (the endpoint must be started and in probing mode). Round trips
// are measured over the first two thirds (then probing is finished: the bounds freeze); in the
// last third each end learns the other's frozen bound (net/ fingerprint messages), so both use the
// same, the larger. Its ticks are not RT-safe (nothing is coupled yet).
LoopStage probe_stage(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r, std::int64_t now_ns);
// After the probing stage `o` ended (or the loop did): r's status. kNoNeighbour when no neighbour
// answered at all, kFailed when some did not, kStopped on `stop`. Before any round-trip complaint
// it compares the neighbours' fingerprints (refusing, kFailed, with the fields that differ) and,
// after, checks the clock offset of each neighbour's tick grid (warning, or kFailed with
// station.clock_offset_refuse). Not RT-safe.
void end_probe(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop, const StageOutcome& o, ProbeResult& r);
// Both on a loop of their own (a station alone; tests of probing).
ProbeResult probe_neighbours(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop);
// The probing tick at which the round-trip bounds freeze: after two thirds of the probing ticks.
std::int64_t probe_freeze_tick(std::int64_t probe_ticks);
// A rejoin's probing ticks (station.rejoin_probe_s); its bounds are taken at the end of them.
std::int64_t rejoin_probe_ticks(double rejoin_probe_s, double period_s);
// The pace at which the neighbours send their states: every tick, or with the transmission deadband
// at least every tx_max_interval_ticks. Probing sends at that pace (rt::SendInterval), so the round trips
// and the loss it measures are those of the run's traffic (a 16,000-node state every tick would be
// 200 MB/s per link), and the loss counters count packets at it.
std::int64_t send_interval_ticks(const ScenarioSpec& spec);


// After probing has been finished on `ep` (`all`: every neighbour has a bound): statistics,
// bounds, missing neighbours, the fingerprint comparison and the status. `after` names how long
// probing ran ("station.probe_s = 1.5 s"). Used by the probe and the rejoin phase.
void collect_probe_result(const StationPlan& plan, net::Endpoint& ep, bool all, const std::string& after, ProbeResult& r);
// Fixes our loss allowance of every neighbour that has a frozen round-trip bound and none yet
// (r.own_loss_allowance_ticks), from r.loss_counter, and hands it to the endpoint, which sends it
// with the bound. Call right after ep.finish_probing(). An allowance above
// station.loss_allowance_max_ticks is capped there, with a warning naming the link, its loss and the key.
void fix_loss_allowances(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r);
// The clock check of r (grid and statistics) against the epoch `epoch_ns`: a warning, or with
// station.clock_offset_refuse the status kFailed.
void check_clock(const StationPlan& plan, std::int64_t epoch_ns, ProbeResult& r);

// Fixes r.steps.own (once; measured = false: no measurement, the rejoin's nominal step) and hands
// T_i^max to the endpoint's fingerprints.
void fix_step_bounds(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r, bool measured);

// The per-neighbour bounds a station derives from its measured round trips (the passivity budget,
// firmware/model/passivity_budget.hpp).
struct MeasuredBounds {
  std::vector<int> round_trip_ticks;    // R_ij = measured bound (+ margin, net/) + loss allowance + 2 x deadband: Nbar_ij + Nbar_ji in eq. (18)
  std::vector<int> index_guard_ticks;   // Nbar_ij = ceil(R_ij / 2): the rt core drops data older than this
  std::vector<int> assumed_sum_ticks;   // Nbar_ij + Nbar_ji put into eq. (18): 2 Nbar_ij + agreement_ticks
                                        // (covers the peer's guard ceil(R_ji/2) while R_ji <= R_ij + 2 agreement_ticks)
  double damping_min_Ns_per_m = 0;      // eq. (18) with R_ij
  double damping_Ns_per_m = 0;          // B_i used (override, pspm rule or margin)
  bool passivity_condition_met = false; // B_i used >= eq. (18) (eq18); by construction (pspm)
};
// The budget of user `user` of `b` from measured endpoint bounds and the agreed loss allowances
// (ticks on the round trip, one each per neighbour); override_B >= 0: B_i given. steps: T_i^min and
// the neighbours' T_j^max eq. (18) uses (null: the scenario's, b.t_min_s / b.t_max_s).
MeasuredBounds bounds_from_round_trips(const BuiltScenario& b, int user, const std::vector<std::uint32_t>& rtt_bound_ticks,
                                       const std::vector<int>& loss_allowance_ticks, double damping_margin, double damping_override,
                                       int agreement_ticks = 2, const StepSet* steps = nullptr);

struct BuildResult {
  PhaseStatus status = PhaseStatus::kFailed;
  std::string message;
  MeasuredBounds bounds;
  bool passivity_condition_met = false;   // B_i used >= eq. (18) on the measured bounds
  std::unique_ptr<rt::StationCore> core;  // set when status == kOk
  rt::TxDeadband tx_deadband;             // this station's transmission policy (rt/tx_deadband)
  // Per neighbour: the largest echo-based age bound a packet may have (R_ij + station.age_slack_ticks) T
  // (net/README.md, "Age guard"; TickInputs::max_age_s).
  std::vector<double> max_age_s;
  DeviceCoupling coupling;                // b_d, K_vc, B_vc, b_v and the force limit the core got
  drivers::WorkspaceMap map;              // device -> object frame (the tick uses it)
  Eigen::Vector3d proxy_start_m = Eigen::Vector3d::Zero();  // where the virtual proxy starts
  bool proxy_from_device = false;         // placed at the mapped device position (else the scenario's start)
  bool proxy_projected = false;           // that position was inside the object: projected onto the contact face
  SolverChoice solver_choice;             // station.solver = "auto": the start-up measurement (solver_choice.hpp)
};

// B_i from eq. (18) on the measured bounds (station.damping_Ns_per_m overrides it: then the
// passivity condition may not be met, which the report names), the device coupling from the opened
// device's capabilities and the [device] keys with eq. (26) on it (device_coupling.hpp: the error
// proposes the largest K_vc), the core and its factorizations.
// device_position_m: the device's current position (device frame) to place the virtual proxy at
// (mapped; projected onto the contact face when inside the object); null: the scenario's start.
BuildResult build_station_core(const StationPlan& plan, const ProbeResult& probe, const drivers::DeviceCapabilities& device,
                               const double* device_position_m = nullptr);

}  // namespace haptic::firmware
