#include "firmware/station/explain.hpp"

#include <cstdio>

namespace haptic::firmware {

namespace {

using nlohmann::json;

std::string num(double v, int digits = 3) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

std::string station_name(const StationOutcome& o, int n) { return "station " + std::to_string(o.plan->neighbours()[static_cast<std::size_t>(n)] + 1); }

double period_s(const StationOutcome& o) { return o.plan->built->spec.period_s; }

// Run time (s from the run start) at the end of run tick kr.
double run_time_s(const StationOutcome& o, std::int64_t kr) { return static_cast<double>(kr + 1) * period_s(o); }

// One link in a span: silent (no packet arrived in it) or late (packets arrived, the newest older than N̄).
std::string span_link_text(const StationOutcome& o, const OutageSpan& s, int n) {
  const std::string age = "its newest data " + std::to_string(s.age_ticks[n]) + " ticks old against N̄ = " + std::to_string(s.bound_ticks[n]);
  if (s.packets[n] == 0) return station_name(o, n) + " SILENT (no packet arrived in it; " + age + ")";
  return station_name(o, n) + " LATE (" + std::to_string(s.packets[n]) + " packets arrived, " + age + ")";
}

// Whether this host missed a deadline in the span: a tick overran, skipped periods, or woke a
// period or more late.
bool span_host_starving(const StationOutcome& o, const OutageSpan& s) {
  return s.overruns > 0 || s.missed_cycles > 0 || static_cast<double>(s.wake_max_ns) * 1e-9 >= period_s(o);
}

std::string span_host_text(const StationOutcome& o, const OutageSpan& s) {
  const std::string figures = "latest wake-up " + num(static_cast<double>(s.wake_max_ns) * 1e-6) + " ms, " + std::to_string(s.overruns) + " overruns, " +
                              std::to_string(s.missed_cycles) + " skipped periods";
  return (span_host_starving(o, s) ? "this host was STARVING in it (" : "this host kept its period in it (") + figures + ")";
}

std::string span_text(const StationOutcome& o, const OutageSpan& s) {
  std::string t = num(run_time_s(o, s.first_kr - 1), 4) + "-" + num(run_time_s(o, s.last_kr), 4) + " s of the run (" + std::to_string(s.ticks) + " ticks): ";
  for (int n = 0; n < s.links; ++n) t += span_link_text(o, s, n) + "; ";
  return t + span_host_text(o, s);
}

json span_json(const StationOutcome& o, const OutageSpan& s) {
  if (s.empty()) return nullptr;
  json links = json::array();
  for (int n = 0; n < s.links; ++n)
    links.push_back({{"peer", o.plan->neighbours()[static_cast<std::size_t>(n)] + 1}, {"packets", s.packets[n]}, {"age_ticks", s.age_ticks[n]},
                     {"nbar_ticks", s.bound_ticks[n]}, {"cause", s.packets[n] == 0 ? "silent" : "late"}});
  return {{"from_s", run_time_s(o, s.first_kr - 1)}, {"to_s", run_time_s(o, s.last_kr)}, {"ticks", s.ticks},
          {"host_starving", span_host_starving(o, s)}, {"wake_max_ms", static_cast<double>(s.wake_max_ns) * 1e-6},
          {"overruns", s.overruns}, {"missed_cycles", s.missed_cycles}, {"links", links}};
}

// Exit 7 from the run (not from probing): the spans, the first and the longest named.
void explain_no_neighbour(const StationOutcome& o, const RunConditions& c, Explanation& e) {
  const OutageTracker& t = o.counters->outages;
  e.json["no_neighbour_spans"] = {{"count", t.spans()}, {"first", span_json(o, t.first())}, {"longest", span_json(o, t.longest())}};
  if (t.spans() == 0) return;
  e.lines.push_back("no usable neighbour in " + num(100 * c.no_neighbour_fraction.value_or(0)) + " % of the run ticks (limit station.max_no_neighbour_fraction = " +
                    num(100 * o.plan->file.station.max_no_neighbour_fraction) + " %), in " + std::to_string(t.spans()) + " span(s)");
  e.lines.push_back("the longest: " + span_text(o, t.longest()));
  if (t.spans() > 1 && t.first().first_kr != t.longest().first_kr) e.lines.push_back("the first: " + span_text(o, t.first()));
}

// Exit 11: the longest stall, when it ended.
void explain_stall(const StationOutcome& o, Explanation& e) {
  const OutageTracker& t = o.counters->outages;
  if (t.largest_skip_cycles() == 0) return;
  const double len_s = static_cast<double>(t.largest_skip_cycles()) * period_s(o);
  const double end_s = run_time_s(o, t.largest_skip_end_kr() - 1);
  e.json["longest_stall"] = {{"periods", t.largest_skip_cycles()}, {"seconds", len_s}, {"from_s", end_s - len_s}, {"to_s", end_s}};
  e.lines.push_back("the longest stall: " + std::to_string(t.largest_skip_cycles()) + " periods skipped at once (" + num(len_s) + " s), " + num(end_s - len_s, 4) +
                    "-" + num(end_s, 4) + " s of the run: this station's tick did not run, so its neighbours saw it silent");
}

// Per link over the run: the largest index delay N against N̄, and the edge drops (N > N̄ while coupled).
void explain_links(const StationOutcome& o, Explanation& e) {
  const rt::StationCore* core = o.build ? o.build->core.get() : nullptr;
  if (core == nullptr || o.counters == nullptr || o.counters->ticks_run == 0) return;
  if (core->neighbor_count() == 0) {  // solo: no link to explain
    e.json["links"] = json::array();
    return;
  }
  std::string t = "links over the run:";
  json links = json::array();
  for (int n = 0; n < core->neighbor_count(); ++n) {
    const auto& rc = core->rx(n).counters();
    const std::int64_t nbar = core->neighbor(n).index_delay_bound_ticks;
    t += " " + station_name(o, n) + " N max " + std::to_string(rc.max_index_delay) + (rc.max_index_delay > nbar ? " > " : " <= ") + "N̄ " +
         std::to_string(nbar) + ", " + std::to_string(core->edge_drop_events(n)) + " edge drops;";
    links.push_back({{"peer", o.plan->neighbours()[static_cast<std::size_t>(n)] + 1}, {"max_index_delay_ticks", rc.max_index_delay}, {"nbar_ticks", nbar},
                     {"over_nbar", rc.max_index_delay > nbar}, {"edge_drops", core->edge_drop_events(n)}});
  }
  t.pop_back();
  e.lines.push_back(t);
  e.json["links"] = links;
}

// The cause line of the exits whose cause is one figure (4, 5, 6, 8, 10, 3).
void explain_cause(const StationOutcome& o, const RunConditions& c, int code, Explanation& e) {
  const TickCounters* k = o.counters;
  if (code == kExitDiverged && k) e.lines.push_back("diverged at " + num(k->diverged_at_s, 4) + " s of the run (a node faster than station.divergence_speed_m_per_s)");
  if (code == kExitSafeState && k && k->device_fault_ticks > 0)
    e.lines.push_back("the device gave no sample in " + std::to_string(k->device_fault_ticks) + " ticks (device fault: " + o.device_fault + ")");
  if (code == kExitPassivityNotMet && o.build) {
    std::string t = "B_i " + num(o.build->bounds.damping_Ns_per_m) + " N s/m below eq. (18)'s " + num(o.build->bounds.damping_min_Ns_per_m) +
                    " N s/m on the measured round-trip bounds:";
    for (std::size_t n = 0; n < o.build->bounds.round_trip_ticks.size(); ++n)
      t += " " + station_name(o, static_cast<int>(n)) + " " + std::to_string(o.build->bounds.round_trip_ticks[n]) + " ticks;";
    t.pop_back();
    e.lines.push_back(t);
  }
  if (code == kExitBeforeRelease && k)
    e.lines.push_back("the run ended at " + num(c.ran_s, 4) + " s, before the scripted release at " +
                      num(o.plan->built->spec.script.release_s, 4) + " s");
  if (code == kExitHeldByGate && o.build && o.build->core) {
    std::string t = "the per-edge energy gate (station.edge_energy_bound_J) tripped:";
    for (int n = 0; n < o.build->core->neighbor_count(); ++n)
      t += " " + station_name(o, n) + " " + std::to_string(o.build->core->edge_gate().trips(n)) + " trips;";
    t.pop_back();
    e.lines.push_back(t);
  }
  (void)c;
}

}  // namespace

HostTiming host_timing(const StationOutcome& o) {
  HostTiming h;
  h.period_ms = o.plan ? o.plan->built->spec.period_s * 1e3 : 0;
  if (o.run != nullptr && o.run->loop.ticks > 0) {
    const LoopCounts& s = o.run->loop;                                   // the run's share of the loop
    const platform::LatencyHistogram& w = o.run->whole_loop.wake_latency;  // the loop's wake-ups (probe to run)
    h.loop = "run";
    h.ticks = s.ticks, h.overruns = s.overruns, h.missed_cycles = s.missed_cycles;
    h.have_latency = true;
    h.wake_p99_ms = static_cast<double>(w.percentile_ns(0.99)) * 1e-6;
    h.wake_max_ms = static_cast<double>(w.max_ns) * 1e-6;
    h.starving = platform::host_starving(s.ticks, s.missed_cycles, w.percentile_ns(0.99), static_cast<std::int64_t>(h.period_ms * 1e6));
  } else if (o.probe != nullptr) {
    h.loop = "probe";
    h.ticks = o.probe->loop_ticks, h.overruns = o.probe->loop_overruns, h.missed_cycles = o.probe->loop_missed_cycles;
    h.starving = platform::host_starving(h.ticks, h.missed_cycles, 0, 1);
  }
  return h;
}

nlohmann::json host_json(const HostTiming& h) {
  if (h.loop.empty()) return nullptr;
  return {{"loop", h.loop}, {"ticks", h.ticks}, {"overruns", h.overruns}, {"missed_cycles", h.missed_cycles},
          {"wake_p99_ms", h.have_latency ? json(h.wake_p99_ms) : json(nullptr)}, {"wake_max_ms", h.have_latency ? json(h.wake_max_ms) : json(nullptr)},
          {"period_ms", h.period_ms}, {"starving", h.starving}};
}

std::string host_line(const HostTiming& h) {
  if (h.loop.empty()) return "this host: no loop ran";
  std::string t = "this host over the " + h.loop + " loop: ";
  if (h.have_latency) t += "wake-up P99 " + num(h.wake_p99_ms) + " ms, max " + num(h.wake_max_ms) + " ms, ";
  t += std::to_string(h.overruns) + " overruns, " + std::to_string(h.missed_cycles) + " skipped periods in " + std::to_string(h.ticks) + " ticks of " +
       num(h.period_ms) + " ms: ";
  return t + (h.starving ? "STARVING (it skipped 1 % or more of the periods, or its wake-up P99 reached a period)" : "kept its period");
}

Explanation explain_exit(const StationOutcome& o, const RunConditions& c, int code) {
  Explanation e;
  e.json = json::object();
  if (code == kExitOk || o.plan == nullptr) return e;
  e.json["exit_code"] = code;
  const bool ran = o.counters != nullptr && o.counters->ticks_run > 0;
  if (code == kExitNoNeighbour && ran) explain_no_neighbour(o, c, e);
  if (code == kExitMissedCycles && o.counters) explain_stall(o, e);
  explain_cause(o, c, code, e);
  if (code == kExitDiverged || code == kExitNoNeighbour || code == kExitHeldByGate || code == kExitSafeState) explain_links(o, e);
  const HostTiming h = host_timing(o);
  e.json["host"] = host_json(h);
  if (!h.loop.empty()) e.lines.push_back(host_line(h));
  e.json["lines"] = e.lines;
  return e;
}

}  // namespace haptic::firmware
