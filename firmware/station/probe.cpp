#include "firmware/station/probe.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>

#include "platform/clock.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/toml_config.hpp"
#include "rt/gains.hpp"

namespace haptic::firmware {

using platform::config::number_text;

namespace {


std::string id_list(const std::vector<int>& ids) {
  std::string s;
  for (int id : ids) {
    if (!s.empty()) s += ", ";
    s += std::to_string(id);
  }
  return s;
}

// Neighbour packets into the tick grid at probing tick k; notes a neighbour already running the
// session (a run packet, sequence number >= run_k0, further ahead of tick k than a grid offset
// within station.clock_offset_limit_ms explains: its session started before ours). Not RT-safe.
void take_neighbour_packets(const StationPlan& plan, net::Endpoint& ep, std::int64_t k, ProbeResult& r) {
  const std::int64_t running_above = std::max(plan.times.run_k0, k + plan.clock_offset_limit_ticks());
  ep.drain([&](std::uint16_t sender, std::uint64_t seq, double send_time_s, const double*, const double*, std::uint32_t) {
    const int n = plan.peers.sender_to_nbr[sender];
    r.grid.add(n, seq, send_time_s, plan.built->spec.period_s);  // the neighbour's tick grid
    r.loss_counter.add(n, seq);                                   // and which of its probes arrived
    if (n >= 0 && static_cast<std::int64_t>(seq) >= running_above && r.running_session_from == 0) r.running_session_from = sender;
  });
}

// What the endpoint dropped while probing, by counted cause ("; counted: 120 bad_mac (forged or
// wrong key), 3 future_sequence"), or "; nothing received at all".
std::string counted_causes(const net::EndpointStats& s) {
  std::string c;
  auto add = [&](std::uint64_t n, const std::string& what) {
    if (n == 0) return;
    c += (c.empty() ? "; counted: " : ", ") + std::to_string(n) + " " + what;
  };
  add(s.drops[net::DropReason::bad_mac], "bad_mac (wrong key or forged)");
  add(s.drops[net::DropReason::wrong_session], "wrong_session (another session id)");
  add(s.drops[net::DropReason::wrong_source], "wrong_source (from an unconfigured address)");
  add(s.wrong_scene_size + s.drops[net::DropReason::too_large], "wrong scene size");
  for (std::size_t r = 0; r < net::kDropReasonCount; ++r) {
    const auto why = static_cast<net::DropReason>(r);
    if (why == net::DropReason::bad_mac || why == net::DropReason::wrong_session || why == net::DropReason::wrong_source ||
        why == net::DropReason::too_large)
      continue;
    add(s.drops.by_reason[r], net::to_string(why));
  }
  if (s.datagrams_received == 0) c += "; nothing received at all";
  return c;
}

}  // namespace

std::int64_t probe_freeze_tick(std::int64_t probe_ticks) { return probe_ticks - probe_ticks / 3; }

std::int64_t rejoin_probe_ticks(double rejoin_probe_s, double period_s) { return std::llround(rejoin_probe_s / period_s); }

std::int64_t send_interval_ticks(const ScenarioSpec& spec) {
  return spec.tx_deadband.enabled() ? spec.tx_deadband.max_interval_ticks : 1;
}

void fix_loss_allowances(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r) {
  const StationSection& S = plan.file.station;
  const BuiltScenario& b = *plan.built;
  const auto& nbrs = plan.neighbours();
  const net::EndpointStats st = ep.stats();
  r.own_loss_allowance_ticks.resize(nbrs.size(), -1);
  r.probe_loss.resize(nbrs.size());
  r.loss_allowance_capped.resize(nbrs.size(), false);
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const auto p = static_cast<std::size_t>(plan.peers.nbr_to_peer[n]);
    const net::PeerStats& ps = st.peers[p];
    if (r.own_loss_allowance_ticks[n] >= 0 || !ps.rtt_has_bound) continue;  // fixed once, with the bound
    int own = S.loss_allowance_ticks;
    if (own < 0) {  // measured: packets later than our round-trip bound count as lost
      r.probe_loss[n] = r.loss_counter.loss(n, net::bound_ticks(ps.rtt_probe_bound_s, b.spec.period_s));
      own = round_trip_loss_allowance(r.probe_loss[n], b.spec.duration_s / b.spec.period_s, 2 * static_cast<int>(b.spec.topology.size()));
      if (own < 0) own = S.loss_allowance_max_ticks;  // nothing measured: the most we accept
      if (own > S.loss_allowance_max_ticks) {  // capped, said, and marked in the report (the energy bound covers the rest)
        r.loss_allowance_capped[n] = true;
        r.warnings.push_back("the link from station " + std::to_string(nbrs[n] + 1) + " lost " + std::to_string(r.probe_loss[n].lost) + " of " +
                             std::to_string(r.probe_loss[n].expected) + " probe packets (longest run " + std::to_string(r.probe_loss[n].longest_gap) +
                             "; lost, later than the round-trip bound, or not sent by an overrunning loop): its loss allowance of " +
                             std::to_string(own) + " ticks exceeds station.loss_allowance_max_ticks = " + std::to_string(S.loss_allowance_max_ticks) +
                             " and is capped there, so Nbar may be exceeded more often than once in 100 runs (the per-edge energy bound, "
                             "station.edge_energy_bound_J, still bounds what the link can inject); fix the link or the load, or raise the maximum");
        own = S.loss_allowance_max_ticks;
      }
    }
    r.own_loss_allowance_ticks[n] = own;
    ep.set_loss_allowance(p, own);
  }
}

