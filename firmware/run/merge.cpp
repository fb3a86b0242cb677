#include "firmware/run/merge.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <Eigen/Core>

#include "firmware/model/metrics.hpp"
#include "firmware/model/passivity_budget.hpp"
#include "firmware/run/metrics.hpp"
#include "firmware/run/summary.hpp"

namespace haptic::firmware {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A CSV file of numbers with a header line.
struct Csv {
  std::map<std::string, std::size_t> column;
  std::vector<std::vector<double>> rows;
  double at(std::size_t row, const std::string& name) const { return rows[row][column.at(name)]; }
};

Csv read_csv(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw MergeError("cannot read " + path);
  Csv c;
  std::string line, cell;
  if (!std::getline(f, line)) throw MergeError(path + " is empty (no header line)");
  std::istringstream head(line);
  for (std::size_t i = 0; std::getline(head, cell, ','); ++i) c.column[cell] = i;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    std::vector<double> row;
    std::istringstream in(line);
    while (std::getline(in, cell, ',')) row.push_back(std::strtod(cell.c_str(), nullptr));
    if (row.size() != c.column.size())
      throw MergeError(path + ": a row has " + std::to_string(row.size()) + " values, the header " + std::to_string(c.column.size()));
    c.rows.push_back(std::move(row));
  }
  return c;
}

// One station's files.
struct StationFiles {
  json summary;
  Csv trace, state;
  std::map<std::int64_t, std::size_t> trace_row, state_row;  // tick k -> row
};

// Reads DIR/station-<i>.json (i = 1..N, N from the first) and its CSV files; refuses a station that
// reported an error.
std::vector<StationFiles> load_stations(const std::string& dir) {
  const std::string first = dir + "/station-1.json";
  if (!fs::exists(first)) throw MergeError("no station-1.json in " + dir + " (the output directory of `haptic-station run`)");
  std::vector<StationFiles> st;
  const int users = json::parse(std::ifstream(first), nullptr, false).value("users", 0);
  if (users < 2) throw MergeError(first + ": 'users' must be at least 2");
  for (int i = 1; i <= users; ++i) {
    const std::string base = dir + "/station-" + std::to_string(i);
    std::ifstream f(base + ".json");
    if (!f) throw MergeError("need station-1.." + std::to_string(users) + ".json in " + dir + ": cannot read " + base + ".json");
    StationFiles s;
    s.summary = json::parse(f, nullptr, false);
    if (s.summary.is_discarded() || s.summary.value("station", 0) != i) throw MergeError(base + ".json is not station " + std::to_string(i) + "'s summary");
    if (!s.summary["error"].is_null()) throw MergeError("station " + std::to_string(i) + " reported an error: " + s.summary["error"].get<std::string>());
    s.trace = read_csv(base + "-trace.csv");
    s.state = read_csv(base + "-state.csv");
    for (std::size_t r = 0; r < s.trace.rows.size(); ++r) s.trace_row[static_cast<std::int64_t>(s.trace.rows[r][0])] = r;
    for (std::size_t r = 0; r < s.state.rows.size(); ++r) s.state_row[static_cast<std::int64_t>(s.state.rows[r][0])] = r;
    st.push_back(std::move(s));
  }
  return st;
}

// The ticks every station recorded in `rows`.
std::vector<std::int64_t> common_ticks(const std::vector<StationFiles>& st, std::map<std::int64_t, std::size_t> StationFiles::*rows) {
  std::vector<std::int64_t> ks;
  for (const auto& [k, r] : st[0].*rows) {
    bool all = true;
    for (const auto& s : st) all = all && (s.*rows).count(k) > 0;
    if (all) ks.push_back(k);
  }
  return ks;
}

Eigen::Vector3d trace_force(const StationFiles& s, std::size_t row) {
  return {s.trace.at(row, "force_x_N"), s.trace.at(row, "force_y_N"), s.trace.at(row, "force_z_N")};
}

