#include "firmware/sim/simulator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <queue>
#include <stdexcept>

#include "firmware/station/link_impairment.hpp"
#include "firmware/run/summary.hpp"
#include "firmware/sim/in_place_slots.hpp"
#include "firmware/session/recorder.hpp"
#include "firmware/station/plan.hpp"
#include "net/impairment.hpp"
#include "net/wire.hpp"
#include "rt/tick_driver.hpp"
#include "rt/tx_deadband.hpp"

namespace haptic::firmware {

namespace {

struct InFlight {
  double arrive_s;
  std::uint64_t order;
  SimPacket packet;
  bool operator>(const InFlight& o) const { return arrive_s != o.arrive_s ? arrive_s > o.arrive_s : order > o.order; }
};

struct Channel {
  int to = 0, from = 0, rx_index = 0;
  net::SendImpairment link;
  std::priority_queue<InFlight, std::vector<InFlight>, std::greater<>> queue;
  std::int64_t max_seq_delivered = -1;
  LinkStats stats;
  InPlaceSlots slots;  // the payloads the receive link reads in place
};


// One station's clock in simulated time (ScenarioSpec's clock model): tick k wakes at its grid
// time g(k) plus a wake delay in [0, timer_jitter]; g advances by T rate (1 + F u). Without a clock
// model every station wakes at exactly k T (the lockstep of earlier versions, bit for bit).
struct StationClock {
  double rate = 1, T = 0, F = 0, J = 0;
  net::Rng rng;
  std::int64_t k = 0;          // the station's next tick
  double grid = 0, wake = 0;   // g(k) and its wake time
  double next_grid = 0, next_wake = 0;
  double prev_wake = 0;        // the previous tick's wake (k > 0)
  StationClock(double T_s, double rate_, double F_, double J_, std::uint64_t seed) : rate(rate_), T(T_s), F(F_), J(J_), rng(seed) {
    wake = J > 0 ? J * rng.uniform01() : 0.0;
    draw_next();
  }
  void draw_next() {
    next_grid = F > 0 || rate != 1.0 ? grid + T * rate * (1 + F * (2 * rng.uniform01() - 1)) : static_cast<double>(k + 1) * T;
    next_wake = next_grid + (J > 0 ? J * rng.uniform01() : 0.0);
  }
  // T_k as the real station measures it: this wake minus the previous one (the first tick, and every
  // tick without a clock model: the nominal T, bit for bit)
  double step() const { return k == 0 || (J == 0 && F == 0 && rate == 1.0) ? T : wake - prev_wake; }
  void advance() {
    ++k;
    prev_wake = wake;
    grid = next_grid;
    wake = next_wake;
    draw_next();
  }
};

// UDP payload bytes of one state on the station's default wire (float32 values, headers, MACs).
std::uint64_t state_wire_bytes(int dofs) {
  net::WireConfig wc;
  wc.encoding = net::ValueEncoding::float32;
  const net::Encoder enc(wc);
  const auto values = static_cast<std::uint32_t>(dofs);
  return enc.payload_bytes(values) + enc.fragment_count(values) * (net::kHeaderBytes + net::kMacBytes);
}

// One lossless session recorder per station when opt.record (each station's initial state
// recorded before its first tick). Not RT-safe.
std::vector<std::unique_ptr<SessionRecorder>> open_sim_recorders(const BuiltScenario& b, const SimOptions& opt,
                                                                 const std::vector<std::unique_ptr<rt::StationCore>>& st) {
  std::vector<std::unique_ptr<SessionRecorder>> rec;
  if (!opt.record) return rec;
  if (opt.out_dir.empty()) throw std::invalid_argument("--record needs --out");
  for (std::size_t i = 0; i < st.size(); ++i) {
    RecorderConfig rc;
    rc.path = opt.out_dir + "/station-" + std::to_string(i + 1) + ".h5";
    rc.lossless = true;
    rc.deflate_level = opt.record_deflate;
    rc.max_bytes = opt.record_max_mb > 0 ? static_cast<std::uint64_t>(opt.record_max_mb * 1024 * 1024) : ~0ull;
    rc.ring_ticks = static_cast<std::uint64_t>(std::llround(opt.record_ring_s / b.spec.period_s));
    SessionInfo info;
    info.source = "sim";
    info.scenario = b.spec.name;
    info.station_id = static_cast<int>(i) + 1;
    info.config_text = opt.command_line;
    info.fingerprint = fingerprint_text(scene_fingerprint(b, std::llround(b.spec.period_s * 1e9))) + ", scenario " + b.spec.name;
    info.damping_min_Ns_per_m = i < b.damping_min.size() ? b.damping_min[i] : -1;
    info.passivity_condition_met = b.passivity_condition_met;
    rec.push_back(std::make_unique<SessionRecorder>(rc, info, st[i]->config()));
    rec.back()->rt_initial_state(st[i]->x().data(), st[i]->v().data());
  }
  return rec;
}

// Everything one simulation run holds: stations, users, channels, metrics, output files.
struct Simulation {
  Simulation(const BuiltScenario& built, const SimOptions& options);

