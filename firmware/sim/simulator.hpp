#pragma once
// Deterministic multi-station simulator: N stations in one process in simulated time, each
// directed link an impaired channel (net/impairment.hpp, seeded), each user a simulated passive
// device + hand (rt/user_model.hpp). Runs the same rt::StationCore as the real-time station and
// takes the run metrics with the same code as the multi-process merge (firmware/run/metrics.hpp).
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "firmware/run/metrics.hpp"
#include "firmware/run/summary.hpp"
#include "firmware/scenario.hpp"
#include "net/impairment.hpp"

namespace haptic::firmware {

struct LinkStats {
  int to = 0, from = 0;  // 0-based; row `to` receives from column `from`
  std::uint64_t sent = 0, delivered = 0, lost = 0, duplicated = 0, reordered = 0;
  double delay_sum_s = 0, delay_max_s = 0;
  std::int64_t max_index_delay = 0;   // max N_ij^k seen by the receiver
  std::uint64_t bound_violations = 0; // edge drop events at the receiver
  std::uint64_t resilient_excluded_ticks = 0;  // ticks the receiver's resilient rule left this edge out (--resilient-f)
  std::uint64_t state_check_isolations = 0;    // times the receiver's state check isolated this edge (--state-check-*)
  std::uint64_t bytes_sent = 0;       // UDP payload bytes of the states sent (float32 wire, headers, MACs)
  std::vector<std::int64_t> sent_ticks;  // tick of every state sent (bandwidth by window)
  EdgeEnergySummary edge_energy{};       // the receiver's energy account of this edge and its bound
  // With --consensus-passivity pspm: the modulation's ticks limited by the reservoir, energy its
  // jumps put in, and the reservoir at the end (rt/set_position_modulation.hpp).
  std::uint64_t pspm_limited_ticks = 0;
  double pspm_injected_J = 0, pspm_reservoir_J = 0;
};

struct SimResult {
  RunMetricsResult metrics;                 // consensus, hold force, deformation, energies, divergence
  double passivity_bound_J = 0;             // d^2 of eq. (13) from the initial energies
  std::vector<LinkStats> links;
  std::uint64_t ticks = 0;
  std::uint64_t steps_clamped = 0;  // T_k outside [T^min, T^max] over all stations (0 with the clock model's own bounds)
  double wall_time_s = 0;
  int trace_every = 1, series_every = 1;  // the rates trace.csv and series.csv were written at (SimOptions)
  std::vector<double> final_port_J, final_controller_J;
  // Per station: the linear step's solver (rt/step_solver: "direct" or "iterative"), the energy its
  // residual put in (EnergyMonitor::solver_residual_J, counted in the balance) and the ticks that
  // stopped at the iteration cap above the tolerance.
  std::vector<std::string> solver;
  std::vector<double> final_solver_residual_J;
  std::vector<std::uint64_t> solver_unconverged_ticks;
  std::vector<double> solver_iterations_mean;  // CG iterations per tick (0: direct)
  std::vector<Eigen::VectorXd> final_x;  // every copy's configuration at the end
};

struct SimOptions {
  std::string out_dir;        // empty: write nothing
  int trace_every = 1;        // write every k-th tick to trace.csv (sim's default: default_trace_every(users))
  int series_every = 1;       // write every k-th tick to series.csv
  bool progress = false;      // progress lines on stderr
  std::vector<double> snapshot_times_s;  // node positions of every copy at these times
  bool record = false;        // session logs out_dir/station-<i>.h5 (firmware/session/log.hpp), lossless
  double record_ring_s = 0;   // > 0: each log keeps only the last this many seconds (a bounded ring)
  double record_max_mb = 0;   // > 0: each log stops growing at this many MB of rows (station.record_max_mb; 0: unbounded)
  int record_deflate = 0;     // HDF5 shuffle + deflate level of the logs' packet values (0: none; station.record_deflate)
  std::string command_line;   // stored in each log as its config_text
};

// trace.csv's default rate for `users` users: every ceil(users / 8)-th tick, so that the file holds
// at most 8 rows per tick (the size of an 8-user run traced every tick, ~0.75 MB per simulated
// second): every tick up to 8 users, every 8th (16 ms) at 64, where every tick wrote 118 MB for the
// paper's 20 s. series.csv (one row per tick whatever the users) stays at every tick.
int default_trace_every(int users);

// Runs the scenario for its duration (or until 0.5 s after a divergence). Not RT-safe.
SimResult run_simulation(const BuiltScenario& scenario, const SimOptions& options);

// The impaired channel sender -> receiver (0-based) as run_simulation() draws it: the scenario's
// link set-up (firmware/station/link_impairment.hpp), run packet k = the core's sequence number k.
net::SendImpairment simulator_channel(const ScenarioSpec& spec, int receiver, int sender);

// What the energy gate and the edge-drop rule did over all stations (summary.json's "gate"), with
// the run's worst port energy. Not RT-safe.
GateSummary sim_gate_summary(const SimResult& r);
// The run's verdict (run_verdict over its metrics, gate and eq. 13 against its d^2): summary.json's and the result line's.
std::string sim_verdict(const SimResult& r);

// summary.json contract (firmware/README.md, firmware/run/summary.hpp): writes path. Not RT-safe.
void write_summary_json(const std::string& path, const BuiltScenario& b, const SimResult& r);

}  // namespace haptic::firmware
