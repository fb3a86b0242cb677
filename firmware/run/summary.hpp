#pragma once
// The run output contract shared by the simulator (`haptic-station sim`) and the multi-process
// merge (`haptic-station merge`): summary.json (scenario, metrics, per-link packets), trace.csv
// (one row per station and recorded tick) and series.csv (one row per recorded tick). The real
// station's station-<id>.json starts with the same scenario part. Values over an empty window are
// null. Not RT-safe.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/run/metrics.hpp"
#include "firmware/scenario.hpp"

namespace haptic::firmware {

// Bit of station-<id>-trace.csv's `flags` (above the core's rt::TickFlags, trace only): this tick
// pushed its state to the neighbours (the transmission policy, rt/tx_deadband, decided to send).
// run/merge.cpp counts them per window (link_stats sent_in_hold_window, sent_after_consensus).
inline constexpr std::uint32_t kTraceStateSent = 1u << 16;


// The scenario part: name, users, dt_s, duration_s, seed, topology (1-based), scene size, margin,
// loss allowance, deadband, script times, the metrics windows (what the merge needs to take
// the same metrics from the stations' records), the traced node's rest position
// (trace_node_rest_m: the figures plot displacement from it) and the snapshot times.
nlohmann::json scenario_json(const BuiltScenario& b);
// A graph's links as [[a, b], ...] with users numbered from 1 (scenario_json's "topology").
nlohmann::json topology_json(const model::Graph& g);
// The keys scenario_json() writes (the merge copies them from station-<id>.json).
const std::vector<std::string>& scenario_json_keys();
// The metrics windows as scenario_json() wrote them ("metrics_windows"); throws
// std::invalid_argument naming the missing key.
MetricsWindows metrics_windows_from_json(const nlohmann::json& scenario);

// The metrics part of summary.json (nulls for empty windows; a speed that is not finite is "inf").
nlohmann::json metrics_json(const RunMetricsResult& m);

// The receiver's per-edge energy account of neighbour n (eq. 14 split per edge, rt/edge_energy.hpp)
// and its damage bound (station.edge_energy_bound_J): the same fields in summary.json's link_stats
// and station-<id>.json's links ("edge_energy"). Not RT-safe.
struct EdgeEnergySummary {
  double account_J = 0, peak_J = 0;  // energy the edge put into the receiver's copy: now, and its maximum
  double bound_J = 0;                // +inf: no bound (written as null)
  std::uint64_t trips = 0, gated_ticks = 0;
  double removed_J = 0;              // the energy the gate's damper action took out of the copy
};
EdgeEnergySummary edge_energy_summary(const rt::StationCore& core, int n);
nlohmann::json edge_energy_json(const EdgeEnergySummary& e);

// What the per-edge energy gate (rt/edge_energy.hpp) and the edge-drop rule (the index-delay bound,
// rt/station.hpp NeighborConfig) did in a run: summary.json's and station-<id>.json's "gate". A run
// in which the gate tripped was kept bounded by the gate's bound, not by eq. (18) alone (its port
// energy may go below -d^2); one in which an edge was dropped ran with a delay over eq. (18)'s bound
// on that edge. Neither is reported as plain "stable" (run_verdict). Not RT-safe.
struct GateSummary {
  std::uint64_t trips = 0, gated_ticks = 0;  // the energy gate, over all edges
  double removed_J = 0;                      // the energy its damper action took out (>= 0)
  std::uint64_t edge_drop_events = 0;        // the edge-drop rule (a packet over its index-delay bound)
  std::optional<double> port_energy_min_J;   // the worst (most negative) cumulative port energy (13)
  bool gate_tripped() const { return trips > 0; }
  bool edge_dropped() const { return edge_drop_events > 0; }
  GateSummary& operator+=(const GateSummary& o);  // counts and energies add; the worst port energy is the smaller
};
GateSummary gate_summary(const rt::StationCore& core);  // port_energy_min_J left empty (the caller's metric)
nlohmann::json gate_json(const GateSummary& g);
GateSummary gate_from_json(const nlohmann::json& gate);  // a station's "gate" (absent keys: 0 / null)
// The run's verdict, summary.json's "verdict": "diverged", "unstable", "held_by_gate" (the energy
// gate tripped), "not_passive" (model::eq13_broken, no gate trip: nothing held the energy the ports took),
// "stable_with_edge_drops" (the edge-drop rule acted, the gate did not) or "stable".
std::string run_verdict(bool diverged, bool unstable, const GateSummary& g, bool eq13_broken);
// The words of a verdict for the one-line results ("HELD BY THE GATE", "stable with edge drops", ...).
std::string verdict_words(const std::string& verdict);
// What the gate did, for the one-line results: "" when neither it nor the drop rule acted, else e.g.
// "263 energy-gate trips (6131 gated ticks), 20.75 J removed by the gate, 0 edge drops; worst port
// energy -0.01437 J".
std::string gate_clause(const GateSummary& g);

// One directed link, row `to` receives from column `from` (1-based), as summary.json's link_stats.
struct LinkSummary {
  int to = 0, from = 0;
  std::uint64_t sent = 0, delivered = 0, lost = 0, duplicated = 0, reordered = 0;
  std::optional<double> mean_delay_ms, max_delay_ms;  // null when nothing arrived
  std::optional<std::int64_t> max_index_delay_ticks;  // max N_ij^k at the receiver
  std::optional<std::uint64_t> bound_violations;      // edge drop events at the receiver
  std::optional<std::int64_t> index_delay_bound_ticks;
  std::optional<EdgeEnergySummary> edge_energy;       // the receiver's account of this edge
};
nlohmann::json link_json(const LinkSummary& l);
// summary.json's "packets": totals over the links.
nlohmann::json packets_json(const std::vector<LinkSummary>& links);

// trace.csv: one row per station (user from 1) and recorded tick, at t = (k + 1) T.
struct TraceRow {
  double t_s = 0;
  int user = 0;
  double node[3], force[3], vp[3], device[3];
  double port_J = 0, ctrl_J = 0, vo_J = 0;
  bool contact = false;
};
// series.csv: the whole system at one recorded tick. Then, for readers that must not compute a
// model quantity themselves (tools/study/hold_balance.py): the rest of sum_i u_i, eq. (20)'s force
// balance (mean_i |u_i| and |sum_i u_i| / mean_i |u_i|, firmware/model/metrics.hpp) and the traced
// node's position in the mean copy. NaN where the tick has no such value (the merge: forces only
// where every station traced).
struct SeriesRow {
  double t_s = 0, consensus_error_m = 0, deformation_m = 0, port_total_J = 0, ctrl_total_J = 0, force_sum_x_N = 0, force_sum_norm_N = 0;
  double force_sum_y_N = NAN, force_sum_z_N = NAN, force_mean_norm_N = NAN, force_balance_ratio = NAN;
  double trace_node_mean_m[3] = {NAN, NAN, NAN};
  void set_forces(const model::ForceBalance& b);
};
void write_trace_header(std::FILE* f);
void write_trace_row(std::FILE* f, const TraceRow& r);
void write_series_header(std::FILE* f);
void write_series_row(std::FILE* f, const SeriesRow& r);

// The times of the snapshot figure: start, end of the push, mid-hold, release and end for a
// push-hold-release script; otherwise start, end of the perturbation and end.
std::vector<double> snapshot_times_s(const ScenarioSpec& s);
// snapshots.json: every copy (x, 3n values) and every proxy at one time; the file adds each copy's
// per-node distance from the mean shape (model::distance_from_mean_shape_m) for the figures.
struct Snapshot {
  double t_s = 0;
  std::vector<std::vector<double>> x_m;
  std::vector<std::array<double, 3>> vp_m;
};
// Writes snapshots.json (the scene's surface triangles, each user's contact nodes, the snapshots)
// for the simulator and the merge alike; throws std::runtime_error naming the file.
void write_snapshots_json(const std::string& path, const std::vector<std::array<int, 3>>& surface,
                          const std::vector<std::vector<int>>& contact_nodes, const std::vector<Snapshot>& snapshots);

// A file opened for writing, closed when it goes; open_out_file throws std::runtime_error naming it.
struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};
using OutFile = std::unique_ptr<std::FILE, FileCloser>;
OutFile open_out_file(const std::string& path);

// Writes j to path (2-space indent); throws std::runtime_error naming the file it cannot write.
void write_json_file(const std::string& path, const nlohmann::json& j);

}  // namespace haptic::firmware
