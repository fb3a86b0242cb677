#include "firmware/run/summary.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace haptic::firmware {

namespace {

using nlohmann::json;

json opt(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

}  // namespace

json topology_json(const model::Graph& g) {
  json topo = json::array();
  for (const auto& l : g) topo.push_back({l.a + 1, l.b + 1});
  return topo;
}

json scenario_json(const BuiltScenario& b) {
  const ScenarioSpec& s = b.spec;
  json j;
  j["scenario"] = s.name;
  j["users"] = s.users;
  j["dt_s"] = s.period_s;
  j["duration_s"] = s.duration_s;
  j["seed"] = s.seed;
  j["topology"] = topology_json(s.topology);
  j["scene_nodes"] = b.scene.nodes;
  j["scene_edges"] = b.scene.mesh.edges.size();
  j["scene_tetrahedra"] = b.scene.mesh.tets.size();
  j["trace_node"] = b.trace_node;
  j["trace_node_rest_m"] = std::vector<double>(b.scene.x_d.data() + 3 * b.trace_node, b.scene.x_d.data() + 3 * b.trace_node + 3);
  j["snapshot_times_s"] = snapshot_times_s(s);
  j["damping_margin"] = s.damping_margin;
  j["loss_allowance_ticks"] = b.loss_allowance_ticks;  // the one used (given, or from the loss model)
  if (s.delay_trace) {
    const auto [lo_ms, hi_ms] = s.delay_trace_range_ms();
    j["delay_trace"] = {{"delays", s.delay_trace->size()}, {"min_ms", lo_ms}, {"max_ms", hi_ms}};
  }
  if (s.burst_enter_probability > 0)
    j["burst_loss"] = {{"enter_probability", s.burst_enter_probability}, {"mean_packets", s.burst_mean_packets},
                       {"loss_probability", s.burst_loss_probability}};
  j["receive_rule"] = rt::rx_rule_name(s.receive_rule);
  j["tx_deadband"] = {{"position_m", s.tx_deadband.position_deadband_m}, {"max_interval_ticks", s.tx_deadband.max_interval_ticks}};
  j["release_time_s"] = s.script.release_s;
  j["push_end_s"] = s.script.push_end_s;
  const MetricsWindows w = metrics_windows(s.script);
  j["metrics_windows"] = {{"release_s", w.release_s},         {"hold_start_s", w.hold_start_s},
                          {"hold_end_s", w.hold_end_s},       {"push_start_s", w.push_start_s},
                          {"push_end_s", w.push_end_s},
                          {"consensus_threshold_m", w.consensus_threshold_m}};
  return j;
}

const std::vector<std::string>& scenario_json_keys() {
  static const std::vector<std::string> keys = {"scenario",    "users",         "dt_s",           "duration_s",           "seed",
                                                "topology",    "scene_nodes",   "scene_edges",    "scene_tetrahedra",     "trace_node", "trace_node_rest_m", "snapshot_times_s",
                                                "damping_margin", "loss_allowance_ticks", "receive_rule", "tx_deadband", "release_time_s", "push_end_s",
                                                "metrics_windows"};
  return keys;
}

MetricsWindows metrics_windows_from_json(const json& scenario) {
  if (!scenario.contains("metrics_windows")) throw std::invalid_argument("no 'metrics_windows' in the station's JSON (written by an older haptic-station?)");
  const json& m = scenario["metrics_windows"];
  MetricsWindows w;
  w.release_s = m.at("release_s").get<double>();
  w.hold_start_s = m.at("hold_start_s").get<double>();
  w.hold_end_s = m.at("hold_end_s").get<double>();
  w.push_start_s = m.at("push_start_s").get<double>();
  w.push_end_s = m.value("push_end_s", 0.0);  // absent in older station files: no push window
  w.consensus_threshold_m = m.at("consensus_threshold_m").get<double>();
  return w;
}

json metrics_json(const RunMetricsResult& m) {
  using F = std::optional<double> RunMetricsResult::*;
  static const std::pair<const char*, F> optional_fields[] = {
      {"consensus_error_m", &RunMetricsResult::consensus_error_m},
      {"max_consensus_error_m", &RunMetricsResult::max_consensus_error_m},
      {"consensus_error_at_release_m", &RunMetricsResult::consensus_error_at_release_m},
      {"consensus_time_s", &RunMetricsResult::consensus_time_s},
      {"consensus_time_10pct_s", &RunMetricsResult::consensus_time_10pct_s},
      {"consensus_time_1pct_s", &RunMetricsResult::consensus_time_1pct_s},
      {"consensus_time_resolution_s", &RunMetricsResult::consensus_time_resolution_s},
      {"hold_force_sum_N", &RunMetricsResult::hold_force_sum_N},
      {"hold_force_mean_N", &RunMetricsResult::hold_force_mean_N},
      {"hold_force_balance_ratio", &RunMetricsResult::hold_force_balance_ratio},
      {"deformation_hold_m", &RunMetricsResult::deformation_hold_m},
      {"deformation_rise_time_s", &RunMetricsResult::deformation_rise_time_s},
      {"port_energy_min_J", &RunMetricsResult::port_energy_min_J},
      {"controller_energy_max_J", &RunMetricsResult::controller_energy_max_J},
      {"diverged_at_s", &RunMetricsResult::diverged_at_s},
      {"growth_detected_at_s", &RunMetricsResult::growth_detected_at_s},
      {"growth_rate_per_s", &RunMetricsResult::growth_rate_per_s}};
  json j;
  j["simulated_s"] = m.simulated_s;
  j["release_time_s"] = m.release_time_s;
  j["hold_window_s"] = {m.hold_window_start_s, m.hold_window_end_s};
  for (const auto& [key, field] : optional_fields) j[key] = opt(m.*field);
  j["diverged"] = m.diverged;
  j["unstable"] = m.unstable;  // diverged by speed or growing consensus error (firmware/model/growth_detector.hpp)
  const auto& v = m.max_node_speed_m_per_s;
  j["max_node_speed_m_per_s"] = !v ? json(nullptr) : std::isfinite(*v) ? json(*v) : json("inf");
  return j;
}

json link_json(const LinkSummary& l) {
  json j = {{"to", l.to},
            {"from", l.from},
            {"sent", l.sent},
            {"delivered", l.delivered},
            {"lost", l.lost},
            {"duplicated", l.duplicated},
            {"reordered", l.reordered},
            {"mean_delay_ms", opt(l.mean_delay_ms)},
            {"max_delay_ms", opt(l.max_delay_ms)},
            {"loss_rate", l.sent ? json(static_cast<double>(l.lost) / static_cast<double>(l.sent)) : json(nullptr)}};
  j["max_index_delay_ticks"] = l.max_index_delay_ticks ? json(*l.max_index_delay_ticks) : json(nullptr);
  j["bound_violations"] = l.bound_violations ? json(*l.bound_violations) : json(nullptr);
  j["index_delay_bound_ticks"] = l.index_delay_bound_ticks ? json(*l.index_delay_bound_ticks) : json(nullptr);
  if (l.edge_energy) j["edge_energy"] = edge_energy_json(*l.edge_energy);
  return j;
}

EdgeEnergySummary edge_energy_summary(const rt::StationCore& core, int n) {
  const auto& a = core.edge_energy();
  const auto& g = core.edge_gate();
  return {a.edge_J(n), a.peak_J(n), g.bound_J(n), g.trips(n), g.gated_ticks(n), g.removed_J(n)};
}

GateSummary& GateSummary::operator+=(const GateSummary& o) {
  trips += o.trips;
  gated_ticks += o.gated_ticks;
  removed_J += o.removed_J;
  edge_drop_events += o.edge_drop_events;
  if (o.port_energy_min_J) port_energy_min_J = std::min(port_energy_min_J.value_or(*o.port_energy_min_J), *o.port_energy_min_J);
  return *this;
}

GateSummary gate_summary(const rt::StationCore& core) {
  GateSummary g;
  const auto& gate = core.edge_gate();
  for (int n = 0; n < core.neighbor_count(); ++n) g.gated_ticks += gate.gated_ticks(n);
  g.trips = gate.trips();
  g.removed_J = gate.removed_J();
  g.edge_drop_events = core.edge_drop_events();
  return g;
}

json gate_json(const GateSummary& g) {
  return {{"energy_gate_trips", g.trips},           {"energy_gate_gated_ticks", g.gated_ticks}, {"energy_gate_removed_J", g.removed_J},
          {"edge_drop_events", g.edge_drop_events}, {"port_energy_min_J", opt(g.port_energy_min_J)},
          {"held_by_gate", g.gate_tripped()},       {"edge_drop_rule_acted", g.edge_dropped()}};
}

GateSummary gate_from_json(const json& j) {
  GateSummary g;
  g.trips = j.value("energy_gate_trips", std::uint64_t{0});
  g.gated_ticks = j.value("energy_gate_gated_ticks", std::uint64_t{0});
  g.removed_J = j.value("energy_gate_removed_J", 0.0);
  g.edge_drop_events = j.value("edge_drop_events", std::uint64_t{0});
  if (j.contains("port_energy_min_J") && j["port_energy_min_J"].is_number()) g.port_energy_min_J = j["port_energy_min_J"].get<double>();
  return g;
}

std::string run_verdict(bool diverged, bool unstable, const GateSummary& g, bool eq13_broken) {
  if (diverged) return "diverged";
  if (unstable) return "unstable";
  if (g.gate_tripped()) return "held_by_gate";
  if (eq13_broken) return "not_passive";
  if (g.edge_dropped()) return "stable_with_edge_drops";
  return "stable";
}

std::string verdict_words(const std::string& verdict) {
  if (verdict == "held_by_gate") return "HELD BY THE GATE";
  if (verdict == "stable_with_edge_drops") return "stable with EDGES DROPPED";
  if (verdict == "diverged") return "DIVERGED";
  if (verdict == "not_passive") return "NOT PASSIVE (port energy below -d^2, eq. 13)";
  return verdict;
}

std::string gate_clause(const GateSummary& g) {
  if (!g.gate_tripped() && !g.edge_dropped()) return "";
  char port[64] = "n/a";
  if (g.port_energy_min_J) std::snprintf(port, sizeof port, "%.4g J", *g.port_energy_min_J);
  char b[256];
  std::snprintf(b, sizeof b, "%llu energy-gate trips (%llu gated ticks), %.4g J removed by the gate, %llu edge drops; worst port energy %s",
                static_cast<unsigned long long>(g.trips), static_cast<unsigned long long>(g.gated_ticks), g.removed_J,
                static_cast<unsigned long long>(g.edge_drop_events), port);
  return b;
}

json edge_energy_json(const EdgeEnergySummary& e) {
  return {{"account_J", e.account_J},
          {"peak_J", e.peak_J},
          {"bound_J", std::isfinite(e.bound_J) ? json(e.bound_J) : json(nullptr)},
          {"trips", e.trips},
          {"gated_ticks", e.gated_ticks},
          {"removed_J", e.removed_J}};
}

json packets_json(const std::vector<LinkSummary>& links) {
  std::uint64_t sent = 0, delivered = 0, lost = 0, dup = 0, reord = 0;
  for (const auto& l : links) {
    sent += l.sent;
    delivered += l.delivered;
    lost += l.lost;
    dup += l.duplicated;
    reord += l.reordered;
  }
  return {{"sent", sent}, {"delivered", delivered}, {"lost", lost}, {"duplicated", dup}, {"reordered", reord}};
}

void write_trace_header(std::FILE* f) {
  std::fprintf(f,
               "t_s,user,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,"
               "device_x_m,device_y_m,device_z_m,port_energy_J,controller_energy_J,vo_energy_J,contact\n");
}

void write_trace_row(std::FILE* f, const TraceRow& r) {
  std::fprintf(f, "%.4f,%d,%.7g,%.7g,%.7g,%.6g,%.6g,%.6g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%d\n", r.t_s, r.user, r.node[0], r.node[1], r.node[2],
               r.force[0], r.force[1], r.force[2], r.vp[0], r.vp[1], r.vp[2], r.device[0], r.device[1], r.device[2], r.port_J, r.ctrl_J, r.vo_J,
               r.contact ? 1 : 0);
}

void write_series_header(std::FILE* f) {
  std::fprintf(f, "t_s,consensus_error_m,deformation_m,port_energy_total_J,controller_energy_total_J,force_sum_x_N,force_sum_norm_N,"
                  "force_sum_y_N,force_sum_z_N,force_mean_norm_N,force_balance_ratio,trace_node_mean_x_m,trace_node_mean_y_m,trace_node_mean_z_m\n");
}

void write_series_row(std::FILE* f, const SeriesRow& r) {
  std::fprintf(f, "%.4f,%.7g,%.7g,%.7g,%.7g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.9g,%.9g,%.9g\n", r.t_s, r.consensus_error_m, r.deformation_m, r.port_total_J,
               r.ctrl_total_J, r.force_sum_x_N, r.force_sum_norm_N, r.force_sum_y_N, r.force_sum_z_N, r.force_mean_norm_N, r.force_balance_ratio,
               r.trace_node_mean_m[0], r.trace_node_mean_m[1], r.trace_node_mean_m[2]);
}

void SeriesRow::set_forces(const model::ForceBalance& b) {
  force_sum_y_N = b.sum_N[1];
  force_sum_z_N = b.sum_N[2];
  force_mean_norm_N = b.mean_norm_N;
  force_balance_ratio = model::force_balance_ratio(b.sum_norm_N, b.mean_norm_N);
}

std::vector<double> snapshot_times_s(const ScenarioSpec& s) {
  const UserScriptSpec& sc = s.script;
  if (sc.kind == UserScriptSpec::Kind::kPushHoldRelease)
    return {0.0, sc.push_end_s, 0.5 * (sc.push_end_s + sc.release_s), sc.release_s, s.duration_s};
  return {0.0, sc.perturb_at_s + sc.perturb_duration_s, s.duration_s};
}

void write_snapshots_json(const std::string& path, const std::vector<std::array<int, 3>>& surface,
                          const std::vector<std::vector<int>>& contact_nodes, const std::vector<Snapshot>& snapshots) {
  json snaps = json::array();
  for (const Snapshot& sn : snapshots) {
    std::vector<const double*> x;
    for (const auto& c : sn.x_m) x.push_back(c.data());
    const int nodes = sn.x_m.empty() ? 0 : static_cast<int>(sn.x_m[0].size() / 3);
    snaps.push_back({{"t_s", sn.t_s}, {"x_m", sn.x_m}, {"vp_m", sn.vp_m}, {"distance_from_mean_shape_m", model::distance_from_mean_shape_m(x, nodes)}});
  }
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << json{{"surface", surface}, {"contact_nodes", contact_nodes}, {"snapshots", snaps}}.dump() << "\n";
}

OutFile open_out_file(const std::string& path) {
  OutFile f(std::fopen(path.c_str(), "w"));
  if (!f) throw std::runtime_error("cannot write " + path);
  return f;
}

void write_json_file(const std::string& path, const json& j) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << j.dump(2) << "\n";
}

}  // namespace haptic::firmware