// Forces and energies at every common trace tick; trace.csv rows. Returns the trace ticks.
std::vector<std::int64_t> merge_traces(const std::vector<StationFiles>& st, double T, RunMetrics& m, std::FILE* trace) {
  const std::vector<std::int64_t> ks = common_ticks(st, &StationFiles::trace_row);
  std::vector<Eigen::Vector3d> forces(st.size());
  static const char* names[] = {"node_x_m", "node_y_m", "node_z_m", "vp_x_m", "vp_y_m", "vp_z_m", "device_x_m", "device_y_m", "device_z_m"};
  for (std::int64_t k : ks) {
    model::StationTotals total;
    for (std::size_t i = 0; i < st.size(); ++i) {
      const std::size_t r = st[i].trace_row.at(k);
      forces[i] = trace_force(st[i], r);
      total.add_energies(st[i].trace.at(r, "port_energy_J"), st[i].trace.at(r, "controller_energy_J"));
      TraceRow row;
      row.t_s = static_cast<double>(k + 1) * T;
      row.user = static_cast<int>(i) + 1;
      for (int a = 0; a < 3; ++a) {
        row.node[a] = st[i].trace.at(r, names[a]);
        row.force[a] = forces[i][a];
        row.vp[a] = st[i].trace.at(r, names[3 + a]);
        row.device[a] = st[i].trace.at(r, names[6 + a]);
      }
      row.port_J = st[i].trace.at(r, "port_energy_J");
      row.ctrl_J = st[i].trace.at(r, "controller_energy_J");
      row.vo_J = st[i].trace.at(r, "vo_energy_J");
      row.contact = st[i].trace.at(r, "contact") != 0;
      write_trace_row(trace, row);
    }
    m.add_forces(k, forces);
    m.add_energies(total.port_J, total.controller_J);
  }
  return ks;
}

// The copies at every common state tick; series.csv rows (energies and forces where all traced).
std::vector<std::int64_t> merge_states(const std::vector<StationFiles>& st, const Eigen::VectorXd& x_d, int trace_node, double T, RunMetrics& m,
                                       std::FILE* series) {
  const std::vector<std::int64_t> ks = common_ticks(st, &StationFiles::state_row);
  std::vector<const double*> x(st.size());
  for (std::int64_t k : ks) {
    for (std::size_t i = 0; i < st.size(); ++i) x[i] = st[i].state.rows[st[i].state_row.at(k)].data() + 1;
    const CopiesSample c = measure_copies(x, x_d);
    m.add_copies(k, c);
    SeriesRow row{static_cast<double>(k + 1) * T, c.consensus_error_m, c.deformation_m, NAN, NAN, NAN, NAN};
    const Eigen::Vector3d node = model::mean_node_position_m(x, trace_node);
    for (int a = 0; a < 3; ++a) row.trace_node_mean_m[a] = node[a];
    bool traced = true;
    for (const auto& s : st) traced = traced && s.trace_row.count(k) > 0;
    if (traced) {
      model::StationTotals total;
      std::vector<Eigen::Vector3d> forces;
      for (const auto& s : st) {
        const std::size_t r = s.trace_row.at(k);
        forces.push_back(trace_force(s, r));
        total.add_force(forces.back());
        total.add_energies(s.trace.at(r, "port_energy_J"), s.trace.at(r, "controller_energy_J"));
      }
      row.port_total_J = total.port_J;
      row.ctrl_total_J = total.controller_J;
      row.force_sum_x_N = total.force_N[0];
      row.force_sum_norm_N = total.force_N.norm();
      row.set_forces(model::force_balance(forces));
    }
    write_series_row(series, row);
  }
  return ks;
}

std::optional<double> opt_number(const json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? std::optional<double>(j[key].get<double>()) : std::nullopt;
}

// Speeds and divergence as each station measured them.
void merge_station_flags(const std::vector<StationFiles>& st, RunMetrics& m) {
  for (const auto& s : st) {
    const json& v = s.summary["max_node_speed_m_per_s"];
    if (v.is_string()) m.add_speed(INFINITY);
    if (v.is_number()) m.add_speed(v.get<double>());
    if (s.summary.value("diverged", false)) m.add_divergence(s.summary["diverged_at_s"].get<double>());
  }
}

const json& link_of(const StationFiles& s, int peer) {
  for (const json& l : s.summary["links"])
    if (l["peer"].get<int>() == peer) return l;
  throw MergeError("station " + std::to_string(s.summary["station"].get<int>()) + " has no link to station " + std::to_string(peer));
}

