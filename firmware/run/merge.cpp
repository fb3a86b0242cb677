#include "firmware/run/merge.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
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

// One station's CSV file of numbers (a header line, then rows in increasing tick k, the first
// column), read a row at a time: a merge holds a row per station, whatever the run's length.
class CsvCursor {
 public:
  explicit CsvCursor(const std::string& path) : path_(path), f_(path) {
    if (!f_) throw MergeError("cannot read " + path);
    std::string line, cell;
    if (!std::getline(f_, line)) throw MergeError(path + " is empty (no header line)");
    std::istringstream head(line);
    for (std::size_t i = 0; std::getline(head, cell, ','); ++i) column_[cell] = i;
  }
  // The next row; false at the end of the file. Throws on a malformed row or a tick out of order.
  bool next() {
    while (std::getline(f_, line_)) {
      if (line_.empty()) continue;
      split_numbers();
      if (row_.size() != column_.size())
        throw MergeError(path_ + ": a row has " + std::to_string(row_.size()) + " values, the header " + std::to_string(column_.size()));
      const auto k = static_cast<std::int64_t>(row_[0]);
      if (valid_ && k <= k_) throw MergeError(path_ + ": tick " + std::to_string(k) + " after tick " + std::to_string(k_) + " (rows must be in tick order)");
      k_ = k;
      return valid_ = true;
    }
    return valid_ = false;
  }
  // Steps to the first row at or after tick k; true when that row is tick k.
  bool seek(std::int64_t k) {
    while (valid_ && k_ < k) next();
    return valid_ && k_ == k;
  }
  bool valid() const { return valid_; }
  std::int64_t k() const { return k_; }
  const std::vector<double>& row() const { return row_; }
  bool has(const std::string& name) const { return column_.count(name) > 0; }
  double at(const std::string& name) const { return row_[column_.at(name)]; }

 private:
  // line_'s comma-separated cells as numbers, as strtod reads them (an empty or non-numeric cell
  // reads 0; from_chars, correctly rounded like glibc's strtod, where it takes the whole cell); a
  // comma that ends the line opens no cell.
  void split_numbers() {
    row_.clear();
    const char* p = line_.c_str();
    const char* const end = p + line_.size();
    while (p < end) {
      const void* comma = std::memchr(p, ',', static_cast<std::size_t>(end - p));
      const char* cell_end = comma == nullptr ? end : static_cast<const char*>(comma);
      double v = 0;
      if (std::from_chars(p, cell_end, v).ptr != cell_end) v = std::strtod(p, nullptr);  // anything from_chars does not take whole
      row_.push_back(v);
      if (comma == nullptr) break;
      p = cell_end + 1;
    }
  }

  std::string path_, line_;
  std::ifstream f_;
  std::map<std::string, std::size_t> column_;
  std::vector<double> row_;
  std::int64_t k_ = 0;
  bool valid_ = false;
};

// One station's files: its summary, and the paths of its trace and state CSV files.
struct StationFiles {
  json summary;
  std::string trace_path, state_path;
};

// Reads DIR/station-<i>.json (i = 1..N, N from the first) and checks its CSV files' headers;
// refuses a station that reported an error.
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
    s.trace_path = base + "-trace.csv";
    s.state_path = base + "-state.csv";
    CsvCursor{s.trace_path}, CsvCursor{s.state_path};  // both readable, with a header
    st.push_back(std::move(s));
  }
  return st;
}

// Every station's file of one kind (trace or state), stepped together through the ticks all of them
// recorded, in increasing k.
class CommonTicks {
 public:
  CommonTicks(const std::vector<StationFiles>& st, std::string StationFiles::*path) {
    for (const auto& s : st) files_.emplace_back(s.*path);
  }
  // The next tick every file has; false when one file has ended.
  bool next() {
    for (auto& f : files_)
      if (!f.next()) return false;
    for (;;) {
      std::int64_t k = files_[0].k();
      for (const auto& f : files_) k = std::max(k, f.k());
      bool all = true;
      for (auto& f : files_) {
        f.seek(k);
        if (!f.valid()) return false;
        all = all && f.k() == k;
      }
      if (all) return true;
    }
  }
  std::int64_t k() const { return files_[0].k(); }
  const CsvCursor& operator[](std::size_t i) const { return files_[i]; }