  const BuiltScenario& b;
  const SimOptions& opt;
  int N, n, dofs;
  double T;
  std::int64_t ticks;
  std::chrono::steady_clock::time_point wall0 = std::chrono::steady_clock::now();
  std::vector<std::unique_ptr<rt::StationCore>> st;
  std::vector<rt::SimulatedUser> users;
  std::vector<rt::TxDeadband> tx;  // transmission policy per station (rt/tx_deadband)
  std::uint64_t state_bytes;
  std::vector<Channel> ch;
  std::vector<StationClock> clk;  // per station (ScenarioSpec's clock model)
  std::vector<unsigned char> due; // stations waking at the current event time
  std::vector<std::vector<int>> out_channels;  // channels each station sends on
  std::vector<std::vector<int>> in_channels;   // channels each station receives on, by receive link
  std::vector<Eigen::Vector3d> forces;
  std::vector<const double*> copies;
  std::vector<std::unique_ptr<SessionRecorder>> rec;  // session logs (opt.record)
  std::uint64_t order = 0;
  RunMetrics metrics;
  std::optional<double> diverged_at_s;
  double d2 = 0;
  OutFile trace, series;
  std::vector<Snapshot> snapshots;
  std::vector<double> snap_times;
  std::size_t next_snap = 0;
  int last_pct = -1;
};

// Directed channels: one per (receiver i, sender j) on every link; seeds derived from the run seed.
void make_channels(Simulation& s) {
  s.out_channels.assign(static_cast<std::size_t>(s.N), {});
  s.in_channels.assign(static_cast<std::size_t>(s.N), {});
  for (int i = 0; i < s.N; ++i)
    for (std::size_t r = 0; r < s.b.neighbors[static_cast<std::size_t>(i)].size(); ++r) {
      Channel c;
      c.to = i;
      c.from = s.b.neighbors[static_cast<std::size_t>(i)][r];
      c.rx_index = static_cast<int>(r);
      c.link = simulator_channel(s.b.spec, i, c.from);
      c.stats.to = i;
      c.stats.from = c.from;
      c.stats.sent_ticks.reserve(static_cast<std::size_t>(s.ticks));
      s.ch.push_back(std::move(c));
      s.out_channels[static_cast<std::size_t>(s.ch.back().from)].push_back(static_cast<int>(s.ch.size()) - 1);
      s.in_channels[static_cast<std::size_t>(i)].push_back(static_cast<int>(s.ch.size()) - 1);
    }
}

Simulation::Simulation(const BuiltScenario& built, const SimOptions& options)
    : b(built),
      opt(options),
      N(built.spec.users),
      n(built.scene.nodes),
      dofs(built.scene.dofs),
      T(built.spec.period_s),
      ticks(static_cast<std::int64_t>(std::llround(built.spec.duration_s / built.spec.period_s))),
      state_bytes(state_wire_bytes(built.scene.dofs)),
      forces(static_cast<std::size_t>(built.spec.users), Eigen::Vector3d::Zero()),
      metrics(metrics_windows(built.spec.script), built.spec.period_s),
      snap_times(options.snapshot_times_s) {
  if (opt.trace_every < 1 || opt.series_every < 1) throw std::invalid_argument("--trace-every must be >= 1");
  due.assign(static_cast<std::size_t>(N), 0);
  for (int i = 0; i < N; ++i)
    clk.emplace_back(T, b.clock_rate[static_cast<std::size_t>(i)], b.spec.step_jitter, b.spec.timer_jitter_s,
                     b.spec.seed * 6364136223846793005ULL + 977ULL * static_cast<std::uint64_t>(i) + 11ULL);
  for (int i = 0; i < N; ++i) {
    st.push_back(std::make_unique<rt::StationCore>(b.station_config(i)));
    users.emplace_back(b.spec.device, b.spec.hand, b.goal_script(i));
    users.back().reset(b.vp_start[static_cast<std::size_t>(i)]);
    tx.emplace_back(b.spec.tx_deadband, dofs, T);
    copies.push_back(st.back()->x().data());
  }
  make_channels(*this);
  rec = open_sim_recorders(b, opt, st);
  if (!opt.out_dir.empty()) {
    trace = open_out_file(opt.out_dir + "/trace.csv");
    series = open_out_file(opt.out_dir + "/series.csv");
    write_trace_header(trace.get());
    write_series_header(series.get());
  }
  std::sort(snap_times.begin(), snap_times.end());
}

// 1. The packets that have arrived on station i's channels by t, each channel's in arrival order
// (rt::drive_tick's source for station i's tick).
template <class Offer>
void arrived_packets(Simulation& s, int i, double t, Offer&& offer) {
  for (int ci : s.in_channels[static_cast<std::size_t>(i)]) {
    auto& c = s.ch[static_cast<std::size_t>(ci)];
    while (!c.queue.empty() && c.queue.top().arrive_s <= t + 1e-12) {
      const InFlight p = c.queue.top();
      c.queue.pop();
      ++c.stats.delivered;
      const double d = p.arrive_s - p.packet.send_s;
      c.stats.delay_sum_s += d;
      c.stats.delay_max_s = std::max(c.stats.delay_max_s, d);
      if (p.packet.seq < c.max_seq_delivered) ++c.stats.reordered;
      c.max_seq_delivered = std::max(c.max_seq_delivered, p.packet.seq);
      c.slots.hand_in(c.rx_index, p.packet, s.dofs, offer);
    }
  }
}

// 2. Every station waking at t ticks: the packets arrived by t (1.) reach its receive links, then
// the step with its device sampled at t and its step T_k.
void tick_stations(Simulation& s, double t) {
  for (int i = 0; i < s.N; ++i) {
    if (!s.due[static_cast<std::size_t>(i)]) continue;
    const auto& ck = s.clk[static_cast<std::size_t>(i)];
    const std::int64_t k = ck.k;
    auto& core = *s.st[static_cast<std::size_t>(i)];
    const auto& q = s.users[static_cast<std::size_t>(i)].position_m();
    const double step_s = ck.step();
    SessionRecorder* recorder = s.rec.empty() ? nullptr : s.rec[static_cast<std::size_t>(i)].get();
    const auto began = recorder ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    const auto out = rt::drive_tick(core, rt::TickDrive{k, 0, q, step_s}, [&](auto&& offer) { arrived_packets(s, i, t, offer); },
                                    RecordOffered{recorder, k});
    if (recorder) {  // the log's exec_ns: this step's time on this host (its packets in, the solve), as a station's tick records its own
      TickRecord row = make_tick_record(core, k, q, out, step_s);
      const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - began).count();
      row.exec_ns = static_cast<std::int32_t>(std::min<std::int64_t>(ns, INT32_MAX));
      recorder->rt_tick(row);
    }
    s.forces[static_cast<std::size_t>(i)] = out.device_force_N;
    if ((out.flags & rt::kDiverged) && !s.diverged_at_s) {
      s.diverged_at_s = t;
      s.metrics.add_divergence(t);
    }
  }
}

// d^2 of eq. (13) after the first tick (model::eq13_d2_J): the copies' energies, the consensus
// springs phi_pq(0) of the links and, with --consensus-passivity pspm, the modulation's reservoirs.
double passivity_bound_J(const Simulation& s) {
  std::vector<double> copies, springs;
  for (int i = 0; i < s.N; ++i) copies.push_back(s.st[static_cast<std::size_t>(i)]->energy().vo_J);
  for (std::size_t e = 0; e < s.b.spec.topology.size(); ++e) {
    const auto& l = s.b.spec.topology[e];
    springs.push_back(model::consensus_spring_J(s.b.gains[e], s.st[static_cast<std::size_t>(l.a)]->x().data(), s.st[static_cast<std::size_t>(l.b)]->x().data()));
  }
  return model::eq13_d2_J(copies, springs,
                          model::pspm_reservoirs_J(s.b.spec.consensus_passivity, static_cast<int>(s.b.spec.topology.size()), s.b.spec.pspm_reservoir0_J));
}

// 3. Every station sends x_hat(k), v_hat(k) to its neighbours through the impaired links.
void send_states(Simulation& s, double t) {
  for (int i = 0; i < s.N; ++i) {
    if (!s.due[static_cast<std::size_t>(i)]) continue;
    const std::int64_t k = s.clk[static_cast<std::size_t>(i)].k;
    const auto& core = *s.st[static_cast<std::size_t>(i)];
    if (!s.tx[static_cast<std::size_t>(i)].should_send(k, core.x_hat(), core.v_hat())) continue;
    auto payload = std::make_shared<std::vector<double>>(static_cast<std::size_t>(2 * s.dofs));
    const bool finite = (rt::copy_non_finite(core.x_hat(), payload->data(), s.dofs) |
                         rt::copy_non_finite(core.v_hat(), payload->data() + s.dofs, s.dofs)) == 0;
    for (int ci : s.out_channels[static_cast<std::size_t>(i)]) {
      auto& c = s.ch[static_cast<std::size_t>(ci)];
      ++c.stats.sent;
      c.stats.bytes_sent += s.state_bytes;
      c.stats.sent_ticks.push_back(k);
      const auto fate = c.link.fate(static_cast<std::uint64_t>(core.sequence()), t);
      if (fate.lost) ++c.stats.lost;
      if (fate.duplicated) ++c.stats.duplicated;
      for (int cp = 0; cp < fate.copies; ++cp) c.queue.push(InFlight{t + fate.delay_s[cp], s.order++, SimPacket{core.sequence(), t, payload, finite}});
    }
  }
}

// 5. The run metrics of tick k (firmware/run/metrics) and series.csv's row.
SeriesRow measure(Simulation& s, std::int64_t k) {
  const CopiesSample c = measure_copies(s.copies, s.b.scene.x_d);
  s.metrics.add_copies(k, c);
  double vmax = 0;
  model::StationTotals total;
  for (int i = 0; i < s.N; ++i) {
    const auto& core = *s.st[static_cast<std::size_t>(i)];
    for (int p = 0; p < s.n; ++p) vmax = std::max(vmax, core.v().segment<3>(3 * p).norm());
    total.add_force(s.forces[static_cast<std::size_t>(i)]);
    total.add_energies(core.energy().port_J, core.energy().controller_J);
  }
  s.metrics.add_speed(vmax);
  s.metrics.add_forces(k, s.forces);
  s.metrics.add_energies(total.port_J, total.controller_J);
  SeriesRow row{static_cast<double>(k + 1) * s.T, c.consensus_error_m, c.deformation_m, total.port_J, total.controller_J, total.force_N[0],
                total.force_N.norm()};
  row.set_forces(model::force_balance(s.forces));
  const Eigen::Vector3d node = model::mean_node_position_m(s.copies, s.b.trace_node);
  for (int a = 0; a < 3; ++a) row.trace_node_mean_m[a] = node[a];
  return row;
}

void write_trace(Simulation& s, std::int64_t k, const SeriesRow& row) {
  if (!s.trace) return;
  if (k % s.opt.series_every == 0) write_series_row(s.series.get(), row);
  if (k % s.opt.trace_every != 0) return;
  for (int i = 0; i < s.N; ++i) {
    const auto& core = *s.st[static_cast<std::size_t>(i)];
    TraceRow r;
    r.t_s = row.t_s;
    r.user = i + 1;
    const auto xn = core.x().segment<3>(3 * s.b.trace_node);
    for (int a = 0; a < 3; ++a) {
      r.node[a] = xn[a];
      r.force[a] = s.forces[static_cast<std::size_t>(i)][a];
      r.vp[a] = core.vp_position_m()[a];
      r.device[a] = s.users[static_cast<std::size_t>(i)].position_m()[a];
    }
    r.port_J = core.energy().port_J;
    r.ctrl_J = core.energy().controller_J;
    r.vo_J = core.energy().vo_J;
    r.contact = core.in_contact();
    write_trace_row(s.trace.get(), r);
  }
}

// Node positions of every copy and every proxy at the requested times.
void take_snapshots(Simulation& s, double t_next) {
  while (s.next_snap < s.snap_times.size() && t_next >= s.snap_times[s.next_snap] - 1e-9) {
    Snapshot sn;
    sn.t_s = t_next;
    for (int i = 0; i < s.N; ++i) {
      const auto& x = s.st[static_cast<std::size_t>(i)]->x();
      sn.x_m.emplace_back(x.data(), x.data() + s.dofs);
      const auto& y = s.st[static_cast<std::size_t>(i)]->vp_position_m();
      sn.vp_m.push_back({y[0], y[1], y[2]});
    }
    s.snapshots.push_back(std::move(sn));
    ++s.next_snap;
  }
}

void report_progress(Simulation& s, std::int64_t k, double t_next, double err) {
  if (!s.opt.progress) return;
  const int pct = static_cast<int>(100 * (k + 1) / s.ticks);
  if (pct / 10 == s.last_pct / 10) return;
  s.last_pct = pct;
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - s.wall0).count();
  std::fprintf(stderr, "  %s: %3d%%  %.1f/%.1f s simulated, %.1f s wall, consensus error %.3g mm\n", s.b.spec.name.c_str(), pct, t_next,
               s.b.spec.duration_s, wall, err * 1e3);
}

