#pragma once
// Deterministic multi-station simulator: N stations in one process in simulated time, each
// directed link an impaired channel (net/impairment.hpp, seeded), each user a simulated passive
// device + hand (rt/user_model.hpp). Runs the same rt::StationCore as the real-time station.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "firmware/scenario.hpp"
#include "net/impairment.hpp"

namespace haptic::firmware {

struct LinkStats {
  int to = 0, from = 0;  // 0-based; row `to` receives from column `from`
  std::uint64_t sent = 0, delivered = 0, lost = 0, duplicated = 0, reordered = 0;
  double delay_sum_s = 0, delay_max_s = 0;
  std::int64_t max_index_delay = 0;   // max N_ij^k seen by the receiver
  std::uint64_t bound_violations = 0; // edge drop events at the receiver
  std::uint64_t bytes_sent = 0;       // UDP payload bytes of the states sent (float32 wire, headers, MACs)
  std::vector<std::int64_t> sent_ticks;  // tick of every state sent (bandwidth by window)
};

struct SimResult {
  double release_time_s = 0;
  double consensus_error_m = 0;             // at the end
  std::optional<double> consensus_time_s;   // after release, error stays < 1 mm
  double hold_force_sum_N = 0, hold_force_mean_N = 0;
  double hold_window_start_s = 0, hold_window_end_s = 0;
  double port_energy_min_J = 0;             // min over time of the cumulative total (13)
  double controller_energy_max_J = 0;       // max over time of the cumulative total (14)
  double passivity_bound_J = 0;             // d^2 of eq. (13) from the initial energies
  bool diverged = false;
  double diverged_at_s = -1;
  double max_node_speed_m_per_s = 0;
  double deformation_hold_m = 0;            // mean shape deformation over the hold window
  std::optional<double> deformation_rise_time_s;  // to 90% of the hold deformation
  double max_consensus_error_m = 0;
  std::vector<LinkStats> links;
  std::uint64_t ticks = 0;
  double wall_time_s = 0;
  std::vector<double> final_port_J, final_controller_J;
  std::vector<Eigen::VectorXd> final_x;  // every copy's configuration at the end
};

struct SimOptions {
  std::string out_dir;        // empty: write nothing
  int trace_every = 1;        // write every k-th tick to trace.csv
  bool progress = false;      // progress lines on stderr
  std::vector<double> snapshot_times_s;  // node positions of every copy at these times
  bool record = false;        // session logs out_dir/station-<i>.h5 (firmware/session_log.hpp), lossless
  std::string command_line;   // stored in each log as its config_text
};

SimResult run_simulation(const BuiltScenario& scenario, const SimOptions& options);

// The impaired channel sender -> receiver (0-based) as run_simulation() draws it: the scenario's
// link set-up (firmware/link_impairment.hpp), run packet k = the core's sequence number k.
net::SendImpairment simulator_channel(const ScenarioSpec& spec, int receiver, int sender);

// summary.json contract (README): writes DIR/summary.json.
void write_summary_json(const std::string& path, const BuiltScenario& b, const SimResult& r);

}  // namespace haptic::firmware
