#include "firmware/simulator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <queue>
#include <stdexcept>

#include "firmware/link_impairment.hpp"
#include "firmware/session_recorder.hpp"
#include "net/impairment.hpp"
#include "net/wire.hpp"
#include "rt/tx_deadband.hpp"

namespace haptic::firmware {

namespace {

struct InFlight {
  double arrive_s;
  std::uint64_t order;
  std::int64_t seq;
  double send_s;
  std::shared_ptr<const std::vector<double>> payload;  // x_hat then v_hat
  bool operator>(const InFlight& o) const { return arrive_s != o.arrive_s ? arrive_s > o.arrive_s : order > o.order; }
};

struct Channel {
  int to = 0, from = 0, rx_index = 0;
  net::SendImpairment link;
  std::priority_queue<InFlight, std::vector<InFlight>, std::greater<>> queue;
  std::int64_t max_seq_delivered = -1;
  LinkStats stats;
};

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// max over user pairs and nodes of |x_i - x_j| (inf when not finite)
double consensus_error(const std::vector<std::unique_ptr<rt::StationCore>>& st, int nodes) {
  double err = 0;
  for (std::size_t i = 0; i < st.size(); ++i)
    for (std::size_t j = i + 1; j < st.size(); ++j) {
      const auto& xi = st[i]->x();
      const auto& xj = st[j]->x();
      for (int p = 0; p < nodes; ++p) err = std::max(err, (xi.segment<3>(3 * p) - xj.segment<3>(3 * p)).norm());
    }
  return std::isfinite(err) ? err : INFINITY;
}

// States sent on a link at ticks k with t0 <= k T < t1.
std::uint64_t sent_between(const LinkStats& l, double t0, double t1, double T) {
  std::uint64_t n = 0;
  for (std::int64_t k : l.sent_ticks) n += (k * T >= t0 - 1e-9 && k * T < t1 - 1e-9) ? 1 : 0;
  return n;
}

File open_out(const std::string& path) {
  File f(std::fopen(path.c_str(), "w"));
  if (!f) throw std::runtime_error("cannot write " + path);
  return f;
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
    rc.max_bytes = ~0ull;
    SessionInfo info;
    info.source = "sim";
    info.station_id = static_cast<int>(i) + 1;
    info.config_text = opt.command_line;
    info.fingerprint = "scene nodes " + std::to_string(b.scene.nodes) + ", scenario " + b.spec.name;
    rec.push_back(std::make_unique<SessionRecorder>(rc, info, st[i]->config()));
    rec.back()->rt_initial_state(st[i]->x().data(), st[i]->v().data());
  }
  return rec;
}

}  // namespace

net::SendImpairment simulator_channel(const ScenarioSpec& spec, int receiver, int sender) {
  const LinkSetup ls = scenario_link(spec, receiver, sender, spec.seed);
  return net::SendImpairment(ls.model, ls.seed, 0);
}