// The stations waking at t (every station's clock at the earliest wake): deliver, tick, send,
// move their users over their steps T_k, advance their clocks.
void wake_stations(Simulation& s, double t) {
  for (int i = 0; i < s.N; ++i) s.due[static_cast<std::size_t>(i)] = s.clk[static_cast<std::size_t>(i)].wake == t ? 1 : 0;
  tick_stations(s, t);
  send_states(s, t);
  // 4. the users' devices move under the commanded force until their station's next wake
  for (int i = 0; i < s.N; ++i) {
    if (!s.due[static_cast<std::size_t>(i)]) continue;
    auto& ck = s.clk[static_cast<std::size_t>(i)];
    s.users[static_cast<std::size_t>(i)].advance(t, ck.step(), s.forces[static_cast<std::size_t>(i)]);
    ck.advance();
  }
}

// Measurement m, on the common grid t = (m + 1) T (all wakes before it done): metrics, records.
void measure_at(Simulation& s, std::int64_t m) {
  if (m == 0) s.d2 = passivity_bound_J(s);
  const SeriesRow row = measure(s, m);
  write_trace(s, m, row);
  take_snapshots(s, row.t_s);
  report_progress(s, m, row.t_s, row.consensus_error_m);
}

SimResult finish(Simulation& s, std::int64_t ticks_run) {
  SimResult r;
  r.ticks = static_cast<std::uint64_t>(ticks_run);
  r.metrics = s.metrics.result(ticks_run);
  r.passivity_bound_J = s.d2;
  for (auto& c : s.ch) {
    auto& core = *s.st[static_cast<std::size_t>(c.to)];
    c.stats.max_index_delay = core.rx(c.rx_index).counters().max_index_delay;
    c.stats.bound_violations = core.edge_drop_events(c.rx_index);
    c.stats.resilient_excluded_ticks = core.resilient_excluded_ticks(c.rx_index);
    c.stats.state_check_isolations = core.edge_monitor().isolations(c.rx_index);
    c.stats.edge_energy = edge_energy_summary(core, c.rx_index);
    if (const rt::SetPositionModulator* m = core.set_position_modulator(c.rx_index)) {
      c.stats.pspm_limited_ticks = m->limited_ticks();
      c.stats.pspm_injected_J = m->injected_J();
      c.stats.pspm_reservoir_J = m->reservoir_J();
    }
    r.links.push_back(c.stats);
  }
  for (const auto& core : s.st) {
    r.steps_clamped += core->step_clamped_ticks();
    r.final_port_J.push_back(core->energy().port_J);
    r.final_controller_J.push_back(core->energy().controller_J);
    r.solver.emplace_back(core->solver_name());
    r.final_solver_residual_J.push_back(core->energy().solver_residual_J);
    r.solver_unconverged_ticks.push_back(core->solver_unconverged_ticks());
    r.solver_iterations_mean.push_back(core->solver_iterations_mean());
    r.final_x.push_back(core->x());
  }
  for (auto& recorder : s.rec) recorder->finish();
  r.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - s.wall0).count();
  r.trace_every = s.opt.trace_every;
  r.series_every = s.opt.series_every;
  if (!s.opt.out_dir.empty() && !s.snap_times.empty())
    write_snapshots_json(s.opt.out_dir + "/snapshots.json", s.b.scene.mesh.surface, s.b.contact_nodes, s.snapshots);
  return r;
}