// One directed link to <- from: the common contract from both ends' counters, plus what the
// receiver measured.
json merged_link(const std::vector<StationFiles>& st, int to, const json& rx, LinkSummary& ls) {
  const int from = rx["peer"].get<int>();
  const json& tx = link_of(st[static_cast<std::size_t>(from - 1)], to);
  ls.to = to;
  ls.from = from;
  ls.sent = tx["tx_packets_run"].get<std::uint64_t>();
  ls.lost = tx["tx_impair_lost_run"].get<std::uint64_t>();
  ls.duplicated = tx["tx_impair_duplicated_run"].get<std::uint64_t>();
  ls.delivered = rx["rx_packets_run"].get<std::uint64_t>();
  ls.reordered = rx.value("rx_stale_reordered", std::uint64_t{0});
  ls.mean_delay_ms = opt_number(rx, "one_way_mean_ms");
  ls.max_delay_ms = opt_number(rx, "one_way_max_ms");
  if (rx.contains("max_index_delay_ticks")) ls.max_index_delay_ticks = rx["max_index_delay_ticks"].get<std::int64_t>();
  if (rx.contains("bound_violations")) ls.bound_violations = rx["bound_violations"].get<std::uint64_t>();
  if (rx.contains("index_delay_bound_ticks")) ls.index_delay_bound_ticks = rx["index_delay_bound_ticks"].get<std::int64_t>();
  json l = link_json(ls);
  for (const char* k : {"rtt_mean_ms", "rtt_max_ms", "rtt_samples", "rtt_over_bound_events", "model_index_delay_bound_ticks"}) l[k] = rx.value(k, json(nullptr));
  l["measured_loss_rate"] = rx.value("rx_loss_fraction_measured", json(nullptr));
  l["round_trip_bound_ticks"] = rx.value("round_trip_bound_ticks", json(nullptr));
  l["assumed_round_trip_ticks_at_receiver"] = rx.value("assumed_round_trip_ticks", json(nullptr));
  l["packets_per_s"] = tx.value("packets_per_s", json(nullptr));  // the sender's datagrams and bytes to this peer
  l["bytes_per_s"] = tx.value("bytes_per_s", json(nullptr));
  return l;
}

// States station s pushed at run ticks k with t0 <= k T < t1: the kTraceStateSent bits of its trace
// (run/summary.hpp), as the simulator's sent_between counts them; null when the trace does not hold
// every tick or predates the bit.
json states_sent_between(const StationFiles& s, double T, double t0, double t1) {
  if (!s.summary.value("trace_marks_state_sent", false) || s.summary.value("trace_every", 0) != 1) return nullptr;
  std::uint64_t n = 0;
  for (const auto& [k, row] : s.trace_row) {
    const double t = static_cast<double>(k) * T;
    if (t >= t0 - 1e-9 && t < t1 - 1e-9 && (static_cast<std::uint32_t>(s.trace.at(row, "flags")) & kTraceStateSent)) ++n;
  }
  return n;
}

// Per link, the states its sender pushed in the hold window and after consensus (every state goes
// to every neighbour), and their totals in `packets`, like the simulator's summary.
void add_windowed_sends(const std::vector<StationFiles>& st, json& j) {
  const double T = st[0].summary["dt_s"].get<double>();
  const double end = static_cast<double>(st[0].summary["ticks_run"].get<std::int64_t>() + 1) * T;
  const auto& hw = j["hold_window_s"];
  const double h0 = hw[0].get<double>(), h1 = hw[1].get<double>();
  const bool settled = j["consensus_time_s"].is_number();
  const double from = settled ? j["release_time_s"].get<double>() + j["consensus_time_s"].get<double>() : end;
  json hold_total = 0, after_total = 0;
  for (json& l : j["link_stats"]) {
    const StationFiles& s = st[static_cast<std::size_t>(l["from"].get<int>() - 1)];
    l["sent_in_hold_window"] = states_sent_between(s, T, h0, h1);
    l["sent_after_consensus"] = states_sent_between(s, T, from, end);
    for (auto [key, total] : {std::pair<const char*, json*>{"sent_in_hold_window", &hold_total}, {"sent_after_consensus", &after_total}})
      *total = l[key].is_null() || total->is_null() ? json(nullptr) : json(total->get<std::uint64_t>() + l[key].get<std::uint64_t>());
  }
  j["packets"]["sent_in_hold_window"] = hold_total;
  j["packets"]["sent_after_consensus"] = after_total;
  j["packets"]["after_consensus_s"] = std::max(0.0, end - T - from);
}