SimResult run_simulation(const BuiltScenario& b, const SimOptions& opt) {
  const auto wall0 = std::chrono::steady_clock::now();
  const auto& spec = b.spec;
  const int N = spec.users;
  const double T = spec.period_s;
  const auto ticks = static_cast<std::int64_t>(std::llround(spec.duration_s / T));
  const int n = b.scene.nodes;
  const int dofs = b.scene.dofs;
  if (opt.trace_every < 1) throw std::invalid_argument("--trace-every must be >= 1");

  std::vector<std::unique_ptr<rt::StationCore>> st;
  std::vector<rt::SimulatedUser> users;
  for (int i = 0; i < N; ++i) {
    st.push_back(std::make_unique<rt::StationCore>(b.station_config(i)));
    users.emplace_back(spec.device, spec.hand, b.goal_script(i));
    users.back().reset(b.vp_start[static_cast<std::size_t>(i)]);
  }
  // Transmission policy per station (rt/tx_deadband: every tick unless a deadband is set) and the
  // UDP payload bytes of one state on the station's default wire (float32 values).
  std::vector<rt::TxDeadband> tx;
  for (int i = 0; i < N; ++i) tx.emplace_back(spec.tx_deadband, dofs);
  std::uint64_t state_bytes = 0;
  {
    net::WireConfig wc;
    wc.encoding = net::ValueEncoding::float32;
    const net::Encoder enc(wc);
    const auto values = static_cast<std::uint32_t>(dofs);
    state_bytes = enc.payload_bytes(values) + enc.fragment_count(values) * (net::kHeaderBytes + net::kMacBytes);
  }
  // Directed channels: one per (receiver i, sender j) on every link; seeds derived from the run seed.
  std::vector<Channel> ch;
  std::vector<std::vector<int>> out_channels(static_cast<std::size_t>(N)), in_channels(static_cast<std::size_t>(N));
  for (int i = 0; i < N; ++i)
    for (std::size_t r = 0; r < b.neighbors[static_cast<std::size_t>(i)].size(); ++r) {
      Channel c;
      c.to = i;
      c.from = b.neighbors[static_cast<std::size_t>(i)][r];
      c.rx_index = static_cast<int>(r);
      c.link = simulator_channel(spec, i, c.from);
      c.stats.to = i;
      c.stats.from = c.from;
      c.stats.sent_ticks.reserve(static_cast<std::size_t>(ticks));
      ch.push_back(std::move(c));
      in_channels[static_cast<std::size_t>(i)].push_back(static_cast<int>(ch.size()) - 1);
      out_channels[static_cast<std::size_t>(ch.back().from)].push_back(static_cast<int>(ch.size()) - 1);
    }

  std::vector<std::unique_ptr<SessionRecorder>> rec = open_sim_recorders(b, opt, st);
  File trace, series;
  if (!opt.out_dir.empty()) {
    trace = open_out(opt.out_dir + "/trace.csv");
    series = open_out(opt.out_dir + "/series.csv");
    std::fprintf(trace.get(),
                 "t_s,user,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,"
                 "device_x_m,device_y_m,device_z_m,port_energy_J,controller_energy_J,vo_energy_J,contact\n");
    std::fprintf(series.get(), "t_s,consensus_error_m,deformation_m,port_energy_total_J,controller_energy_total_J,force_sum_x_N,force_sum_norm_N\n");
  }
  nlohmann::json snapshots = nlohmann::json::array();
  std::vector<double> snap_times = opt.snapshot_times_s;
  std::sort(snap_times.begin(), snap_times.end());
  std::size_t next_snap = 0;

  SimResult r;
  const auto& sc = spec.script;
  switch (sc.kind) {
    case UserScriptSpec::Kind::kPushHoldRelease:
      r.release_time_s = sc.release_s;
      r.hold_window_start_s = sc.push_end_s + 0.5 * (sc.release_s - sc.push_end_s);
      r.hold_window_end_s = sc.release_s;
      break;
    case UserScriptSpec::Kind::kPerturb:
      r.release_time_s = sc.perturb_at_s + sc.perturb_duration_s;
      break;
    case UserScriptSpec::Kind::kHold:
    case UserScriptSpec::Kind::kRandom:
      r.release_time_s = 0;
      break;
  }
  double hold_sum = 0, hold_mean = 0, deform_sum = 0;
  std::int64_t hold_count = 0;
  double last_violation_s = -1;
  bool any_violation_after_release = false;
  double port_total_min = 0, ctrl_total_max = 0;
  std::vector<double> deformation_series;
  deformation_series.reserve(static_cast<std::size_t>(ticks));
  std::vector<Eigen::Vector3d> forces(static_cast<std::size_t>(N), Eigen::Vector3d::Zero());
  std::vector<std::uint32_t> flags(static_cast<std::size_t>(N), 0);
  std::uint64_t order = 0;
  Eigen::VectorXd xbar(dofs);
  int last_pct = -1;
  double d2 = 0;

  double last_err = 0;
  std::int64_t k = 0;
  for (; k < ticks; ++k) {
    const double t = k * T;
    // 1. deliver every packet that has arrived by t_k
    for (auto& c : ch) {
      auto& rx = st[static_cast<std::size_t>(c.to)]->rx(c.rx_index);
      while (!c.queue.empty() && c.queue.top().arrive_s <= t + 1e-12) {
        const InFlight p = c.queue.top();
        c.queue.pop();
        ++c.stats.delivered;
        const double d = p.arrive_s - p.send_s;
        c.stats.delay_sum_s += d;
        c.stats.delay_max_s = std::max(c.stats.delay_max_s, d);
        if (p.seq < c.max_seq_delivered) ++c.stats.reordered;
        c.max_seq_delivered = std::max(c.max_seq_delivered, p.seq);
        rx.offer(p.seq, p.send_s, p.payload->data(), p.payload->data() + dofs, dofs);
        if (!rec.empty()) rec[static_cast<std::size_t>(c.to)]->rt_packet(k, c.rx_index, p.seq, p.send_s, p.payload->data(), p.payload->data() + dofs);
      }
    }
    // 2. every station ticks with its device sampled at t_k
    for (int i = 0; i < N; ++i) {
      const auto out = st[static_cast<std::size_t>(i)]->tick(users[static_cast<std::size_t>(i)].position_m());
      if (!rec.empty()) rec[static_cast<std::size_t>(i)]->rt_tick(make_tick_record(*st[static_cast<std::size_t>(i)], k, users[static_cast<std::size_t>(i)].position_m(), out));
      forces[static_cast<std::size_t>(i)] = out.device_force_N;
      flags[static_cast<std::size_t>(i)] = out.flags;
      if (out.flags & rt::kDiverged) {
        if (!r.diverged) r.diverged_at_s = t;
        r.diverged = true;
      }
    }
    if (k == 0) {
      for (int i = 0; i < N; ++i) d2 += st[static_cast<std::size_t>(i)]->energy().vo_J;
      for (std::size_t e = 0; e < spec.topology.size(); ++e) {
        // phi_pq(0) = |x_p(0) - x_q(0)|_P^2 / 4 (all copies start equal: zero)
        const auto& l = spec.topology[e];
        Eigen::VectorXd dx = st[static_cast<std::size_t>(l.a)]->x() - st[static_cast<std::size_t>(l.b)]->x();
        Eigen::VectorXd Pdx = Eigen::VectorXd::Zero(dofs);
        b.gains[e].P.multiply_add(1.0, dx.data(), Pdx.data());
        d2 += dx.dot(Pdx) / 4.0;
      }
    }
    // 3. every station sends x_hat(k), v_hat(k) to its neighbours through the impaired links
    for (int i = 0; i < N; ++i) {
      const auto& s = *st[static_cast<std::size_t>(i)];
      if (!tx[static_cast<std::size_t>(i)].should_send(k, s.x_hat())) continue;
      auto payload = std::make_shared<std::vector<double>>(static_cast<std::size_t>(2 * dofs));
      std::copy(s.x_hat(), s.x_hat() + dofs, payload->begin());
      std::copy(s.v_hat(), s.v_hat() + dofs, payload->begin() + dofs);
      for (int ci : out_channels[static_cast<std::size_t>(i)]) {
        auto& c = ch[static_cast<std::size_t>(ci)];
        ++c.stats.sent;
        c.stats.bytes_sent += state_bytes;
        c.stats.sent_ticks.push_back(k);
        const auto fate = c.link.fate(static_cast<std::uint64_t>(s.sequence()), t);
        if (fate.lost) ++c.stats.lost;
        if (fate.duplicated) ++c.stats.duplicated;
        for (int cp = 0; cp < fate.copies; ++cp) c.queue.push(InFlight{t + fate.delay_s[cp], order++, s.sequence(), t, payload});
      }
    }
    // 4. the users' devices move under the commanded force until t_{k+1}
    for (int i = 0; i < N; ++i) users[static_cast<std::size_t>(i)].advance(t, T, forces[static_cast<std::size_t>(i)]);

    // 5. measurements
    const double t_next = (k + 1) * T;
    const double err = consensus_error(st, n);
    last_err = err;
    r.max_consensus_error_m = std::max(r.max_consensus_error_m, err);
    xbar.setZero();
    double vmax = 0;
    for (int i = 0; i < N; ++i) {
      xbar += st[static_cast<std::size_t>(i)]->x();
      const auto& v = st[static_cast<std::size_t>(i)]->v();
      for (int p = 0; p < n; ++p) vmax = std::max(vmax, v.segment<3>(3 * p).norm());
    }
    r.max_node_speed_m_per_s = std::max(r.max_node_speed_m_per_s, std::isfinite(vmax) ? vmax : INFINITY);
    xbar /= N;
    Eigen::Vector3d mean_disp = Eigen::Vector3d::Zero();
    for (int p = 0; p < n; ++p) mean_disp += xbar.segment<3>(3 * p) - b.scene.x_d.segment<3>(3 * p);
    mean_disp /= n;
    double def2 = 0;
    for (int p = 0; p < n; ++p) def2 += (xbar.segment<3>(3 * p) - b.scene.x_d.segment<3>(3 * p) - mean_disp).squaredNorm();
    const double deformation = std::sqrt(def2 / n);
    deformation_series.push_back(deformation);
    Eigen::Vector3d fsum = Eigen::Vector3d::Zero();
    double fmean = 0;
    double port_total = 0, ctrl_total = 0;
    for (int i = 0; i < N; ++i) {
      fsum += forces[static_cast<std::size_t>(i)];
      fmean += forces[static_cast<std::size_t>(i)].norm() / N;
      port_total += st[static_cast<std::size_t>(i)]->energy().port_J;
      ctrl_total += st[static_cast<std::size_t>(i)]->energy().controller_J;
    }
    port_total_min = std::min(port_total_min, port_total);
    ctrl_total_max = std::max(ctrl_total_max, ctrl_total);
    if (t >= r.hold_window_start_s && t < r.hold_window_end_s) {
      hold_sum += fsum.norm();
      hold_mean += fmean;
      deform_sum += deformation;
      ++hold_count;
    }
    if (t_next > r.release_time_s && !(err < 1e-3)) {
      last_violation_s = t_next;
      any_violation_after_release = true;
    }
    if (trace && k % opt.trace_every == 0) {
      for (int i = 0; i < N; ++i) {
        const auto& s = *st[static_cast<std::size_t>(i)];
        const auto xn = s.x().segment<3>(3 * b.trace_node);
        const auto& f = forces[static_cast<std::size_t>(i)];
        const auto& y = s.vp_position_m();
        const auto& q = users[static_cast<std::size_t>(i)].position_m();
        std::fprintf(trace.get(), "%.4f,%d,%.7g,%.7g,%.7g,%.6g,%.6g,%.6g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%d\n", t_next, i + 1, xn[0], xn[1],
                     xn[2], f[0], f[1], f[2], y[0], y[1], y[2], q[0], q[1], q[2], s.energy().port_J, s.energy().controller_J, s.energy().vo_J,
                     s.in_contact() ? 1 : 0);
      }
      std::fprintf(series.get(), "%.4f,%.7g,%.7g,%.7g,%.7g,%.6g,%.6g\n", t_next, err, deformation, port_total, ctrl_total, fsum[0], fsum.norm());
    }
    while (next_snap < snap_times.size() && t_next >= snap_times[next_snap] - 1e-9) {
      nlohmann::json snap;
      snap["t_s"] = t_next;
      nlohmann::json copies = nlohmann::json::array();
      for (int i = 0; i < N; ++i) {
        const auto& x = st[static_cast<std::size_t>(i)]->x();
        copies.push_back(std::vector<double>(x.data(), x.data() + dofs));
      }
      snap["x_m"] = copies;
      nlohmann::json vps = nlohmann::json::array();
      for (int i = 0; i < N; ++i) {
        const auto& y = st[static_cast<std::size_t>(i)]->vp_position_m();
        vps.push_back({y[0], y[1], y[2]});
      }
      snap["vp_m"] = vps;
      snapshots.push_back(snap);
      ++next_snap;
    }
    if (opt.progress) {
      const int pct = static_cast<int>(100 * (k + 1) / ticks);
      if (pct / 10 != last_pct / 10) {
        last_pct = pct;
        const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
        std::fprintf(stderr, "  %s: %3d%%  %.1f/%.1f s simulated, %.1f s wall, consensus error %.3g mm\n", spec.name.c_str(), pct, t_next,
                     spec.duration_s, wall, err * 1e3);
      }
    }
    if (r.diverged && t > r.diverged_at_s + 0.5) {
      ++k;
      break;
    }
  }
  r.ticks = static_cast<std::uint64_t>(k);
  // Final figures (the last tick's measurement is of the final state)
  r.consensus_error_m = last_err;
  if (!r.diverged && r.consensus_error_m < 1e-3 && k * T > r.release_time_s)
    r.consensus_time_s = any_violation_after_release ? std::max(0.0, last_violation_s - r.release_time_s) : 0.0;
  if (hold_count > 0) {
    r.hold_force_sum_N = hold_sum / hold_count;
    r.hold_force_mean_N = hold_mean / hold_count;
    r.deformation_hold_m = deform_sum / hold_count;
    for (std::size_t kk = 0; kk < deformation_series.size(); ++kk)
      if (deformation_series[kk] >= 0.9 * r.deformation_hold_m) {
        r.deformation_rise_time_s = (kk + 1) * T - spec.script.push_start_s;
        break;
      }
  }
  r.port_energy_min_J = port_total_min;
  r.controller_energy_max_J = ctrl_total_max;
  r.passivity_bound_J = d2;
  for (auto& c : ch) {
    const auto& rc = st[static_cast<std::size_t>(c.to)]->rx(c.rx_index).counters();
    c.stats.max_index_delay = rc.max_index_delay;
    c.stats.bound_violations = st[static_cast<std::size_t>(c.to)]->edge_drop_events(c.rx_index);
    r.links.push_back(c.stats);
  }
  for (int i = 0; i < N; ++i) {
    r.final_port_J.push_back(st[static_cast<std::size_t>(i)]->energy().port_J);
    r.final_controller_J.push_back(st[static_cast<std::size_t>(i)]->energy().controller_J);
    r.final_x.push_back(st[static_cast<std::size_t>(i)]->x());
  }
  for (auto& recorder : rec) recorder->finish();
  r.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (!opt.out_dir.empty() && !snap_times.empty()) {
    nlohmann::json js;
    js["surface"] = b.scene.mesh.surface;
    js["contact_nodes"] = b.contact_nodes;
    js["snapshots"] = snapshots;
    std::ofstream(opt.out_dir + "/snapshots.json") << js.dump();
  }
  return r;
}