// States sent on a link at ticks k with t0 <= k T < t1.
std::uint64_t sent_between(const LinkStats& l, double t0, double t1, double T) {
  std::uint64_t n = 0;
  for (std::int64_t k : l.sent_ticks) n += (k * T >= t0 - 1e-9 && k * T < t1 - 1e-9) ? 1 : 0;
  return n;
}

// The simulator's link_stats row: the common contract plus bandwidth over the run, the hold window
// and after consensus (the transmission policy, rt/tx_deadband, decides what is sent).
nlohmann::json sim_link_json(const BuiltScenario& b, const SimResult& r, const LinkStats& l, double settled_from_s) {
  const double T = b.spec.period_s, run_s = static_cast<double>(r.ticks) * T;
  LinkSummary ls;
  ls.to = l.to + 1;
  ls.from = l.from + 1;
  ls.sent = l.sent;
  ls.delivered = l.delivered;
  ls.lost = l.lost;
  ls.duplicated = l.duplicated;
  ls.reordered = l.reordered;
  if (l.delivered) ls.mean_delay_ms = 1e3 * l.delay_sum_s / static_cast<double>(l.delivered);
  if (l.delivered) ls.max_delay_ms = 1e3 * l.delay_max_s;
  ls.max_index_delay_ticks = l.max_index_delay;
  ls.bound_violations = l.bound_violations;
  ls.index_delay_bound_ticks = b.nbar_ticks(l.to, l.from);
  ls.edge_energy = l.edge_energy;
  nlohmann::json j = link_json(ls);
  if (b.spec.resilient_f > 0) j["resilient_excluded_ticks"] = l.resilient_excluded_ticks;  // only when on: summaries unchanged when off
  if (b.spec.state_check.enabled()) j["state_check_isolations"] = l.state_check_isolations;  // likewise
  j["packets_per_s"] = run_s > 0 ? nlohmann::json(static_cast<double>(l.sent) / run_s) : nlohmann::json(nullptr);
  j["bytes_per_s"] = run_s > 0 ? nlohmann::json(static_cast<double>(l.bytes_sent) / run_s) : nlohmann::json(nullptr);
  j["sent_in_hold_window"] = sent_between(l, r.metrics.hold_window_start_s, r.metrics.hold_window_end_s, T);
  j["sent_after_consensus"] = sent_between(l, settled_from_s, run_s + T, T);
  if (b.spec.consensus_passivity == rt::ConsensusPassivity::kSetPositionModulation) {
    j["pspm_limited_ticks"] = l.pspm_limited_ticks;
    j["pspm_injected_J"] = l.pspm_injected_J;
    j["pspm_reservoir_J"] = l.pspm_reservoir_J;
  }
  return j;
}

}  // namespace