// Eq. (18) at station i assumed Nbar_ij + Nbar_ji = its own measured round trip plus the agreement
// margin; the guards actually enforced are Nbar_ij (at i) + Nbar_ji (at j). Per link: whether the
// enforced sum stays within what BOTH ends assumed. Returns whether it does on every link.
bool check_bounds(json& links) {
  std::map<std::pair<int, int>, const json*> by;
  for (const json& l : links) by[{l["to"].get<int>(), l["from"].get<int>()}] = &l;
  bool all = true;
  for (json& l : links) {
    const json& r = *by.at({l["from"].get<int>(), l["to"].get<int>()});
    const json *g = &l["index_delay_bound_ticks"], *rg = &r["index_delay_bound_ticks"];
    const json *a = &l["assumed_round_trip_ticks_at_receiver"], *ra = &r["assumed_round_trip_ticks_at_receiver"];
    if (g->is_null() || rg->is_null() || a->is_null() || ra->is_null()) {
      all = false;
      continue;
    }
    const std::int64_t enforced = g->get<std::int64_t>() + rg->get<std::int64_t>();
    l["enforced_round_trip_ticks"] = enforced;
    l["bounds_consistent"] = enforced <= std::min(a->get<std::int64_t>(), ra->get<std::int64_t>());
    all = all && l["bounds_consistent"].get<bool>();
  }
  return all;
}

// The steps T_k a station integrated with, from its trace's step_s (null: an older trace without it):
// smallest, mean, largest over the traced ticks, and, when every tick was traced, how far the
// integrated time (the sum of T_k) ran from the tick grid (ticks x T) by the last one. The merged
// metrics stay on the common tick grid (the stations' ticks are scheduled on it, so copies are
// compared at the same wall time); this says how the variable-step integration kept pace with it.
json steps_json(const StationFiles& f) {
  if (!f.trace.column.count("step_s") || f.trace.rows.empty()) return nullptr;
  double lo = INFINITY, hi = 0, sum = 0;
  for (std::size_t r = 0; r < f.trace.rows.size(); ++r) {
    const double t = f.trace.at(r, "step_s");
    lo = std::min(lo, t), hi = std::max(hi, t), sum += t;
  }
  const auto n = static_cast<double>(f.trace.rows.size());
  const bool every = f.summary.value("trace_every", 1) == 1;
  const double T = f.summary["dt_s"].get<double>();
  return {{"min_s", lo}, {"mean_s", sum / n}, {"max_s", hi}, {"integrated_minus_grid_s", every ? json(sum - n * T) : json(nullptr)}};
}

// What a reader must not miss in a merged run: a link whose index delay N went over its guard N̄
// (the receiver used none of its data for those ticks; edge drops counted) and a station whose host
// was starving (station-<id>.json "host", the one rule platform::host_starving), each in words.
json merge_flags(const std::vector<StationFiles>& st) {
  json flags = json::array();
  for (const auto& f : st) {
    const json& s = f.summary;
    const int to = s["station"].get<int>();
    for (const json& l : s["links"]) {
      if (!l.contains("max_index_delay_ticks") || !l.contains("index_delay_bound_ticks")) continue;
      const auto n = l["max_index_delay_ticks"].get<std::int64_t>(), nbar = l["index_delay_bound_ticks"].get<std::int64_t>();
      if (n > nbar)
        flags.push_back("link " + std::to_string(to) + "<-" + std::to_string(l["peer"].get<int>()) + ": N max " + std::to_string(n) + " > N̄ " +
                        std::to_string(nbar) + " (" + std::to_string(l.value("bound_violations", std::uint64_t{0})) + " edge drops)");
    }
    const json& h = s.value("host", json(nullptr));
    if (h.is_object() && h.value("starving", false)) {
      char b[200];
      std::snprintf(b, sizeof b, "station %d: host STARVING (wake-up P99 %.3g ms, max %.3g ms, %llu overruns, %llu skipped periods in %llu ticks)", to,
                    h["wake_p99_ms"].is_number() ? h["wake_p99_ms"].get<double>() : 0.0, h["wake_max_ms"].is_number() ? h["wake_max_ms"].get<double>() : 0.0,
                    static_cast<unsigned long long>(h["overruns"].get<std::uint64_t>()), static_cast<unsigned long long>(h["missed_cycles"].get<std::uint64_t>()),
                    static_cast<unsigned long long>(h["ticks"].get<std::uint64_t>()));
      flags.push_back(b);
    }
  }
  return flags;
}

