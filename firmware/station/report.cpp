#include "firmware/station/report.hpp"

#include "firmware/station/neighbours.hpp"
#include "firmware/station/state_check.hpp"
#include "firmware/station/explain.hpp"

#include "firmware/run/summary.hpp"
#include "firmware/model/delay_model.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace haptic::firmware {

namespace {

using nlohmann::json;

json or_null(bool has, double v) { return has ? json(v) : json(nullptr); }

// The run's scenario part (firmware/run/summary.hpp, shared with summary.json) and the station's own.
json station_scenario_json(const StationPlan& p) {
  const BuiltScenario& b = *p.built;
  json j = scenario_json(b);
  j["station"] = p.station_id;
  if (p.overrides.solo) j["solo"] = {{"anchor_N_per_m", b.scene.params.ground_stiffness_N_per_m}};  // haptic-station solo (make_solo)
  j["x_d"] = std::vector<double>(b.scene.x_d.data(), b.scene.x_d.data() + b.scene.dofs);
  j["scene_surface"] = b.scene.mesh.surface;                     // for the merge's snapshots.json
  j["contact_nodes"] = b.contact_nodes[static_cast<std::size_t>(p.me)];
  j["transport"] = p.net.transport;
  j["impairment_preset"] = p.file.impairment_preset;
  j["epoch_monotonic_s"] = static_cast<double>(p.times.epoch_ns) * 1e-9;
  j["probe_ticks"] = p.times.probe_ticks;
  j["run_k0"] = p.times.run_k0;
  j["run_ticks_planned"] = p.times.run_ticks;
  j["damping_model_Ns_per_m"] = b.damping[static_cast<std::size_t>(p.me)];
  j["damping_model_min_Ns_per_m"] = b.damping_min[static_cast<std::size_t>(p.me)];
  j["agreement_ticks"] = p.file.station.agreement_ticks;
  // What the merge needs for d^2 of eq. (13) (model::eq13_d2_J): the reservoirs pspm starts each
  // edge end with and lambda_max(P_ij) of the edge gains (the consensus springs, bounded).
  j["pspm_reservoir0_J"] = b.spec.pspm_reservoir0_J;
  j["consensus_P_lambda_max_N_per_m"] = b.gains.empty() ? 0.0 : b.gains[0].lambda_max_P;
  // the station's loss allowance: fixed, or -1 = measured per link while probing (links[].loss_allowance_ticks)
  j["loss_allowance_ticks"] = p.file.station.loss_allowance_ticks;
  j["loss_allowance_max_ticks"] = p.file.station.loss_allowance_max_ticks;
  j["fingerprint"] = {{"protocol_version", p.fingerprint.protocol_version}, {"scene_nodes", p.fingerprint.scene_nodes},
                      {"period_ns", p.fingerprint.period_ns}, {"scene_hash", p.fingerprint.scene_hash}, {"gains_hash", p.fingerprint.gains_hash},
                      {"consensus_law", p.fingerprint.consensus_law}, {"tx_predict", p.fingerprint.tx_predict}, {"tx_deadband_hash", p.fingerprint.tx_deadband_hash}};
  return j;
}

// The record windows (station/records.hpp): rows streamed to the CSV files and rows the tick
// dropped because the writer fell behind (0 unless the host starved the writer for a window).
void add_records_json(const StationOutcome& o, json& j) {
  const TickRecords* r = o.records_streamed ? o.records : nullptr;
  j["records"] = {{"trace_rows", r ? r->trace_rows : 0},
                  {"state_rows", r ? r->state_rows : 0},
                  {"trace_rows_lost", r ? r->trace_lost : 0},
                  {"state_rows_lost", r ? r->state_lost : 0},
                  {"window_s", kRecordWindowS},
                  {"window_bytes", o.plan->record_window_bytes()}};
}

void add_run_json(const StationOutcome& o, json& j) {
  const TickCounters* c = o.counters;
  const bool ran = c != nullptr && c->ticks_run > 0;
  j["first_run_k"] = o.run ? o.run->first_run_k : -1;
  j["ticks_run"] = c ? c->ticks_run : 0;
  j["diverged"] = c && c->diverged;
  j["diverged_at_s"] = c && c->diverged ? json(c->diverged_at_s) : json(nullptr);
  j["max_node_speed_m_per_s"] = !ran ? json(nullptr) : std::isfinite(c->max_speed_m_per_s) ? json(c->max_speed_m_per_s) : json("inf");
  j["port_energy_min_J"] = or_null(ran, ran ? c->port_min_J : 0);
  j["no_neighbour_ticks"] = c ? c->no_neighbour_ticks : 0;
  // Run packets the tick's age guard refused (no echo of our sends / age bound over the limit); what
  // the receive links did not use is per link (rx_stale_reordered, rx_duplicate), what the endpoint
  // refused is in drops.
  j["rx_refused"] = {{"no_echo", c ? c->no_echo : 0}, {"age_over_bound", c ? c->age_over_bound : 0}};
  j["push_failures"] = (c ? c->push_failures : 0) + (o.probe ? o.probe->push_failures : 0);
  // the trace's flags carry kTraceStateSent (station/tick.hpp) on every trace_every-th tick
  j["trace_every"] = o.plan->file.station.trace_every;
  j["trace_marks_state_sent"] = true;
  add_records_json(o, j);
  j["device_fault_ticks"] = c ? c->device_fault_ticks : 0;
  j["contact_ticks"] = c ? c->contact_ticks : 0;
  j["device_force_max_N"] = or_null(ran, ran ? c->device_force_max_N : 0);
  j["foreign_packets"] = c ? c->foreign_packets : 0;
  j["probe_packets_after_run"] = c ? c->probe_packets_after_run : 0;
  j["rx_offered"] = c ? c->rx_offered : 0;
  j["device"] = o.device_name;
  j["device_fault"] = o.device_fault;
  j["stopped_by_signal"] = o.run && o.run->stopped_by_signal;
  j["loop_exception"] = o.run && o.run->loop_exception ? json(o.run->loop_exception_what) : json(nullptr);
  if (o.run) {
    j["rt"] = {{"summary", o.run->rt_summary}, {"warnings", o.run->rt_warnings}, {"fully_real_time", o.run->rt_warnings.empty()}};
    j["loop"] = {{"ticks", o.run->loop.ticks}, {"overruns", o.run->loop.overruns}, {"missed_cycles", o.run->loop.missed_cycles},
                 {"overrun_storms", o.run->loop.overrun_storms}};
    // the station's one loop over its whole life (probe, set-up gap and run: the ticks a tracer sees)
    const platform::LoopStats& w = o.run->whole_loop;
    j["station_loop"] = {{"ticks", w.ticks}, {"overruns", w.overruns}, {"missed_cycles", w.missed_cycles}, {"overrun_storms", w.overrun_storms}};
  } else {
    j["loop"] = {{"ticks", 0}, {"overruns", 0}, {"missed_cycles", 0}, {"overrun_storms", 0}};
  }
  if (o.probe)
    j["probe_loop"] = {{"ticks", o.probe->loop_ticks}, {"overruns", o.probe->loop_overruns}, {"missed_cycles", o.probe->loop_missed_cycles}};
  const rt::StationCore* core = o.build ? o.build->core.get() : nullptr;
  j["port_energy_final_J"] = core && ran ? json(core->energy().port_J) : json(nullptr);
  j["controller_energy_final_J"] = core && ran ? json(core->energy().controller_J) : json(nullptr);
  j["solver"] = core ? json(core->solver_name()) : json(nullptr);  // the linear step's (rt/step_solver)
  if (o.build && o.build->solver_choice.measured)  // station.solver = "auto": what start-up measured (firmware/station/solver_choice.hpp)
    j["solver_choice"] = {{"direct_tick_us", o.build->solver_choice.direct_tick_us},
                          {"iterative_tick_us", o.build->solver_choice.iterative_tick_us},
                          {"timed_ticks", o.build->solver_choice.timed_ticks}};
  j["solver_residual_energy_final_J"] = core && ran ? json(core->energy().solver_residual_J) : json(nullptr);
  j["solver_unconverged_ticks"] = core ? json(core->solver_unconverged_ticks()) : json(nullptr);
  j["edge_drop_events"] = core ? json(core->edge_drop_events()) : json(nullptr);
  j["edge_energy_trips"] = core ? json(core->edge_gate().trips()) : json(nullptr);
  if (core) {  // what the energy gate and the edge-drop rule did (firmware/run_summary.hpp GateSummary)
    GateSummary g = gate_summary(*core);
    if (ran) g.port_energy_min_J = c->port_min_J;
    j["gate"] = gate_json(g);
    j["verdict"] = station_verdict(o);
  }
  j["safe_state_ticks"] = core ? json(core->safe_state_ticks()) : json(nullptr);
  j["steps_clamped"] = core ? json(core->step_clamped_ticks()) : json(nullptr);  // measured T_k outside period_min_s..period_max_s
  if (o.probe && o.probe->steps.fixed) {  // this station's step bounds (probe.hpp StepSet), the ones its core and eq. (18) used
    const StepSet& s = o.probe->steps;
    j["step_bounds"] = {{"t_min_s", s.own.t_min_s}, {"t_max_s", s.own.t_max_s}, {"measured", s.measured}, {"capped", s.measured && s.own.capped},
                        {"max_wake_latency_s", s.max_wake_latency_s}, {"wakes_measured", s.wakes}};
  }
}

void add_bounds_json(const StationOutcome& o, json& j) {
  const bool built = o.build != nullptr && o.build->status == PhaseStatus::kOk;
  j["damping_Ns_per_m"] = built ? json(o.build->bounds.damping_Ns_per_m) : json(nullptr);
  j["damping_min_Ns_per_m"] = built ? json(o.build->bounds.damping_min_Ns_per_m) : json(nullptr);
  j["passivity_condition_met"] = built && o.build->passivity_condition_met;  // eq. (18) (eq18), by construction (pspm)
  if (o.plan) j["consensus_passivity"] = o.plan->file.station.consensus_passivity;
  const rt::StationCore* core = built ? o.build->core.get() : nullptr;
  if (core && core->set_position_modulator(0)) {  // per edge: ticks the reservoir limited, energy the jumps put in
    json m = json::array();
    for (int n = 0; n < core->neighbor_count(); ++n)
      m.push_back({{"limited_ticks", core->set_position_modulator(n)->limited_ticks()}, {"injected_J", core->set_position_modulator(n)->injected_J()},
                   {"reservoir_J", core->set_position_modulator(n)->reservoir_J()}, {"edge_energy_peak_J", core->edge_energy().peak_J(n)}});
    j["pspm_edges"] = m;
  }
}

json endpoint_json(const net::EndpointStats& st, const net::EndpointConfig& ec, const std::string& io_sched) {
  json j;
  j["io_thread_scheduling"] = io_sched;
  j["drops"] = {{"datagrams_received", st.datagrams_received}, {"receive_errors", st.receive_errors}, {"rx_ring_full", st.rx_ring_full},
                {"tx_overruns", st.tx_overruns}, {"wrong_scene_size", st.wrong_scene_size}, {"tx_safe_state", st.tx_safe_state}};
  // Every datagram the decoder/endpoint dropped, by reason (net/wire.hpp DropReason), zeros included.
  json by_reason = json::object();
  for (std::size_t r = 0; r < net::kDropReasonCount; ++r)
    by_reason[net::to_string(static_cast<net::DropReason>(r))] = st.drops.by_reason[r];
  j["drops"]["by_reason"] = by_reason;
  j["drops"]["total"] = st.drops.total();
  j["io_thread"] = {{"cpu_s", st.io_thread_cpu_s},         {"tx_spin", ec.tx_spin},
                    {"tx_packets", st.tx_packets},         {"tx_caught_spinning", st.tx_caught_spinning},
                    {"tx_spin_windows", st.tx_spin_windows}, {"tx_handoff_mean_us", or_null(st.tx_packets > 0, st.tx_handoff_mean_s * 1e6)},
                    {"tx_handoff_max_us", or_null(st.tx_packets > 0, st.tx_handoff_max_s * 1e6)},
                    {"tx_direct", ec.tx_direct},           {"tx_direct_sent", st.tx_direct},
                    {"tx_direct_unfinished", st.tx_direct_unfinished}, {"tx_direct_would_block", st.tx_direct_would_block},
                    {"tx_direct_declined", st.tx_direct_declined}};
  return j;
}

json link_json(const StationOutcome& o, std::size_t n, const net::PeerStats& ps, const net::PeerStats& ps0) {
  const StationPlan& p = *o.plan;
  json l;
  l["peer"] = p.neighbours()[n] + 1;
  const bool rx = ps.packets_received > 0;
  l["rx_packets_run"] = ps.packets_received - ps0.packets_received;
  l["rx_packets_total"] = ps.packets_received;
  l["rx_loss_fraction_measured"] = or_null(rx, ps.loss_fraction);
  l["one_way_mean_ms"] = or_null(rx, 1e3 * ps.one_way_mean_s);
  l["one_way_max_ms"] = or_null(rx, 1e3 * ps.one_way_max_s);
  l["tx_packets_run"] = ps.packets_sent - ps0.packets_sent;
  // Per-link rates over the run (the simulator's link_stats have the same two): states sent and UDP
  // payload bytes of every datagram sent to this peer (state fragments, echoes, fingerprints), per
  // second of the run's span on the grid (periods a loaded host skipped are seconds that passed).
  const double run_s = o.run && o.run->last_run_k >= 0 ? static_cast<double>(o.run->last_run_k + 1 - o.run->first_run_k) * p.built->spec.period_s : 0.0;
  l["packets_per_s"] = or_null(run_s > 0, static_cast<double>(ps.packets_sent - ps0.packets_sent) / run_s);
  l["bytes_per_s"] = or_null(run_s > 0, static_cast<double>(ps.bytes_sent - ps0.bytes_sent) / run_s);
  l["tx_impair_lost_run"] = ps.impair_lost - ps0.impair_lost;
  l["tx_impair_duplicated_run"] = ps.impair_duplicated - ps0.impair_duplicated;
  l["tx_send_errors"] = ps.send_errors;
  l["tx_delay_queue_full"] = ps.delay_queue_full;
  const bool rtt = ps.rtt_samples > 0;
  l["rtt_samples"] = ps.rtt_samples;
  l["rtt_mean_ms"] = or_null(rtt, 1e3 * ps.rtt_mean_s);
  l["rtt_min_ms"] = or_null(rtt, 1e3 * ps.rtt_min_s);
  l["rtt_max_ms"] = or_null(rtt, 1e3 * ps.rtt_max_s);
  l["rtt_bound_ms_now"] = or_null(ps.rtt_has_bound, 1e3 * ps.rtt_bound_s);
  l["rtt_over_bound_events"] = ps.rtt_over_bound_events;
  l["rtt_echoes_before_pause"] = ps.echoes_before_pause;  // held through the set-up gap: no round-trip samples
  l["peer_safe_state_packets"] = ps.safe_state_packets;
  l["rate_limited"] = ps.rate_limited;
  // Pairwise keys (net.key_file): agreed with this neighbour, how often (a restart re-agrees), hellos.
  l["keys"] = json::object({{"agreed", ps.keys_agreed}, {"agreements", ps.key_agreements}, {"hellos_sent", ps.hellos_sent},
               {"hellos_received", ps.hellos_received}, {"states_held_back", ps.tx_without_keys}});
  if (o.build && o.build->status == PhaseStatus::kOk) {
    l["round_trip_bound_ticks"] = o.build->bounds.round_trip_ticks[n];
    l["index_delay_bound_ticks"] = o.build->bounds.index_guard_ticks[n];
    l["assumed_round_trip_ticks"] = o.build->bounds.assumed_sum_ticks[n];
  }
  if (o.probe && n < o.probe->own_rtt_bound_ticks.size()) {  // each end's frozen probing bound; both use the larger
    l["round_trip_bound_ticks_own"] = o.probe->own_rtt_bound_ticks[n];
    l["round_trip_bound_ticks_peer"] = o.probe->peer_rtt_bound_ticks[n] >= 0 ? json(o.probe->peer_rtt_bound_ticks[n]) : json(nullptr);
  }
  if (o.probe && n < o.probe->loss_allowance_ticks.size()) {  // each end's loss allowance; both use the larger
    const int own = o.probe->own_loss_allowance_ticks[n], peer = o.probe->peer_loss_allowance_ticks[n];
    l["loss_allowance_ticks"] = o.probe->loss_allowance_ticks[n];
    l["loss_allowance_ticks_own"] = own >= 0 ? json(own) : json(nullptr);
    l["loss_allowance_ticks_peer"] = peer >= 0 ? json(peer) : json(nullptr);
    l["loss_allowance_capped"] = n < o.probe->loss_allowance_capped.size() && o.probe->loss_allowance_capped[n];
    const ProbeLoss& pl = o.probe->probe_loss[n];
    l["probe_loss"] = json::object({{"lost", pl.lost}, {"expected", pl.expected}, {"longest_gap", pl.longest_gap},
                                    {"upper_bound", pl.expected > 0 ? json(model::loss_upper_bound(pl.lost, pl.expected)) : json(nullptr)}});
  }
  if (o.probe && n < o.probe->steps.t_max_j_s.size()) {  // the neighbour's T_j^max as it announced it (null: did not arrive), as eq. (18) used it
    const double peer = o.probe->steps.peer_t_max_s[n];
    l["step_max_s_peer"] = peer > 0 ? json(peer) : json(nullptr);
    l["step_max_s_used"] = o.probe->steps.t_max_j_s[n];
  }
  l["model_index_delay_bound_ticks"] = p.built->nbar_ticks(p.me, p.neighbours()[n]);
  if (o.build && o.build->core) {
    rt::StationCore& core = *o.build->core;
    const auto& rc = core.rx(static_cast<int>(n)).counters();
    l["rx_accepted"] = rc.accepted;
    l["rx_stale_reordered"] = rc.stale;
    l["rx_duplicate"] = rc.duplicate;
    l["rx_ahead_ticks"] = rc.ahead_ticks;
    l["rx_sustained_ticks"] = rc.sustained_ticks;
    l["max_index_delay_ticks"] = rc.max_index_delay;
    l["bound_violations"] = core.edge_drop_events(static_cast<int>(n));
    if (core.config().resilient_f > 0) l["resilient_excluded_ticks"] = core.resilient_excluded_ticks(static_cast<int>(n));
    l["edge_energy"] = edge_energy_json(edge_energy_summary(core, static_cast<int>(n)));
  }
  return l;
}

void add_links_json(const StationOutcome& o, json& j) {
  if (o.endpoint == nullptr) return;
  const net::EndpointStats st = o.endpoint->stats();
  j.update(endpoint_json(st, o.plan->net.endpoint, o.io_sched));
  if (!o.lifecycle.is_null()) j["lifecycle"] = o.lifecycle;
  if (!o.recording.is_null()) j["recording"] = o.recording;
  json links = json::array();
  for (std::size_t n = 0; n < o.plan->neighbours().size(); ++n) {
    const auto p = static_cast<std::size_t>(o.plan->peers.nbr_to_peer[n]);
    const bool have0 = o.probe && p < o.probe->stats_at_end.peers.size();
    links.push_back(link_json(o, n, st.peers[p], have0 ? o.probe->stats_at_end.peers[p] : net::PeerStats{}));
  }
  j["links"] = links;
}

// The CSV files of a run whose records never streamed (the run phase did not start): headers only.
void write_empty_records(const std::string& base, int dofs) {
  for (const bool trace : {true, false}) {
    const std::string path = base + (trace ? "-trace.csv" : "-state.csv");
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (!f) throw std::runtime_error("cannot write " + path);
    if (trace) {
      write_station_trace_header(f);
    } else {
      write_station_state_header(f, dofs);
    }
    std::fclose(f);
  }
}

}  // namespace

