#include "firmware/station/state_check.hpp"

#include <cmath>
#include <cstdio>

namespace haptic::firmware {

namespace {

const char* reason_text(rt::EdgeLie lie) {
  switch (lie) {
    case rt::EdgeLie::kKinematic: return "its reported positions moved more than its own reported velocities explain";
    case rt::EdgeLie::kDisagreement: return "its reported state stayed far from this copy";
    case rt::EdgeLie::kNone: break;
  }
  return "no reason";
}

const char* reason_key(rt::EdgeLie lie) {
  return lie == rt::EdgeLie::kKinematic ? "station.state_check_kinematic_m" : "station.state_check_disagreement_m";
}

double bound_of(const rt::EdgeMonitorParams& p, rt::EdgeLie lie) {
  return lie == rt::EdgeLie::kKinematic ? p.kinematic_bound_m : p.disagreement_bound_m;
}

std::string isolation_line(int station, const rt::EdgeMonitor& m, int j, double T) {
  const rt::EdgeLie why = m.last_reason(j);
  char b[512];
  std::snprintf(b, sizeof b,
                "neighbour state check: station %d isolated %llu time(s), last at run time %.3f s: %s (node %d: %.3f mm, %s = %.3f mm); "
                "its edge acted as a damper for %llu ticks (%.3f s)",
                station, static_cast<unsigned long long>(m.isolations(j)), static_cast<double>(m.last_isolated_k(j)) * T, reason_text(why),
                m.trip_node(j), 1e3 * m.trip_value_m(j), reason_key(why), 1e3 * bound_of(m.params(), why),
                static_cast<unsigned long long>(m.isolated_ticks(j)), static_cast<double>(m.isolated_ticks(j)) * T);
  std::string line = b;
  if (m.readmissions(j) > 0) {
    std::snprintf(b, sizeof b, "; re-admitted %llu time(s), last at run time %.3f s", static_cast<unsigned long long>(m.readmissions(j)),
                  static_cast<double>(m.last_readmitted_k(j)) * T);
    line += b;
  }
  line += m.isolated(j) ? "; still isolated at the end of the run" : "";
  return line;
}

}  // namespace

std::vector<std::string> state_check_messages(const StationPlan& plan, const rt::StationCore& core) {
  std::vector<std::string> lines;
  const auto& m = core.edge_monitor();
  const auto& nbrs = plan.neighbours();
  const double T = core.config().period_s;
  int isolated_now = 0;
  for (int j = 0; j < core.neighbor_count() && j < static_cast<int>(nbrs.size()); ++j) {
    if (m.isolated(j)) ++isolated_now;
    if (m.isolations(j) > 0) lines.push_back(isolation_line(nbrs[static_cast<std::size_t>(j)] + 1, m, j, T));
  }
  if (core.neighbor_count() > 0 && isolated_now == core.neighbor_count()) {
    std::string who;
    for (int j = 0; j < core.neighbor_count(); ++j) who += (who.empty() ? "station " : ", station ") + std::to_string(nbrs[static_cast<std::size_t>(j)] + 1);
    lines.push_back("neighbour state check: every neighbour of this station (" + who +
                    ") was isolated at the end of the run: this station stopped coupling and held its own copy alone");
  }
  return lines;
}

nlohmann::json state_check_json(const StationPlan& plan, const rt::StationCore& core) {
  using nlohmann::json;
  const auto& m = core.edge_monitor();
  const auto& p = m.params();
  auto finite_or_null = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json j = {{"enabled", m.enabled()},
            {"kinematic_bound_m", finite_or_null(p.kinematic_bound_m)},
            {"kinematic_window_s", p.kinematic_window_s},
            {"max_gap_ticks", p.max_gap_ticks},
            {"max_checked_gap_ticks", p.max_checked_gap_ticks},
            {"disagreement_bound_m", finite_or_null(p.disagreement_bound_m)},
            {"disagreement_window_s", p.disagreement_window_s},
            {"readmit_s", p.readmit_s},
            {"isolations", m.isolations()}};
  const auto& nbrs = plan.neighbours();
  const double T = core.config().period_s;
  const bool disagreement_on = std::isfinite(p.disagreement_bound_m);
  json per = json::array();
  for (int n = 0; n < m.edges() && n < static_cast<int>(nbrs.size()); ++n) {
    json e = {{"station", nbrs[static_cast<std::size_t>(n)] + 1},
              {"isolations", m.isolations(n)},
              {"readmissions", m.readmissions(n)},
              {"isolated_ticks", m.isolated_ticks(n)},
              {"isolated_at_end", m.isolated(n)},
              {"peak_kinematic_m", m.peak_kinematic_m(n)},
              {"peak_disagreement_m", disagreement_on ? json(m.peak_disagreement_m(n)) : json(nullptr)},  // P off: not filtered while admitted
              {"gap_checks", m.gap_checks(n)},
              {"peak_gap_ratio", m.peak_gap_ratio(n)},
              {"unchecked_gaps", m.unchecked_gaps(n)},
              {"step_bounds_s", {m.step_box(n).min_s, m.step_box(n).max_s}}};  // the neighbour's T^min, T^max K fits within
    if (m.isolations(n) > 0) {
      e["reason"] = rt::edge_lie_name(m.last_reason(n));
      e["last_isolated_run_s"] = static_cast<double>(m.last_isolated_k(n)) * T;
      e["trip_node"] = m.trip_node(n);
      e["trip_value_m"] = m.trip_value_m(n);
    }
    per.push_back(std::move(e));
  }
  j["neighbours"] = std::move(per);
  return j;
}

}  // namespace haptic::firmware