json station_rows(const std::vector<StationFiles>& st) {
  json rows = json::array();
  for (const auto& f : st) {
    const json& s = f.summary;
    rows.push_back({{"station", s["station"]}, {"ticks_run", s["ticks_run"]}, {"overruns", s["loop"]["overruns"]},
                    {"missed_cycles", s["loop"]["missed_cycles"]}, {"edge_drop_events", s.value("edge_drop_events", json(0))},
                    {"fully_real_time", s["rt"]["fully_real_time"]}, {"rt_warnings", s["rt"]["warnings"]},
                    {"stopped_by_signal", s["stopped_by_signal"]}, {"device", s["device"]}, {"wall_time_s", s["wall_time_s"]},
                    {"exit_code", s.value("exit_code", json(nullptr))}, {"conditions", s.value("conditions", json::array())},
                    {"host", s.value("host", json(nullptr))},
                    {"steps", steps_json(f)}});
  }
  return rows;
}

// Per station: its B_i, eq. (18) minimum, the model's B_i, the passivity flag, final energies, solver.
void add_station_arrays(const std::vector<StationFiles>& st, json& j) {
  for (const char* k : {"damping_Ns_per_m", "damping_min_Ns_per_m", "damping_model_Ns_per_m", "port_energy_final_J", "controller_energy_final_J",
                        "solver", "solver_residual_energy_final_J", "solver_unconverged_ticks"}) {
    json a = json::array();
    for (const auto& s : st) a.push_back(s.summary.value(k, json(nullptr)));
    j[k] = a;
  }
  json met = json::array();
  for (const auto& s : st) met.push_back(s.summary.value("passivity_condition_met", false));
  j["damping_condition_met_per_station"] = met;
}


// d^2 of eq. (13) as the simulator takes it (model::eq13_d2_J): the copies' energies at the first
// common trace tick, the consensus springs of the links from the copies at the first common state
// tick (bounded by lambda_max(P): exact while the copies agree, as they do when every station starts
// from rest) and, under pspm, every edge end's initial reservoir.
double merged_d2_J(const std::vector<StationFiles>& st, std::int64_t trace_k, std::int64_t state_k) {
  const json& s0 = st[0].summary;
  std::vector<double> copies, springs;
  for (const auto& s : st) copies.push_back(s.trace.at(s.trace_row.at(trace_k), "vo_energy_J"));
  const double lambda_P = s0.value("consensus_P_lambda_max_N_per_m", 0.0);
  for (const auto& l : s0.value("topology", json::array())) {  // absent in older station files: no springs counted
    const StationFiles& a = st[static_cast<std::size_t>(l[0].get<int>() - 1)];
    const StationFiles& b = st[static_cast<std::size_t>(l[1].get<int>() - 1)];
    const auto& xa = a.state.rows[a.state_row.at(state_k)];
    const auto& xb = b.state.rows[b.state_row.at(state_k)];
    springs.push_back(model::consensus_spring_bound_J(lambda_P, xa.data() + 1, xb.data() + 1, static_cast<int>(xa.size()) - 1));
  }
  const rt::ConsensusPassivity law = rt::parse_consensus_passivity(s0.value("consensus_passivity", std::string("eq18")), "consensus_passivity");
  return model::eq13_d2_J(copies, springs, model::pspm_reservoirs_J(law, static_cast<int>(springs.size()), s0.value("pspm_reservoir0_J", 0.0)));
}