std::vector<std::string> RunConditions::names() const {
  std::vector<std::string> n;
  if (device_missing) n.push_back("device_missing");
  if (diverged) n.push_back("diverged");
  if (safe_state_latched) n.push_back("safe_state_latched");
  if (passivity_not_met) n.push_back("passivity_condition_not_met");
  if (key_compromise) n.push_back("key_compromise_suspected");
  if (neighbour_isolated) n.push_back("neighbour_isolated");
  if (missed_cycles) n.push_back("missed_cycles");
  if (no_neighbour) n.push_back("no_neighbour");
  if (failed) n.push_back("failed");
  if (ended_before_release) n.push_back("ended_before_release");
  if (held_by_gate) n.push_back("held_by_gate");
  if (edge_drop_rule_acted) n.push_back("edge_drop_rule_acted");
  return n;
}

RunConditions run_conditions(const StationOutcome& o) {
  RunConditions c;
  const StationPlan& p = *o.plan;
  const TickCounters* k = o.counters;
  c.device_missing = o.failure_status == PhaseStatus::kDeviceMissing;
  c.diverged = k && k->diverged;
  c.safe_state_latched = (o.run && o.run->loop_exception) || (!o.device_fault.empty() && o.device_fault != "none");
  c.passivity_not_met = o.build && o.build->status == PhaseStatus::kOk && !o.build->passivity_condition_met;
  // the run loop's only: the probing loop's ticks do start-up work (key agreement) and skip ~190 on a loaded machine
  c.missed_cycles_total = o.run ? o.run->loop.missed_cycles : 0;
  c.missed_cycles = c.missed_cycles_total > static_cast<std::uint64_t>(p.file.station.max_missed_cycles);
  if (o.endpoint) c.key_compromise_messages = key_compromise_messages(p, o.endpoint->stats());
  c.key_compromise = !c.key_compromise_messages.empty();
  if (k && k->ticks_run > 0) c.no_neighbour_fraction = static_cast<double>(k->no_neighbour_ticks) / static_cast<double>(k->ticks_run);
  c.no_neighbour = o.failure_status == PhaseStatus::kNoNeighbour ||
                   (c.no_neighbour_fraction && *c.no_neighbour_fraction > p.file.station.max_no_neighbour_fraction);
  c.failed = !o.failure.empty() && o.failure_status != PhaseStatus::kNoNeighbour && o.failure_status != PhaseStatus::kDeviceMissing &&
             !(o.run && o.run->loop_exception);
  const auto& sc = p.built->spec.script;
  // Run time reached: the end of the last run tick on the epoch's grid. A rejoined station's run starts
  // late (first_run_k > run_k0) and ends on time; a period the loop skipped is time the run covered
  // (the core ticks the grid's index), not time it lacked.
  if (o.run && o.run->last_run_k >= 0) c.ran_s = static_cast<double>(o.run->last_run_k + 1 - p.times.run_k0) * p.built->spec.period_s;
  // Named when planned so, or when the run phase started and stopped early (a run that never
  // started is named by its failure).
  c.ended_before_release = sc.kind == UserScriptSpec::Kind::kPushHoldRelease && (p.ends_before_release || (o.run != nullptr && c.ran_s <= sc.release_s));
  const rt::StationCore* core = o.build ? o.build->core.get() : nullptr;
  c.held_by_gate = core && core->edge_gate().trips() > 0;
  if (core) c.isolation_messages = state_check_messages(p, *core);
  c.neighbour_isolated = core && core->edge_monitor().isolations() > 0;
  c.edge_drop_rule_acted = core && core->edge_drop_events() > 0;
  return c;
}