void write_summary_json(const std::string& path, const BuiltScenario& b, const SimResult& r) {
  using nlohmann::json;
  const auto& s = b.spec;
  json j;
  j["scenario"] = s.name;
  j["users"] = s.users;
  j["dt_s"] = s.period_s;
  j["duration_s"] = s.duration_s;
  j["simulated_s"] = static_cast<double>(r.ticks) * s.period_s;
  j["seed"] = s.seed;
  json topo = json::array();
  for (const auto& l : s.topology) topo.push_back({l.a + 1, l.b + 1});
  j["topology"] = topo;
  j["scene_nodes"] = b.scene.nodes;
  j["scene_edges"] = b.scene.mesh.edges.size();
  j["scene_tetrahedra"] = b.scene.mesh.tets.size();
  j["damping_Ns_per_m"] = b.damping;
  j["damping_min_Ns_per_m"] = b.damping_min;
  j["round_trip_half_sum_ms"] = b.round_trip_sum_ms;
  j["damping_margin"] = s.damping_margin;
  j["loss_allowance_ticks"] = s.loss_allowance_ticks;
  j["passivity_condition_met"] = b.passivity_condition_met;
  j["receive_rule"] = rt::rx_rule_name(s.receive_rule);
  j["release_time_s"] = r.release_time_s;
  j["consensus_error_m"] = r.consensus_error_m;
  j["max_consensus_error_m"] = r.max_consensus_error_m;
  j["consensus_time_s"] = r.consensus_time_s ? json(*r.consensus_time_s) : json(nullptr);
  j["hold_window_s"] = {r.hold_window_start_s, r.hold_window_end_s};
  j["hold_force_sum_N"] = r.hold_force_sum_N;
  j["hold_force_mean_N"] = r.hold_force_mean_N;
  j["hold_force_balance_ratio"] = r.hold_force_mean_N > 0 ? r.hold_force_sum_N / r.hold_force_mean_N : 0.0;
  j["deformation_hold_m"] = r.deformation_hold_m;
  j["deformation_rise_time_s"] = r.deformation_rise_time_s ? json(*r.deformation_rise_time_s) : json(nullptr);
  j["port_energy_min_J"] = r.port_energy_min_J;
  j["controller_energy_max_J"] = r.controller_energy_max_J;
  j["passivity_bound_J"] = r.passivity_bound_J;
  j["port_energy_final_J"] = r.final_port_J;
  j["controller_energy_final_J"] = r.final_controller_J;
  j["diverged"] = r.diverged;
  j["diverged_at_s"] = r.diverged ? json(r.diverged_at_s) : json(nullptr);
  j["max_node_speed_m_per_s"] = std::isfinite(r.max_node_speed_m_per_s) ? json(r.max_node_speed_m_per_s) : json("inf");
  json pk;
  std::uint64_t sent = 0, delivered = 0, lost = 0, dup = 0, reord = 0, sent_hold = 0, sent_settled = 0;
  json links = json::array();
  // Bandwidth per link over the run, over the hold window and after consensus (release +
  // consensus time to the end); the transmission policy (rt/tx_deadband) decides what is sent.
  const double run_s = static_cast<double>(r.ticks) * s.period_s;
  const double settled_from_s = r.consensus_time_s ? r.release_time_s + *r.consensus_time_s : run_s;
  for (const auto& l : r.links) {
    const std::uint64_t in_hold = sent_between(l, r.hold_window_start_s, r.hold_window_end_s, s.period_s);
    const std::uint64_t settled = sent_between(l, settled_from_s, run_s + s.period_s, s.period_s);
    sent_hold += in_hold;
    sent_settled += settled;
    sent += l.sent;
    delivered += l.delivered;
    lost += l.lost;
    dup += l.duplicated;
    reord += l.reordered;
    links.push_back({{"to", l.to + 1},
                     {"from", l.from + 1},
                     {"sent", l.sent},
                     {"delivered", l.delivered},
                     {"lost", l.lost},
                     {"duplicated", l.duplicated},
                     {"reordered", l.reordered},
                     {"mean_delay_ms", l.delivered ? 1e3 * l.delay_sum_s / l.delivered : 0.0},
                     {"max_delay_ms", 1e3 * l.delay_max_s},
                     {"loss_rate", l.sent ? static_cast<double>(l.lost) / l.sent : 0.0},
                     {"max_index_delay_ticks", l.max_index_delay},
                     {"bound_violations", l.bound_violations},
                     {"packets_per_s", run_s > 0 ? static_cast<double>(l.sent) / run_s : 0.0},
                     {"bytes_per_s", run_s > 0 ? static_cast<double>(l.bytes_sent) / run_s : 0.0},
                     {"sent_in_hold_window", in_hold},
                     {"sent_after_consensus", settled},
                     {"index_delay_bound_ticks", b.nbar_ticks(l.to, l.from)}});
  }
  pk["sent"] = sent;
  pk["delivered"] = delivered;
  pk["lost"] = lost;
  pk["duplicated"] = dup;
  pk["reordered"] = reord;
  pk["sent_in_hold_window"] = sent_hold;
  pk["sent_after_consensus"] = sent_settled;
  pk["after_consensus_s"] = run_s - settled_from_s;
  j["tx_deadband"] = {{"position_m", s.tx_deadband.position_deadband_m}, {"max_interval_ticks", s.tx_deadband.max_interval_ticks}};
  j["packets"] = pk;
  j["link_stats"] = links;
  j["wall_time_s"] = r.wall_time_s;
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << j.dump(2) << "\n";
}

}  // namespace haptic::firmware