void fix_step_bounds(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r, bool measured) {
  StepSet& st = r.steps;
  if (st.fixed) return;
  const StationSection& S = plan.file.station;
  const double T = plan.built->spec.period_s;
  const double cap = std::min(S.step_margin_max * T, st.eq26_margin_max_s);
  st.own = measured ? model::measured_step_bounds(T, st.max_wake_latency_s, cap) : model::step_bounds(T, 1.0, 0.0, 0.0);
  st.measured = measured && (S.period_min_s == 0 || S.period_max_s == 0);
  if (S.period_min_s > 0) st.own.t_min_s = S.period_min_s;
  if (S.period_max_s > 0) st.own.t_max_s = S.period_max_s;
  const bool keys = S.period_min_s > 0 || S.period_max_s > 0;
  st.text = "steps T_k in [" + number_text(st.own.t_min_s * 1e3) + ", " + number_text(st.own.t_max_s * 1e3) + "] ms (" +
            (st.measured ? "measured: wake-up latency up to " + number_text(st.max_wake_latency_s * 1e3) + " ms while probing" +
                               (keys ? std::string(", the other bound from station.period_min_s / period_max_s") : "")
             : keys      ? std::string("station.period_min_s / period_max_s")
                         : "the nominal period: a rejoin");
  if (st.measured && st.own.capped)
    st.text += ", capped at +-" + number_text(cap * 1e3) + " ms by " +
               (cap < S.step_margin_max * T ? std::string("what eq. (26) allows this device's coupling") : "station.step_margin_max") +
               ": longer steps are clamped and counted, steps_clamped";
  st.text += ")";
  st.fixed = true;
  ep.set_step_max(st.own.t_max_s);
}

LoopStage probe_stage(const StationPlan& plan, net::Endpoint& ep, ProbeResult& r, std::int64_t now_ns) {
  r.grid = NeighbourGrid(plan.neighbours().size());
  const BuiltScenario& b = *plan.built;
  const std::int64_t pace = send_interval_ticks(b.spec);
  r.loss_counter = ProbeLossCounter(plan.neighbours().size(), pace);
  const std::vector<double> x0(b.scene.x_d.data(), b.scene.x_d.data() + b.scene.dofs), v0(x0.size(), 0.0);
  LoopStage s;
  s.timeline = plan.times;
  s.last_phase = TickPhase::kProbe;
  s.k_first = plan.times.tick_at(now_ns);  // from now: the ticks before the epoch watch for a running session
  const std::int64_t freeze = probe_freeze_tick(plan.times.probe_ticks);
  s.tick = [&plan, &ep, &r, x0, v0, freeze, pace = rt::SendInterval(pace), frozen = false](std::int64_t k, const platform::TickInfo& info) mutable {
    if (k >= freeze && !frozen) {  // the bounds freeze; the last third exchanges them
      frozen = true;
      r.all_bounds_at_freeze = ep.finish_probing();
      fix_loss_allowances(plan, ep, r);  // travels with the frozen bounds
      fix_step_bounds(plan, ep, r, true);
    }
    if (k >= 0 && !frozen) {  // this host's wake-up latency: the step bounds (StepSet)
      r.steps.max_wake_latency_s = std::max(r.steps.max_wake_latency_s, static_cast<double>(info.wake_latency_ns) * 1e-9);
      ++r.steps.wakes;
    }
    take_neighbour_packets(plan, ep, k, r);
    if (r.running_session_from != 0) return false;  // the caller rejoins the running session
    if (k < 0) return true;                         // before the epoch: watching only
    if (r.first_probe_k < 0) r.first_probe_k = k;
    if (pace.take(k) && !ep.push_state(static_cast<std::uint64_t>(k), net::monotonic_s(), x0.data(), v0.data())) ++r.push_failures;
    return true;
  };
  return s;
}