net::SendImpairment simulator_channel(const ScenarioSpec& spec, int receiver, int sender) {
  const LinkSetup ls = scenario_link(spec, receiver, sender, spec.seed);
  return net::SendImpairment(ls.model, ls.seed, 0);
}

int default_trace_every(int users) { return std::max(1, (users + 7) / 8); }

SimResult run_simulation(const BuiltScenario& b, const SimOptions& opt) {
  Simulation s(b, opt);
  std::int64_t m = 0;  // measurements taken (common grid)
  while (m < s.ticks) {
    double t = s.clk[0].wake;
    for (const auto& c : s.clk) t = std::min(t, c.wake);
    bool stop = false;
    while (m < s.ticks && t >= static_cast<double>(m + 1) * s.T - 1e-12) {
      measure_at(s, m);
      ++m;
      if (s.diverged_at_s && static_cast<double>(m - 1) * s.T > *s.diverged_at_s + 0.5) stop = true;
      if (stop) break;
    }
    if (stop || m >= s.ticks) break;
    wake_stations(s, t);
  }
  return finish(s, m);
}

std::string sim_verdict(const SimResult& r) {
  return run_verdict(r.metrics.diverged, r.metrics.unstable, sim_gate_summary(r), model::eq13_broken(r.metrics.port_energy_min_J, r.passivity_bound_J));
}