 private:
  std::vector<CsvCursor> files_;
};

Eigen::Vector3d trace_force(const CsvCursor& c) { return {c.at("force_x_N"), c.at("force_y_N"), c.at("force_z_N")}; }

// What the passes over the files keep of the first common ticks (eq. 13's d^2 is taken there).
struct FirstTicks {
  std::optional<std::int64_t> trace_k, state_k;
  std::int64_t last_state_k = 0;
  std::vector<double> vo_energy_J;             // per station, at the first common trace tick
  std::vector<std::vector<double>> state_rows;  // per station, at the first common state tick (k, x...)
};

// Forces and energies at every common trace tick; trace.csv rows.
void merge_traces(const std::vector<StationFiles>& st, double T, RunMetrics& m, std::FILE* trace, FirstTicks& first) {
  CommonTicks ct(st, &StationFiles::trace_path);
  std::vector<Eigen::Vector3d> forces(st.size());
  static const char* names[] = {"node_x_m", "node_y_m", "node_z_m", "vp_x_m", "vp_y_m", "vp_z_m", "device_x_m", "device_y_m", "device_z_m"};
  while (ct.next()) {
    const std::int64_t k = ct.k();
    if (!first.trace_k) {
      first.trace_k = k;
      for (std::size_t i = 0; i < st.size(); ++i) first.vo_energy_J.push_back(ct[i].at("vo_energy_J"));
    }
    model::StationTotals total;
    for (std::size_t i = 0; i < st.size(); ++i) {
      const CsvCursor& c = ct[i];
      forces[i] = trace_force(c);
      total.add_energies(c.at("port_energy_J"), c.at("controller_energy_J"));
      TraceRow row;
      row.t_s = static_cast<double>(k + 1) * T;
      row.user = static_cast<int>(i) + 1;
      for (int a = 0; a < 3; ++a) {
        row.node[a] = c.at(names[a]);
        row.force[a] = forces[i][a];
        row.vp[a] = c.at(names[3 + a]);
        row.device[a] = c.at(names[6 + a]);
      }
      row.port_J = c.at("port_energy_J");
      row.ctrl_J = c.at("controller_energy_J");
      row.vo_J = c.at("vo_energy_J");
      row.contact = c.at("contact") != 0;
      write_trace_row(trace, row);
    }
    m.add_forces(k, forces);
    m.add_energies(total.port_J, total.controller_J);
  }
}

// Forces and energies of the stations' traces at state tick k when every station traced it.
void add_traced(std::vector<CsvCursor>& traces, std::int64_t k, SeriesRow& row) {
  bool traced = true;
  for (auto& c : traces) traced = c.seek(k) && traced;
  if (!traced) return;
  model::StationTotals total;
  std::vector<Eigen::Vector3d> forces;
  for (const auto& c : traces) {
    forces.push_back(trace_force(c));
    total.add_force(forces.back());
    total.add_energies(c.at("port_energy_J"), c.at("controller_energy_J"));
  }
  row.port_total_J = total.port_J;
  row.ctrl_total_J = total.controller_J;
  row.force_sum_x_N = total.force_N[0];
  row.force_sum_norm_N = total.force_N.norm();
  row.set_forces(model::force_balance(forces));
}

// The snapshots' copies: at the first common state tick at or after each time (the last one when the
// run ended before it), and each proxy at the first common trace tick at or after that one.
struct SnapshotPicks {
  std::vector<double> times_s;
  std::vector<std::optional<std::int64_t>> k;         // per time: the state tick taken
  std::vector<std::vector<std::vector<double>>> x;    // per time, per station: the state row (k, x...)
  std::vector<std::vector<std::array<double, 3>>> vp;  // per time, per station (filled by pick_snapshot_proxies)
  std::vector<std::vector<double>> last_rows;         // the last common state tick's rows
  void take(const CommonTicks& ct, std::size_t n, double T) {
    if (times_s.empty()) return;  // no snapshot asked for: nothing to keep
    for (std::size_t p = 0; p < times_s.size(); ++p)
      if (!k[p] && static_cast<double>(ct.k() + 1) * T >= times_s[p] - 1e-9) k[p] = ct.k(), x[p] = rows(ct, n);
    last_rows.resize(n);
    for (std::size_t i = 0; i < n; ++i) last_rows[i] = ct[i].row();  // in place: the rows' storage is reused tick after tick
  }
  static std::vector<std::vector<double>> rows(const CommonTicks& ct, std::size_t n) {
    std::vector<std::vector<double>> r;
    for (std::size_t i = 0; i < n; ++i) r.push_back(ct[i].row());
    return r;
  }
};