void end_probe(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop, const StageOutcome& o, ProbeResult& r) {
  r.loop_ticks = o.counts.ticks;
  r.loop_overruns = o.counts.overruns;
  r.loop_missed_cycles = o.counts.missed_cycles;
  if (stop.load(std::memory_order_acquire)) {
    r.status = PhaseStatus::kStopped;
    r.message = "stopped by a signal while probing";
    return;
  }
  if (!o.ended) {
    r.status = PhaseStatus::kFailed;
    r.message = "the station loop ended while probing";
    return;
  }
  if (r.running_session_from != 0) {  // the caller rejoins the running session instead
    r.status = PhaseStatus::kOk;
    r.message = "station " + std::to_string(r.running_session_from) + " already runs the session (its run packets arrive before our probing ended)";
    return;
  }
  if (r.first_probe_k < 0 || r.first_probe_k * 2 > plan.times.probe_ticks) {  // opening the device/endpoint took most of it
    r.status = PhaseStatus::kFailed;
    r.message = "probing began at tick " + std::to_string(r.first_probe_k) + " of " + std::to_string(plan.times.probe_ticks) +
                ": the station was ready too late for the common epoch (station.start_at / --start-at, station.start_delay_s)";
    return;
  }
  // A neighbour with too few round trips at the freeze gets its bound now, from all of probing (its
  // end then may not learn ours in time: the warning in collect_probe_result says so).
  if (!r.all_bounds_at_freeze) {
    r.all_bounds_at_freeze = ep.finish_probing();
    fix_loss_allowances(plan, ep, r);
  }
  fix_step_bounds(plan, ep, r, true);  // (a loop that never reached the freeze)
  collect_probe_result(plan, ep, r.all_bounds_at_freeze, "station.probe_s = " + std::to_string(plan.file.station.probe_s) + " s", r);
  if (r.status == PhaseStatus::kOk) check_clock(plan, plan.times.epoch_ns, r);
}

ProbeResult probe_neighbours(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop) {
  ProbeResult r;
  StationLoop loop(plan, nullptr, stop);
  try {
    loop.start(probe_stage(plan, ep, r, net::monotonic_ns()), RunObserver{});
  } catch (const std::exception& e) {
    r.status = PhaseStatus::kFailed;
    r.message = std::string("real-time set-up: ") + e.what();
    return r;
  }
  loop.wait_stage(0, RunObserver{});
  loop.finish();
  end_probe(plan, ep, stop, loop.stage(0), r);
  return r;
}

namespace {

// Neighbour n's loss allowance both ends use: the larger of ours and the neighbour's (ours alone,
// with a warning, when the neighbour's did not arrive). Not RT-safe.
void agree_loss_allowance(const StationPlan& plan, std::size_t n, const net::PeerStats& ps, ProbeResult& r) {
  r.own_loss_allowance_ticks.resize(plan.neighbours().size(), -1);
  r.probe_loss.resize(plan.neighbours().size());
  r.loss_allowance_capped.resize(plan.neighbours().size(), false);
  const int own = r.own_loss_allowance_ticks[n], peer = ps.peer_loss_allowance_ticks;
  r.peer_loss_allowance_ticks.push_back(peer);
  r.loss_allowance_ticks.push_back(std::max({own, peer, 0}));
  if (own >= 0 && peer < 0 && ps.rtt_has_bound)
    r.warnings.push_back("station " + std::to_string(plan.neighbours()[n] + 1) + "'s loss allowance did not arrive while probing: ours (" +
                         std::to_string(own) + " ticks) alone is used");
}

// Neighbour n's T_j^max for eq. (18): as it announced it, or 2 T (the most any station file allows:
// station.period_max_s < 2 period, station.step_margin_max <= 0.5) with a warning. Not RT-safe.
void agree_step_bound(const StationPlan& plan, std::size_t n, const net::PeerStats& ps, ProbeResult& r) {
  const double peer = ps.peer_step_max_s;
  r.steps.peer_t_max_s.push_back(peer);
  r.steps.t_max_j_s.push_back(peer > 0 ? peer : 2.0 * plan.built->spec.period_s);
  if (peer <= 0 && ps.rtt_has_bound)
    r.warnings.push_back("station " + std::to_string(plan.neighbours()[n] + 1) + "'s step bound T^max did not arrive while probing: eq. (18) "
                         "assumes 2 periods, the most a station file allows");
}

}  // namespace