GateSummary sim_gate_summary(const SimResult& r) {
  GateSummary g;
  for (const auto& l : r.links) {
    g.trips += l.edge_energy.trips;
    g.gated_ticks += l.edge_energy.gated_ticks;
    g.removed_J += l.edge_energy.removed_J;
    g.edge_drop_events += l.bound_violations;
  }
  g.port_energy_min_J = r.metrics.port_energy_min_J;
  return g;
}

void write_summary_json(const std::string& path, const BuiltScenario& b, const SimResult& r) {
  using nlohmann::json;
  json j = scenario_json(b);
  j["mode"] = "sim";
  j["damping_Ns_per_m"] = b.damping;
  j["damping_min_Ns_per_m"] = b.damping_min;
  j["round_trip_half_sum_ms"] = b.round_trip_sum_ms;
  j["passivity_condition_met"] = b.passivity_condition_met;  // eq. (18) (eq18), by construction (pspm)
  j["period_min_s"] = b.t_min_s;  // T_i^min, T_i^max of eq. (18) and (26) (the clock model's bounds)
  j["period_max_s"] = b.t_max_s;
  j["clock"] = {{"timer_jitter_ms", 1e3 * b.spec.timer_jitter_s}, {"step_jitter", b.spec.step_jitter}, {"clock_drift_ppm", b.spec.clock_drift_ppm}};
  j["steps_clamped"] = r.steps_clamped;
  j["consensus_passivity"] = rt::consensus_passivity_name(b.spec.consensus_passivity);
  if (b.spec.resilient_f > 0) j["resilient_f"] = b.spec.resilient_f;  // only when on: summaries unchanged when off
  if (b.spec.state_check.enabled()) j["state_check"] = {{"kinematic_m", b.spec.state_check.kinematic_bound_m < rt::EdgeMonitorParams::kOff ? nlohmann::json(b.spec.state_check.kinematic_bound_m) : nlohmann::json(nullptr)},
                                                     {"disagreement_m", b.spec.state_check.disagreement_bound_m < rt::EdgeMonitorParams::kOff ? nlohmann::json(b.spec.state_check.disagreement_bound_m) : nlohmann::json(nullptr)}};
  if (b.spec.edge_energy_hold_s > 0) j["edge_energy_hold_s"] = b.spec.edge_energy_hold_s;
  if (b.spec.consensus_passivity == rt::ConsensusPassivity::kSetPositionModulation) j["pspm_reservoir0_J"] = b.spec.pspm_reservoir0_J;
  j["push_pattern"] = b.spec.script.push_pattern == UserScriptSpec::PushPattern::kAsymmetric ? "asymmetric" : "spread";
  j["push_depth_m"] = b.push_depth_m;
  j["push_imbalance_ratio"] = b.push_imbalance_ratio;
  j.update(metrics_json(r.metrics));
  j["passivity_bound_J"] = r.passivity_bound_J;
  j["eq13_broken"] = model::eq13_broken(r.metrics.port_energy_min_J, r.passivity_bound_J);
  j["port_energy_final_J"] = r.final_port_J;
  j["controller_energy_final_J"] = r.final_controller_J;
  j["solver"] = r.solver;
  j["solver_residual_energy_final_J"] = r.final_solver_residual_J;
  j["solver_unconverged_ticks"] = r.solver_unconverged_ticks;
  j["solver_iterations_mean"] = r.solver_iterations_mean;
  j["edge_energy_bound_J"] = b.spec.edge_energy_bound_J > 0 ? json(b.spec.edge_energy_bound_J) : json(nullptr);
  const GateSummary gate = sim_gate_summary(r);
  j["edge_energy_trips"] = gate.trips;
  j["gate"] = gate_json(gate);
  j["verdict"] = sim_verdict(r);
  const double run_s = r.metrics.simulated_s;
  const auto& ct = r.metrics.consensus_time_s;
  const double settled_from_s = ct ? r.metrics.release_time_s + *ct : run_s;
  json links = json::array();
  std::vector<LinkSummary> totals;
  std::uint64_t sent_hold = 0, sent_settled = 0;
  for (const auto& l : r.links) {
    links.push_back(sim_link_json(b, r, l, settled_from_s));
    sent_hold += links.back()["sent_in_hold_window"].get<std::uint64_t>();
    sent_settled += links.back()["sent_after_consensus"].get<std::uint64_t>();
    totals.push_back(LinkSummary{0, 0, l.sent, l.delivered, l.lost, l.duplicated, l.reordered, {}, {}, {}, {}, {}, {}});
  }
  json pk = packets_json(totals);
  pk["sent_in_hold_window"] = sent_hold;
  pk["sent_after_consensus"] = sent_settled;
  pk["after_consensus_s"] = run_s - settled_from_s;
  j["packets"] = pk;
  j["link_stats"] = links;
  j["trace_every"] = r.trace_every;
  j["series_every"] = r.series_every;
  j["wall_time_s"] = r.wall_time_s;
  write_json_file(path, j);
}

}  // namespace haptic::firmware
