#include "firmware/station/edge_events.hpp"

#include <cstdio>

namespace haptic::firmware {

void EdgeEventWatch::push(const EdgeEvent& e) {
  if (!ring_.writer_try_push(e)) dropped_.fetch_add(1, std::memory_order_relaxed);
}

void EdgeEventWatch::after_tick(const rt::StationCore& core, std::int64_t kr) {
  const auto& m = core.edge_monitor();
  const auto& g = core.edge_gate();
  for (int j = 0; j < core.neighbor_count(); ++j) {
    const auto n = static_cast<std::size_t>(j);
    if (m.enabled() && m.isolations(j) != isolations_[n]) {
      isolations_[n] = m.isolations(j);
      push({kr, j, EdgeEventKind::kIsolated, m.last_reason(j), m.trip_node(j), m.trip_value_m(j), isolations_[n], false, 0});
    }
    if (m.enabled() && m.readmissions(j) != readmissions_[n]) {
      readmissions_[n] = m.readmissions(j);
      push({kr, j, EdgeEventKind::kReadmitted, rt::EdgeLie::kNone, -1, 0, readmissions_[n], false, 0});
    }
    if (g.trips(j) != trips_[n]) {
      trips_[n] = g.trips(j);
      push({kr, j, EdgeEventKind::kGateTripped, rt::EdgeLie::kNone, -1, core.edge_energy().edge_J(j), trips_[n], false, g.forgiven_J(j)});
    }
    if (g.releases(j) != releases_[n]) {
      const bool timed = g.timed_releases(j) != timed_[n];
      releases_[n] = g.releases(j);
      timed_[n] = g.timed_releases(j);
      push({kr, j, EdgeEventKind::kGateReleased, rt::EdgeLie::kNone, -1, core.edge_energy().edge_J(j), releases_[n], timed, g.forgiven_J(j)});
    }
  }
}

std::vector<EdgeEvent> EdgeEventWatch::drain() {
  std::vector<EdgeEvent> out;
  EdgeEvent e;
  while (ring_.reader_try_pop(e)) out.push_back(e);
  return out;
}

namespace {

std::string isolated_line(const EdgeEvent& e, int station, const rt::EdgeMonitorParams& p) {
  const bool k = e.reason == rt::EdgeLie::kKinematic;
  char b[400];
  std::snprintf(b, sizeof b,
                "isolated station %d (neighbour state check, isolation %llu): %s (node %d: %.3f mm, %s = %.3f mm); its edge is a damper "
                "until %.3g s of truthful packets",
                station, static_cast<unsigned long long>(e.count), rt::edge_lie_name(e.reason), e.node, 1e3 * e.value,
                k ? "station.state_check_kinematic_m" : "station.state_check_disagreement_m", 1e3 * (k ? p.kinematic_bound_m : p.disagreement_bound_m),
                p.readmit_after_s(e.count));
  return b;
}

std::string gate_line(const EdgeEvent& e, int station, const rt::EdgeEnergyGate& g, double T) {
  char b[400], hold[120] = " until its account falls to the release level";
  if (g.hold_ticks(e.edge) > 0)
    std::snprintf(hold, sizeof hold, " for %.4g s (station.edge_energy_hold_s, doubled per trip)", static_cast<double>(g.hold_after_trip(e.edge, e.count)) * T);
  if (e.kind == EdgeEventKind::kGateTripped)
    std::snprintf(b, sizeof b, "energy gate tripped on station %d's edge (trip %llu): its account %.4g J is over station.edge_energy_bound_J = %.4g J; the edge is a damper%s",
                  station, static_cast<unsigned long long>(e.count), e.value, g.bound_J(e.edge), hold);
  else
    std::snprintf(b, sizeof b, "energy gate released station %d's edge (release %llu, %s; account %.4g J, %.4g J forgiven so far); the trip stays counted",
                  station, static_cast<unsigned long long>(e.count), e.timed ? "its hold ended" : "its account fell to the release level", e.value,
                  e.forgiven_J);
  return b;
}

}  // namespace

std::string edge_event_line(const EdgeEvent& e, int station, const rt::StationCore& core) {
  const double T = core.config().period_s;
  char at[64];
  std::snprintf(at, sizeof at, "run time %.3f s: ", static_cast<double>(e.kr) * T);
  switch (e.kind) {
    case EdgeEventKind::kIsolated: return at + isolated_line(e, station, core.edge_monitor().params());
    case EdgeEventKind::kReadmitted:
      return at + std::string("re-admitted station ") + std::to_string(station) + " (neighbour state check, re-admission " + std::to_string(e.count) +
             "): its packets were truthful for the re-admission time";
    case EdgeEventKind::kGateTripped:
    case EdgeEventKind::kGateReleased: return at + gate_line(e, station, core.edge_gate(), T);
  }
  return at;
}

}  // namespace haptic::firmware