void collect_probe_result(const StationPlan& plan, net::Endpoint& ep, bool all, const std::string& after_what, ProbeResult& r) {
  r.stats_at_end = ep.stats();
  const auto& nbrs = plan.neighbours();
  const double T = plan.built->spec.period_s;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const auto p = static_cast<std::size_t>(plan.peers.nbr_to_peer[n]);
    if (!r.stats_at_end.peers[p].rtt_has_bound) r.missing.push_back(nbrs[n] + 1);
    const net::PeerStats& ps = r.stats_at_end.peers[p];
    r.own_rtt_bound_ticks.push_back(net::bound_ticks(ps.rtt_probe_bound_s, T));
    r.peer_rtt_bound_ticks.push_back(ps.peer_rtt_probe_bound_s > 0 ? net::bound_ticks(ps.peer_rtt_probe_bound_s, T) : -1);
    r.rtt_bound_ticks.push_back(static_cast<std::uint32_t>(std::max(r.own_rtt_bound_ticks.back(), r.peer_rtt_bound_ticks.back())));
    if (ps.rtt_has_bound && r.peer_rtt_bound_ticks.back() < 0)
      r.warnings.push_back("station " + std::to_string(nbrs[n] + 1) + "'s round-trip bound did not arrive while probing: ours alone is used, "
                           "so the two ends may assume different bounds (station.agreement_ticks is the margin for that)");
    agree_loss_allowance(plan, n, ps, r);
    agree_step_bound(plan, n, ps, r);
  }
  const std::string after = " after " + after_what;
  // A neighbour with another scene, period, gains or protocol: say which, before anything else
  // (its state packets are dropped as the wrong size, so its round trips are missing too).
  const std::string mismatch = fingerprint_mismatches(plan, r.stats_at_end);
  if (!mismatch.empty()) {
    r.status = PhaseStatus::kFailed;
    r.message = "refusing to couple: neighbour fingerprint differs (" + mismatch + ")";
  } else if (r.missing.size() == nbrs.size()) {
    r.status = PhaseStatus::kNoNeighbour;
    r.message = "no neighbour answered: no round trip from station(s) " + id_list(r.missing) + after +
                " (not running, or wrong address, session key or session id" + counted_causes(r.stats_at_end) +
                "); a station does not run alone";
  } else if (!all || !r.missing.empty()) {
    r.status = PhaseStatus::kFailed;
    r.message = "probing: no round-trip bound for neighbour(s) " + id_list(r.missing) + after +
                " (peer not running, wrong address/key/session, or fewer than net.rtt_min_probe_samples echoes" +
                counted_causes(r.stats_at_end) + ")";
  } else {
    r.status = PhaseStatus::kOk;
  }
}

void check_clock(const StationPlan& plan, std::int64_t epoch_ns, ProbeResult& r) {
  r.clock = check_clock_offsets(plan, r.stats_at_end, r.grid, epoch_ns);
  if (!r.clock.refusal.empty()) {
    r.status = PhaseStatus::kFailed;
    r.message = r.clock.refusal;
    return;
  }
  if (!r.clock.exceeded) return;
  if (plan.file.station.clock_offset_refuse) {
    r.status = PhaseStatus::kFailed;
    r.message = "refusing to couple (station.clock_offset_refuse = true): " + r.clock.message;
  } else {
    r.warnings.push_back(r.clock.message);
  }
}

MeasuredBounds bounds_from_round_trips(const BuiltScenario& b, int user, const std::vector<std::uint32_t>& rtt_ticks,
                                       const std::vector<int>& loss_allowance_ticks, double margin, double override_B, int agreement,
                                       const StepSet* steps) {
  const auto& nbrs = b.neighbors[static_cast<std::size_t>(user)];
  if (rtt_ticks.size() != nbrs.size() || loss_allowance_ticks.size() != nbrs.size())
    throw std::invalid_argument("bounds_from_round_trips: one bound and one loss allowance per neighbour needed");
  MeasuredBounds m;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const model::LinkBound l = model::link_bound_from_round_trip(static_cast<int>(rtt_ticks[n]), loss_allowance_ticks[n],
                                                                 b.spec.tx_deadband, agreement, b.spec.receive_rule);
    m.round_trip_ticks.push_back(l.round_trip_ticks);
    m.index_guard_ticks.push_back(l.guard_ticks);
    m.assumed_sum_ticks.push_back(l.assumed_sum_ticks);
  }
  const model::Damping d = steps ? b.damping_eq18(user, m.assumed_sum_ticks, override_B, margin, steps->own.t_min_s, steps->t_max_j_s)
                                 : b.damping_eq18(user, m.assumed_sum_ticks, override_B, margin);
  m.damping_min_Ns_per_m = d.min_Ns_per_m;
  m.damping_Ns_per_m = d.used_Ns_per_m;
  m.passivity_condition_met = d.condition_met;
  return m;
}