// The metrics from the stations' records (trace.csv and series.csv written on the way).
RunMetricsResult merged_metrics(const std::vector<StationFiles>& st, const std::string& dir, double& passivity_bound_J) {
  const json& s0 = st[0].summary;
  const double T = s0["dt_s"].get<double>();
  RunMetrics m(metrics_windows_from_json(s0), T);
  const std::vector<double> xd = s0["x_d"].get<std::vector<double>>();
  const Eigen::VectorXd x_d = Eigen::Map<const Eigen::VectorXd>(xd.data(), static_cast<Eigen::Index>(xd.size()));
  OutFile trace = open_out_file(dir + "/trace.csv"), series = open_out_file(dir + "/series.csv");
  write_trace_header(trace.get());
  write_series_header(series.get());
  const auto trace_ks = merge_traces(st, T, m, trace.get());
  const auto state_ks = merge_states(st, x_d, s0.value("trace_node", 0), T, m, series.get());
  if (trace_ks.empty() || state_ks.empty()) throw MergeError("the stations in " + dir + " share no recorded tick");
  merge_station_flags(st, m);
  passivity_bound_J = merged_d2_J(st, trace_ks.front(), state_ks.front());
  return m.result(state_ks.back() + 1);
}

// The copies at the scenario's snapshot times, as the simulator takes them: at the first common
// state tick at or after each time (the last one when the run ended before it), with each proxy
// from the first trace tick at or after that one. Writes DIR/snapshots.json (the simulator's file).
void write_merged_snapshots(const std::vector<StationFiles>& st, double T, const std::string& dir) {
  const json& s0 = st[0].summary;
  if (!s0.contains("snapshot_times_s") || !s0.contains("scene_surface")) return;  // an older station's files
  const std::vector<std::int64_t> ks = common_ticks(st, &StationFiles::state_row), trace_ks = common_ticks(st, &StationFiles::trace_row);
  if (ks.empty() || trace_ks.empty()) return;
  std::vector<Snapshot> snaps;
  for (double t : s0["snapshot_times_s"].get<std::vector<double>>()) {
    auto it = std::find_if(ks.begin(), ks.end(), [&](std::int64_t k) { return static_cast<double>(k + 1) * T >= t - 1e-9; });
    const std::int64_t k = it == ks.end() ? ks.back() : *it;
    if (!snaps.empty() && snaps.back().t_s == static_cast<double>(k + 1) * T) continue;
    auto tr = std::lower_bound(trace_ks.begin(), trace_ks.end(), k);
    const std::int64_t kt = tr == trace_ks.end() ? trace_ks.back() : *tr;
    Snapshot sn;
    sn.t_s = static_cast<double>(k + 1) * T;
    for (const auto& s : st) {
      const std::vector<double>& row = s.state.rows[s.state_row.at(k)];
      sn.x_m.emplace_back(row.begin() + 1, row.end());
      const std::size_t r = s.trace_row.at(kt);
      sn.vp_m.push_back({s.trace.at(r, "vp_x_m"), s.trace.at(r, "vp_y_m"), s.trace.at(r, "vp_z_m")});
    }
    snaps.push_back(std::move(sn));
  }
  std::vector<std::vector<int>> contacts;
  for (const auto& s : st) contacts.push_back(s.summary.value("contact_nodes", std::vector<int>{}));
  write_snapshots_json(dir + "/snapshots.json", s0["scene_surface"].get<std::vector<std::array<int, 3>>>(), contacts, snaps);
}

// What the stations' energy gates and edge-drop rules did, added up (older station files without
// "gate": their trip and drop counts), with the merged run's worst port energy.
GateSummary merged_gate(const std::vector<StationFiles>& st, const json& merged) {
  GateSummary g;
  for (const auto& f : st) {
    const json& s = f.summary;
    auto count = [&](const char* key) { return s.contains(key) && s[key].is_number() ? s[key].get<std::uint64_t>() : std::uint64_t{0}; };
    GateSummary sg = s.contains("gate") ? gate_from_json(s["gate"]) : GateSummary{};
    if (!s.contains("gate")) sg.trips = count("edge_energy_trips"), sg.edge_drop_events = count("edge_drop_events");
    sg.port_energy_min_J.reset();  // a station's own; the run's is the merged total's below
    g += sg;
  }
  if (merged.contains("port_energy_min_J") && merged["port_energy_min_J"].is_number()) g.port_energy_min_J = merged["port_energy_min_J"].get<double>();
  return g;
}

}  // namespace