// The copies at every common state tick; series.csv rows (energies and forces where all traced).
void merge_states(const std::vector<StationFiles>& st, const Eigen::VectorXd& x_d, int trace_node, double T, RunMetrics& m, std::FILE* series,
                  FirstTicks& first, SnapshotPicks& snaps) {
  CommonTicks ct(st, &StationFiles::state_path);
  std::vector<CsvCursor> traces;
  for (const auto& s : st) traces.emplace_back(s.trace_path);
  for (auto& c : traces) c.next();
  std::vector<const double*> x(st.size());
  while (ct.next()) {
    const std::int64_t k = first.last_state_k = ct.k();
    if (!first.state_k) first.state_k = k, first.state_rows = SnapshotPicks::rows(ct, st.size());
    snaps.take(ct, st.size(), T);
    for (std::size_t i = 0; i < st.size(); ++i) x[i] = ct[i].row().data() + 1;
    const CopiesSample c = measure_copies(x, x_d);
    m.add_copies(k, c);
    SeriesRow row{static_cast<double>(k + 1) * T, c.consensus_error_m, c.deformation_m, NAN, NAN, NAN, NAN};
    const Eigen::Vector3d node = model::mean_node_position_m(x, trace_node);
    for (int a = 0; a < 3; ++a) row.trace_node_mean_m[a] = node[a];
    add_traced(traces, k, row);
    write_series_row(series, row);
  }
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

// What one pass over a station's own trace (every row it wrote, not only the common ticks) gives:
// its steps T_k and the states it pushed in two windows of run time.
struct TraceScan {
  json steps;                     // min/mean/max of step_s and the integrated time's drift from the grid, or null
  json sent_in_hold, sent_after;  // states it pushed in the hold window and after consensus, or null
};

// Station f's trace scanned once: the steps T_k it integrated with, from step_s (null: an older
// trace without it): smallest, mean, largest over the traced ticks, and, when every tick was traced,
// how far the integrated time (the sum of T_k) ran from the tick grid (ticks x T) by the last one.
// The merged metrics stay on the common tick grid (the stations' ticks are scheduled on it, so
// copies are compared at the same wall time); this says how the variable-step integration kept pace
// with it. And the states it pushed at run ticks k with t0 <= k T < t1 in each window: the
// kTraceStateSent bits of its trace (run/summary.hpp), as the simulator's sent_between counts them;
// null when the trace does not hold every tick or predates the bit.
TraceScan scan_trace(const StationFiles& f, const std::array<double, 2>& hold, const std::array<double, 2>& after) {
  const double T = f.summary["dt_s"].get<double>();
  const bool every = f.summary.value("trace_every", 1) == 1;
  const bool marks = f.summary.value("trace_marks_state_sent", false) && f.summary.value("trace_every", 0) == 1;
  CsvCursor c(f.trace_path);
  const bool steps = c.has("step_s");
  double lo = INFINITY, hi = 0, sum = 0, n = 0;
  std::uint64_t in_hold = 0, in_after = 0;
  while (c.next()) {
    if (steps) {
      const double t = c.at("step_s");
      lo = std::min(lo, t), hi = std::max(hi, t), sum += t, n += 1;
    }
    if (!marks || !(static_cast<std::uint32_t>(c.at("flags")) & kTraceStateSent)) continue;
    const double t = static_cast<double>(c.k()) * T;
    in_hold += t >= hold[0] - 1e-9 && t < hold[1] - 1e-9;
    in_after += t >= after[0] - 1e-9 && t < after[1] - 1e-9;
  }
  TraceScan s;
  s.steps = !steps || n == 0 ? json(nullptr)
                             : json{{"min_s", lo}, {"mean_s", sum / n}, {"max_s", hi}, {"integrated_minus_grid_s", every ? json(sum - n * T) : json(nullptr)}};
  s.sent_in_hold = marks ? json(in_hold) : json(nullptr);
  s.sent_after = marks ? json(in_after) : json(nullptr);
  return s;
}

// The merged run's hold window and its time after consensus (to the end of the run), in s.
struct SendWindows {
  double T;
  std::array<double, 2> hold, after;
};

SendWindows send_windows(const std::vector<StationFiles>& st, const json& j) {
  const double T = st[0].summary["dt_s"].get<double>();
  const double end = static_cast<double>(st[0].summary["ticks_run"].get<std::int64_t>() + 1) * T;
  const auto& hw = j["hold_window_s"];
  const bool settled = j["consensus_time_s"].is_number();
  const double from = settled ? j["release_time_s"].get<double>() + j["consensus_time_s"].get<double>() : end;
  return {T, {hw[0].get<double>(), hw[1].get<double>()}, {from, end}};
}

// Per station, scan_trace() over the merged run's send windows.
std::vector<TraceScan> scan_traces(const std::vector<StationFiles>& st, const SendWindows& w) {
  std::vector<TraceScan> out;
  for (const auto& f : st) out.push_back(scan_trace(f, w.hold, w.after));
  return out;
}

// Per link, the states its sender pushed in the hold window and after consensus (every state goes
// to every neighbour), and their totals in `packets`, like the simulator's summary.
void add_windowed_sends(const SendWindows& w, const std::vector<TraceScan>& scans, json& j) {
  json hold_total = 0, after_total = 0;
  for (json& l : j["link_stats"]) {
    const TraceScan& s = scans[static_cast<std::size_t>(l["from"].get<int>() - 1)];
    l["sent_in_hold_window"] = s.sent_in_hold;
    l["sent_after_consensus"] = s.sent_after;
    for (auto [key, total] : {std::pair<const char*, json*>{"sent_in_hold_window", &hold_total}, {"sent_after_consensus", &after_total}})
      *total = l[key].is_null() || total->is_null() ? json(nullptr) : json(total->get<std::uint64_t>() + l[key].get<std::uint64_t>());
  }
  j["packets"]["sent_in_hold_window"] = hold_total;
  j["packets"]["sent_after_consensus"] = after_total;
  j["packets"]["after_consensus_s"] = std::max(0.0, w.after[1] - w.T - w.after[0]);
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

json station_rows(const std::vector<StationFiles>& st, const std::vector<TraceScan>& scans) {
  json rows = json::array();
  for (std::size_t i = 0; i < st.size(); ++i) {
    const json& s = st[i].summary;
    rows.push_back({{"station", s["station"]}, {"ticks_run", s["ticks_run"]}, {"overruns", s["loop"]["overruns"]},
                    {"missed_cycles", s["loop"]["missed_cycles"]}, {"edge_drop_events", s.value("edge_drop_events", json(0))},
                    {"fully_real_time", s["rt"]["fully_real_time"]}, {"rt_warnings", s["rt"]["warnings"]},
                    {"stopped_by_signal", s["stopped_by_signal"]}, {"device", s["device"]}, {"wall_time_s", s["wall_time_s"]},
                    {"exit_code", s.value("exit_code", json(nullptr))}, {"conditions", s.value("conditions", json::array())},
                    {"host", s.value("host", json(nullptr))},
                    {"steps", scans[i].steps}});
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
double merged_d2_J(const std::vector<StationFiles>& st, const FirstTicks& first) {
  const json& s0 = st[0].summary;
  std::vector<double> springs;
  const double lambda_P = s0.value("consensus_P_lambda_max_N_per_m", 0.0);
  for (const auto& l : s0.value("topology", json::array())) {  // absent in older station files: no springs counted
    const auto& xa = first.state_rows[static_cast<std::size_t>(l[0].get<int>() - 1)];
    const auto& xb = first.state_rows[static_cast<std::size_t>(l[1].get<int>() - 1)];
    springs.push_back(model::consensus_spring_bound_J(lambda_P, xa.data() + 1, xb.data() + 1, static_cast<int>(xa.size()) - 1));
  }
  const rt::ConsensusPassivity law = rt::parse_consensus_passivity(s0.value("consensus_passivity", std::string("eq18")), "consensus_passivity");
  return model::eq13_d2_J(first.vo_energy_J, springs, model::pspm_reservoirs_J(law, static_cast<int>(springs.size()), s0.value("pspm_reservoir0_J", 0.0)));
}

// The snapshot times a run's stations name (none for an older station's files).
SnapshotPicks snapshot_picks(const json& s0) {
  SnapshotPicks p;
  if (!s0.contains("snapshot_times_s") || !s0.contains("scene_surface")) return p;
  p.times_s = s0["snapshot_times_s"].get<std::vector<double>>();
  p.k.resize(p.times_s.size());
  p.x.resize(p.times_s.size());
  return p;
}

// The metrics from the stations' records (trace.csv and series.csv written on the way), and the
// snapshots' copies picked on the way.
RunMetricsResult merged_metrics(const std::vector<StationFiles>& st, const std::string& dir, double& passivity_bound_J, SnapshotPicks& snaps) {
  const json& s0 = st[0].summary;
  const double T = s0["dt_s"].get<double>();
  RunMetrics m(metrics_windows_from_json(s0), T);
  const std::vector<double> xd = s0["x_d"].get<std::vector<double>>();
  const Eigen::VectorXd x_d = Eigen::Map<const Eigen::VectorXd>(xd.data(), static_cast<Eigen::Index>(xd.size()));
  OutFile trace = open_out_file(dir + "/trace.csv"), series = open_out_file(dir + "/series.csv");
  write_trace_header(trace.get());
  write_series_header(series.get());
  FirstTicks first;
  merge_traces(st, T, m, trace.get(), first);
  merge_states(st, x_d, s0.value("trace_node", 0), T, m, series.get(), first, snaps);
  if (!first.trace_k || !first.state_k) throw MergeError("the stations in " + dir + " share no recorded tick");
  merge_station_flags(st, m);
  passivity_bound_J = merged_d2_J(st, first);
  return m.result(first.last_state_k + 1);
}

// Each snapshot's proxies: at the first common trace tick at or after its state tick (the last
// common trace tick when there is none), one more pass over the traces.
void pick_snapshot_proxies(const std::vector<StationFiles>& st, SnapshotPicks& p) {
  p.vp.assign(p.times_s.size(), {});
  CommonTicks ct(st, &StationFiles::trace_path);
  std::vector<std::array<double, 3>> last;
  auto proxies = [&] {
    std::vector<std::array<double, 3>> v;
    for (std::size_t i = 0; i < st.size(); ++i) v.push_back({ct[i].at("vp_x_m"), ct[i].at("vp_y_m"), ct[i].at("vp_z_m")});
    return v;
  };
  while (ct.next()) {
    last = proxies();
    for (std::size_t s = 0; s < p.times_s.size(); ++s)
      if (p.vp[s].empty() && ct.k() >= *p.k[s]) p.vp[s] = last;
  }
  for (auto& v : p.vp)
    if (v.empty()) v = last;
}

// The copies at the scenario's snapshot times, as the simulator takes them (SnapshotPicks). Writes
// DIR/snapshots.json (the simulator's file).
void write_merged_snapshots(const std::vector<StationFiles>& st, double T, const std::string& dir, SnapshotPicks& p) {
  if (p.times_s.empty()) return;
  for (std::size_t s = 0; s < p.times_s.size(); ++s)
    if (!p.k[s]) p.k[s] = static_cast<std::int64_t>(p.last_rows[0][0]), p.x[s] = p.last_rows;  // the run ended before it
  pick_snapshot_proxies(st, p);
  std::vector<Snapshot> snaps;
  for (std::size_t s = 0; s < p.times_s.size(); ++s) {
    const double t = static_cast<double>(*p.k[s] + 1) * T;
    if (!snaps.empty() && snaps.back().t_s == t) continue;
    Snapshot sn;
    sn.t_s = t;
    for (std::size_t i = 0; i < st.size(); ++i) {
      sn.x_m.emplace_back(p.x[s][i].begin() + 1, p.x[s][i].end());
      sn.vp_m.push_back(p.vp[s][i]);
    }
    snaps.push_back(std::move(sn));
  }
  std::vector<std::vector<int>> contacts;
  for (const auto& f : st) contacts.push_back(f.summary.value("contact_nodes", std::vector<int>{}));
  write_snapshots_json(dir + "/snapshots.json", st[0].summary["scene_surface"].get<std::vector<std::array<int, 3>>>(), contacts, snaps);
}

// The receiver's neighbour-state-check entry for neighbour `from` (station-<id>.json "state_check"), or null.
const json* state_check_entry(const json& s, int from) {
  if (!s.contains("state_check") || !s["state_check"].contains("neighbours")) return nullptr;
  for (const json& n : s["state_check"]["neighbours"])
    if (n.value("station", 0) == from) return &n;
  return nullptr;
}

// What the resilient rule and the neighbour state check did, as the stations counted it: per link
// (to <- from) the receiver's resilient_excluded_ticks (with the rule on) and its state check's
// isolations, readmissions and isolated ticks; per station row their sums; the run's totals
// ("resilient_excluded_ticks" with the rule on anywhere, "state_check" when the stations have the
// check); each isolation is a flag (a safeguard that acted is said on the result line).
void add_edge_safeguards(const std::vector<StationFiles>& st, json& j) {
  std::uint64_t excluded = 0, isolations = 0, readmissions = 0, isolated_ticks = 0;
  bool rule = false, check = false;
  for (json& l : j["link_stats"]) {
    const json& s = st[static_cast<std::size_t>(l["to"].get<int>() - 1)].summary;
    const int from = l["from"].get<int>();
    for (const json& rx : s["links"])
      if (rx["peer"].get<int>() == from && rx.contains("resilient_excluded_ticks")) {
        l["resilient_excluded_ticks"] = rx["resilient_excluded_ticks"];
        excluded += rx["resilient_excluded_ticks"].get<std::uint64_t>(), rule = true;
      }
    if (const json* n = state_check_entry(s, from)) {
      for (const char* k : {"isolations", "readmissions", "isolated_ticks"}) l["state_check_" + std::string(k)] = n->value(k, std::uint64_t{0});
      isolations += n->value("isolations", std::uint64_t{0}), readmissions += n->value("readmissions", std::uint64_t{0});
      isolated_ticks += n->value("isolated_ticks", std::uint64_t{0}), check = true;
      if (n->value("isolations", std::uint64_t{0}) > 0)
        j["flags"].push_back("station " + std::to_string(l["to"].get<int>()) + " isolated station " + std::to_string(from) + " " +
                             std::to_string(n->value("isolations", std::uint64_t{0})) + " time(s) (neighbour state check: " +
                             n->value("reason", std::string("?")) + ")");
    }
  }
  for (json& row : j["stations"]) {
    const json& s = st[static_cast<std::size_t>(row["station"].get<int>() - 1)].summary;
    json sum = nullptr;
    for (const json& rx : s["links"])
      if (rx.contains("resilient_excluded_ticks")) sum = (sum.is_null() ? std::uint64_t{0} : sum.get<std::uint64_t>()) + rx["resilient_excluded_ticks"].get<std::uint64_t>();
    row["resilient_excluded_ticks"] = sum;
    row["state_check_isolations"] = s.contains("state_check") ? s["state_check"].value("isolations", json(nullptr)) : json(nullptr);
  }
  if (rule) j["resilient_excluded_ticks"] = excluded;
  if (check) j["state_check"] = {{"isolations", isolations}, {"readmissions", readmissions}, {"isolated_ticks", isolated_ticks}};
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
  SnapshotPicks snaps = snapshot_picks(s0);
  const RunMetricsResult m = merged_metrics(st, dir, d2, snaps);
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
  const SendWindows windows = send_windows(st, j);
  const std::vector<TraceScan> scans = scan_traces(st, windows);
  add_windowed_sends(windows, scans, j);
  j["stations"] = station_rows(st, scans);
  j["flags"] = merge_flags(st);  // N > N̄ on a link, a starving host: said on the result line too
  add_edge_safeguards(st, j);  // the resilient rule's exclusions, the state check's isolations (flagged)
  const GateSummary gate = merged_gate(st, j);
  j["gate"] = gate_json(gate);
  j["verdict"] = run_verdict(j.value("diverged", false), j.value("unstable", false), gate, j["eq13_broken"].get<bool>());
  write_json_file(dir + "/summary.json", j);
  write_merged_snapshots(st, s0["dt_s"].get<double>(), dir, snaps);
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