int exit_code(const RunConditions& c) {
  if (c.device_missing) return kExitDeviceMissing;
  if (c.diverged) return kExitDiverged;
  if (c.safe_state_latched) return kExitSafeState;
  if (c.passivity_not_met) return kExitPassivityNotMet;
  if (c.key_compromise) return kExitKeyCompromise;
  if (c.neighbour_isolated) return kExitNeighbourIsolated;
  if (c.missed_cycles) return kExitMissedCycles;
  if (c.no_neighbour) return kExitNoNeighbour;
  if (c.failed) return kExitRunFailed;
  if (c.ended_before_release) return kExitBeforeRelease;
  if (c.held_by_gate) return kExitHeldByGate;
  return kExitOk;
}

std::string station_verdict(const StationOutcome& o) {
  const rt::StationCore* core = o.build ? o.build->core.get() : nullptr;
  if (core == nullptr) return "stable";
  // eq. (13) is a sum over all stations: the merge decides it
  return run_verdict(o.counters != nullptr && o.counters->diverged, false, gate_summary(*core), false);
}

nlohmann::json station_summary(const StationOutcome& o, const RunConditions& c) {
  json j = station_scenario_json(*o.plan);
  add_bounds_json(o, j);
  add_run_json(o, j);
  add_links_json(o, j);
  j["error"] = o.failure.empty() ? json(nullptr) : json(o.failure);
  j["warnings"] = o.plan->warnings;
  j["no_neighbour_fraction"] = c.no_neighbour_fraction ? json(*c.no_neighbour_fraction) : json(nullptr);
  j["max_no_neighbour_fraction"] = o.plan->file.station.max_no_neighbour_fraction;
  j["missed_cycles_total"] = c.missed_cycles_total;  // the run loop's (loop.missed_cycles)
  j["max_missed_cycles"] = o.plan->file.station.max_missed_cycles;
  j["key_compromise"] = c.key_compromise_messages;  // [] when none
  if (o.build && o.build->core) j["state_check"] = state_check_json(*o.plan, *o.build->core);
  j["isolation"] = c.isolation_messages;  // [] when none
  j["incarnation"] = o.endpoint ? o.endpoint->incarnation() : 0;  // ours, as announced to the neighbours
  j["conditions"] = c.names();
  j["exit_code"] = exit_code(c);
  j["host"] = host_json(host_timing(o));  // this host's timing: wake-up P99/max, overruns, skipped periods, starving
  j["explanation"] = explain_exit(o, c, exit_code(c)).json;  // why a non-zero exit (firmware/station/explain.hpp)
  j["wall_time_s"] = o.wall_time_s;
  return j;
}

void write_station_outputs(const StationOutcome& o, const RunConditions& c) {
  const std::string& base = o.plan->base_path;
  write_json_file(base + ".json", station_summary(o, c));
  if (!o.records_streamed) write_empty_records(base, o.plan->built->scene.dofs);
}

}  // namespace haptic::firmware