BuildResult build_station_core(const StationPlan& plan, const ProbeResult& probe, const drivers::DeviceCapabilities& device,
                               const double* device_position_m) {
  BuildResult r;
  const StationSection& S = plan.file.station;
  const BuiltScenario& built = *plan.built;
  try {
    // Each link's loss allowance (both ends agreed on it while probing) and the transmission
    // deadband's: the passivity budget (model::link_bound_from_round_trip, model::damping_eq18).
    r.bounds = bounds_from_round_trips(built, plan.me, probe.rtt_bound_ticks, probe.loss_allowance_ticks, S.damping_margin, S.damping_Ns_per_m,
                                       S.agreement_ticks, probe.steps.fixed ? &probe.steps : nullptr);
    r.passivity_condition_met = r.bounds.passivity_condition_met;
    rt::StationConfig sc = built.station_config(plan.me);
    sc.damping_Ns_per_m = r.bounds.damping_Ns_per_m;
    if (probe.steps.fixed) {  // this station's own step bounds (StepSet), not the plan's limits
      sc.period_min_s = probe.steps.own.t_min_s;
      sc.period_max_s = probe.steps.own.t_max_s;
    }
    // the opened device's own capabilities + the [device] keys; eq. (26) again (the plan checked the published figures)
    r.coupling = device_coupling(plan.file, built.spec, device);
    check_device_coupling(r.coupling, sc.t_min(), sc.t_max());
    sc.vp.coupling = r.coupling.gains;
    sc.device_damping_Ns_per_m = r.coupling.object_b_d_Ns_per_m();  // eq. (26) in the object frame: b_d / scale^2
    sc.device_force_feedback = r.coupling.force_feedback;
    if (r.coupling.force_limit_N > 0) sc.max_device_force_N = r.coupling.object_force_limit_N();  // the device's limit, the only one
    r.map = drivers::WorkspaceMap(workspace_map_config(plan.file, device));
    if (device_position_m != nullptr) {
      sc.vp_initial_position_m = initial_proxy_position(r.map.to_object(device_position_m, nullptr), built.scene, sc.contact_nodes, &r.proxy_projected);
      r.proxy_from_device = true;
    }
    r.proxy_start_m = sc.vp_initial_position_m;
    for (std::size_t n = 0; n < sc.neighbors.size(); ++n) {
      auto& nc = sc.neighbors[n];
      nc.index_delay_bound_ticks = r.bounds.index_guard_ticks[n];
      if (probe.steps.fixed && n < probe.steps.t_max_j_s.size()) {  // the state check's step fit: the bounds eq. (18) took
        nc.step_max_s = probe.steps.t_max_j_s[n];
        nc.step_min_s = model::announced_step_min(built.spec.period_s, nc.step_max_s);
      }
    }
    // "auto": measured on this machine (firmware/station/solver_choice.hpp); "auto-fixed": rt's size rule
    sc.solver.kind = rt::parse_step_solver_kind(S.solver == "auto-fixed" ? "auto" : S.solver);
    if (S.solver == "auto") {
      r.solver_choice = measure_solver_choice(sc);
      sc.solver.kind = r.solver_choice.kind;
    }
    r.core = std::make_unique<rt::StationCore>(sc);
    for (int R : r.bounds.round_trip_ticks) r.max_age_s.push_back((R + S.age_slack_ticks) * built.spec.period_s);
    r.tx_deadband = rt::TxDeadband(built.spec.tx_deadband, built.scene.dofs, built.spec.period_s);
    r.status = PhaseStatus::kOk;
  } catch (const std::exception& e) {
    r.status = PhaseStatus::kFailed;
    r.message = std::string("building the station core: ") + e.what();
  }
  return r;
}

}  // namespace haptic::firmware