json merge_run(const std::string& dir) {
  const std::vector<StationFiles> st = load_stations(dir);
  const json& s0 = st[0].summary;
  json j;
  for (const auto& k : scenario_json_keys())
    if (s0.contains(k)) j[k] = s0[k];
  // the coupling law, as the simulator's summary says it (the fingerprint makes every station agree)
  if (s0.contains("consensus_passivity")) j["consensus_passivity"] = s0["consensus_passivity"];
  j["mode"] = "run (" + std::to_string(st.size()) + " processes, " + s0.value("transport", std::string("?")) + ")";
  double d2 = 0;
  const RunMetricsResult m = merged_metrics(st, dir, d2);
  j.update(metrics_json(m));
  j["passivity_bound_J"] = d2;
  j["eq13_broken"] = model::eq13_broken(m.port_energy_min_J, d2);
  add_station_arrays(st, j);
  json links = json::array();
  std::vector<LinkSummary> totals;
  for (const auto& s : st)
    for (const json& rx : s.summary["links"]) {
      totals.emplace_back();
      links.push_back(merged_link(st, s.summary["station"].get<int>(), rx, totals.back()));
    }
  const bool consistent = check_bounds(links);
  bool met = consistent;
  for (const auto& s : st) met = met && s.summary.value("passivity_condition_met", false);
  j["passivity_condition_met"] = met;  // eq. (18) at every station for the bounds enforced at both ends
  j["bounds_consistent_all_links"] = consistent;
  j["packets"] = packets_json(totals);
  j["link_stats"] = links;
  add_windowed_sends(st, j);
  j["stations"] = station_rows(st);
  j["flags"] = merge_flags(st);  // N > N̄ on a link, a starving host: said on the result line too
  const GateSummary gate = merged_gate(st, j);
  j["gate"] = gate_json(gate);
  j["verdict"] = run_verdict(j.value("diverged", false), j.value("unstable", false), gate, j["eq13_broken"].get<bool>());
  write_json_file(dir + "/summary.json", j);
  write_merged_snapshots(st, s0["dt_s"].get<double>(), dir);
  return j;
}

namespace {
// "; FLAGGED: link 2<-1: N max 74 > N̄ 12 (3 edge drops); station 2: host STARVING (...)", or "".
std::string flags_clause(const json& s) {
  if (!s.contains("flags") || s["flags"].empty()) return "";
  std::string t = "; FLAGGED: ";
  for (const auto& f : s["flags"]) t += f.get<std::string>() + "; ";
  return t.substr(0, t.size() - 2);
}
}  // namespace

std::string merge_result_line(const json& s) {
  auto num = [&](const char* k, double scale, const char* unit, const char* none) {
    if (!s.contains(k) || !s[k].is_number()) return std::string(none);
    char b[64];
    std::snprintf(b, sizeof b, "%.4g%s", s[k].get<double>() * scale, unit);
    return std::string(b);
  };
  const std::string gate = s.contains("gate") ? gate_clause(gate_from_json(s["gate"])) : std::string();
  const std::string verdict = s.contains("verdict") ? verdict_words(s["verdict"].get<std::string>()) : s.value("diverged", false) ? "DIVERGED" : "stable";
  return s.value("scenario", std::string("?")) + ": " + verdict + (gate.empty() ? "" : " (" + gate + ")") + ", consensus error at end " +
         num("consensus_error_m", 1e3, " mm", "n/a") + ", consensus time after release " + num("consensus_time_s", 1, " s", "never") + " (< 1 mm), " +
         num("consensus_time_10pct_s", 1, " s", "never") + " (10 %), " + num("consensus_time_1pct_s", 1, " s", "never") +
         " (1 %), hold |sum u| " + num("hold_force_sum_N", 1, " N", "n/a") + " vs mean |u_i| " + num("hold_force_mean_N", 1, " N", "n/a") +
         ", min port energy " + num("port_energy_min_J", 1, " J", "n/a") + " (bound -" + num("passivity_bound_J", 1, " J", "n/a") + "), packets sent " +
         std::to_string(s["packets"]["sent"].get<std::uint64_t>()) + " delivered " + std::to_string(s["packets"]["delivered"].get<std::uint64_t>()) +
         flags_clause(s);
}

}  // namespace haptic::firmware
