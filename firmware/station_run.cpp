#include "firmware/station_run.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cstring>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "drivers/device_factory.hpp"
#include "platform/gpio.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/rt_thread.hpp"
#include "platform/telemetry.hpp"
#include "platform/trace.hpp"
#include "rt/gains.hpp"

namespace haptic::firmware {

namespace {

std::int64_t clock_ns(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void sleep_until_mono_ns(std::int64_t t) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

constexpr std::size_t kMaxTraceRecords = 4'000'000;
constexpr std::size_t kMaxStateValues = 64'000'000;  // 512 MB of doubles: refuse above

}  // namespace

void run_tick(RunTick& c, std::int64_t k, std::int64_t kr, const platform::TickInfo& info) {
  // 1. GPIO high (the loop already emitted tick_begin)
  if (c.gpio) c.gpio->tick_high();
  // Every step below is an LTTng stage (platform/trace.hpp), so tools/trace/analyze.py breaks
  // the tick down: device_read, rx_drain, solve, publish (force out), tx, monitor, telemetry.
  using platform::trace::Stage;
  using platform::trace::StageScope;
  // 2. newest device sample
  drivers::DeviceSample ds{};
  rt::Vec3 q;
  {
    StageScope stage(Stage::device_read);
    if (c.device->read_newest(ds)) {
      q = rt::Vec3(ds.position_m[0], ds.position_m[1], ds.position_m[2]);
    } else {
      q = rt::Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // safe state for this tick
      ++c.device_fault_ticks;
    }
    platform::trace::device_read(0, ds.sequence);
  }
  // 3. drain RX into the receive links; sequence numbers translated to the core's k
  const std::int64_t lag = kr - (c.core->sequence() + 1);  // cycles skipped by overruns
  platform::trace::stage_begin(Stage::rx_drain);
  c.ep->drain([&](std::uint16_t sender, std::uint64_t seq, double send_time_s, const double* x, const double* v, std::uint32_t count) {
    const int n = c.sender_to_nbr[sender];
    if (n < 0) {
      ++c.foreign_packets;
      return;
    }
    if (static_cast<std::int64_t>(seq) < c.run_k0) {
      ++c.probe_packets_after_run;
      return;
    }
    platform::trace::packet_rx(static_cast<std::uint32_t>(sender), seq, static_cast<std::uint32_t>(count));
    c.core->rx(n).offer(static_cast<std::int64_t>(seq) - c.run_k0 - lag, send_time_s, x, v, static_cast<int>(count));
    ++c.rx_offered;
  });
  platform::trace::stage_end(Stage::rx_drain);
  // 4. the coupled VO + VP step
  platform::trace::solve_begin();
  const auto out = c.core->tick(q);
  platform::trace::solve_end();
  // 5. force to the device, state to the neighbours
  const double F[3] = {out.device_force_N[0], out.device_force_N[1], out.device_force_N[2]};
  platform::trace::stage_begin(Stage::publish);
  c.device->command_force(F);
  platform::trace::device_write(0, static_cast<std::uint64_t>(kr));
  if (c.simulated) c.simulated->service(static_cast<double>(kr) * c.T, c.T);
  platform::trace::stage_end(Stage::publish);
  platform::trace::stage_begin(Stage::tx);
  if (!c.ep->push_state(static_cast<std::uint64_t>(k), net::monotonic_s(), c.core->x_hat(), c.core->v_hat())) ++c.push_failures;
  platform::trace::stage_end(Stage::tx);
  // 6. monitor, records, telemetry
  platform::trace::stage_begin(Stage::monitor);
  const auto& e = c.core->energy();
  c.port_min = std::min(c.port_min, e.port_J);
  const auto& vv = c.core->v();
  double vmax = 0;
  for (int p = 0; p < c.dofs / 3; ++p) vmax = std::max(vmax, vv.segment<3>(3 * p).norm());
  if (!std::isfinite(vmax)) vmax = INFINITY;
  c.max_speed = std::max(c.max_speed, vmax);
  if ((out.flags & rt::kDiverged) && !c.diverged) {
    c.diverged = true;
    c.diverged_at_s = static_cast<double>(kr) * c.T;
    if (c.telemetry) c.telemetry->report_fault(platform::FaultKind::divergence, info.index);
  }
  if (kr % c.trace_every == 0 && c.trace_n < c.trace_cap) {
    TraceRec& r = c.trace[c.trace_n++];
    r.k = kr;
    const auto xn = c.core->x().segment<3>(3 * c.trace_node);
    const auto& y = c.core->vp_position_m();
    for (int a = 0; a < 3; ++a) {
      r.node[a] = xn[a];
      r.force[a] = F[a];
      r.vp[a] = y[a];
      r.device[a] = q[a];
    }
    r.port_J = e.port_J;
    r.ctrl_J = e.controller_J;
    r.vo_J = e.vo_J;
    r.max_speed = vmax;
    r.flags = out.flags;
    r.wake_latency_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.wake_latency_ns, INT32_MAX));
    r.contact = c.core->in_contact() ? 1 : 0;
  }
  if (kr % c.state_every == 0 && c.state_n < c.state_cap) {
    c.state_k[c.state_n] = kr;
    std::copy(c.core->x().data(), c.core->x().data() + c.dofs, c.state_x + c.state_n * static_cast<std::size_t>(c.dofs));
    ++c.state_n;
  }
  platform::trace::stage_end(Stage::monitor);
  if (c.telemetry) {
    StageScope stage(Stage::telemetry);
    platform::TelemetryRecord tr;
    tr.tick = info.index;
    tr.scheduled_ns = info.scheduled_ns;
    tr.wake_latency_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.wake_latency_ns, INT32_MAX));
    tr.exec_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.prev_exec_ns, INT32_MAX));
    tr.overruns = static_cast<std::uint32_t>(info.overruns);
    tr.status = out.flags;
    for (int a = 0; a < 3; ++a) {
      tr.values[static_cast<std::size_t>(a)] = F[a];
      tr.values[static_cast<std::size_t>(3 + a)] = q[a];
    }
    tr.values[6] = e.port_J;
    tr.values[7] = e.controller_J;
    tr.values[8] = e.vo_J;
    tr.values[9] = c.core->in_contact() ? 1 : 0;
    tr.values[10] = static_cast<double>(c.core->edge_drop_events());
    c.telemetry->record(tr);
  }
  ++c.ticks_run;
  if (c.gpio) c.gpio->tick_low();
}

ScenarioSpec station_scenario_spec(const StationFile& f, const RunOverrides& o) {
  const StationSection& s = f.station;
  ScenarioSpec spec = make_scenario(s.scenario);
  if (!s.topology.empty()) spec.topology = parse_topology(s.topology, spec.users);
  spec.scene_nodes = s.nodes;
  spec.seed = s.seed;
  const double dur = o.duration_s > 0 ? o.duration_s : s.duration_s;
  if (dur > 0) spec.duration_s = dur;
  if (s.push_start_s >= 0) spec.script.push_start_s = s.push_start_s;
  if (s.push_end_s >= 0) spec.script.push_end_s = s.push_end_s;
  if (s.release_s >= 0) spec.script.release_s = s.release_s;
  spec.damping_margin = s.damping_margin;
  spec.loss_allowance_ticks = s.loss_allowance_ticks;
  if (std::llabs(std::llround(spec.period_s * 1e9) - f.loop.period_ns) > 0)
    throw std::invalid_argument("config: loop.period_ns must equal the scenario's period " + std::to_string(std::llround(spec.period_s * 1e9)) +
                                " ns (the paper's T = 2 ms)");
  if (s.id > spec.users) throw std::invalid_argument("config: station.id must be in [1, " + std::to_string(spec.users) + "] for scenario " + spec.name);
  const auto& sc = spec.script;
  if (sc.kind == UserScriptSpec::Kind::kPushHoldRelease && !(sc.push_start_s < sc.push_end_s && sc.push_end_s < sc.release_s))
    throw std::invalid_argument("config: station.push_start_s < station.push_end_s < station.release_s must hold (got " +
                                std::to_string(sc.push_start_s) + ", " + std::to_string(sc.push_end_s) + ", " + std::to_string(sc.release_s) + ")");
  spec.validate();
  return spec;
}

MeasuredBounds bounds_from_round_trips(const BuiltScenario& b, int user, const std::vector<std::uint32_t>& rtt_ticks, int allowance,
                                       double margin, double override_B, int agreement) {
  const auto& nbrs = b.neighbors[static_cast<std::size_t>(user)];
  if (rtt_ticks.size() != nbrs.size()) throw std::invalid_argument("bounds_from_round_trips: one bound per neighbour needed");
  MeasuredBounds m;
  std::vector<rt::Eq18Neighbor> nb;
  const double T = b.spec.period_s;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const int R = static_cast<int>(rtt_ticks[n]) + allowance;
    m.round_trip_ticks.push_back(R);
    m.index_guard_ticks.push_back((R + 1) / 2);
    m.assumed_sum_ticks.push_back(2 * ((R + 1) / 2) + agreement);
    nb.push_back({static_cast<double>(m.assumed_sum_ticks.back()), T,
                  &b.gains[static_cast<std::size_t>(b.neighbor_edge[static_cast<std::size_t>(user)][n])]});
  }
  m.damping_min_Ns_per_m = rt::damping_min_eq18(T, nb);
  m.damping_Ns_per_m = override_B >= 0 ? override_B : (1.0 + margin) * m.damping_min_Ns_per_m;
  return m;
}

int run_station(const StationFile& f, const RunOverrides& o, std::atomic<bool>& stop) {
  namespace fs = std::filesystem;
  const auto wall0 = std::chrono::steady_clock::now();
  const StationSection& S = f.station;
  const std::string tag = "haptic-station run [station " + std::to_string(S.id) + "]";
  auto say = [&](const std::string& line) {
    if (!o.quiet) std::cerr << tag << ": " << line << "\n";
  };

  // ---- start-up (non-RT) ------------------------------------------------------------------
  const ScenarioSpec spec = station_scenario_spec(f, o);
  const BuiltScenario built = build_scenario(spec);
  const int me = S.id - 1;
  const int N = spec.users;
  const double T = spec.period_s;
  const std::int64_t period_ns = f.loop.period_ns;
  const int dofs = built.scene.dofs;
  const auto& nbrs = built.neighbors[static_cast<std::size_t>(me)];
  const std::string out_dir = o.out_dir.empty() ? S.out_dir : o.out_dir;
  fs::create_directories(out_dir);
  const std::string base = out_dir + "/station-" + std::to_string(S.id);

  // Network: net/ parses its section; the station aligns the peers with the scenario.
  net::NetConfig nc = net::parse_net_config(f.text, static_cast<std::uint32_t>(dofs));
  if (nc.endpoint.wire.station_id != S.id)
    throw std::invalid_argument("config: the wire station id (net.station_id / station.id) must be station.id = " + std::to_string(S.id));
  std::vector<int> peer_to_nbr(nc.endpoint.peers.size(), -1);
  std::vector<int> nbr_to_peer(nbrs.size(), -1);
  std::vector<int> sender_to_nbr(65536, -1);
  for (std::size_t p = 0; p < nc.endpoint.peers.size(); ++p) {
    const int u = nc.endpoint.peers[p].station_id - 1;
    for (std::size_t n = 0; n < nbrs.size(); ++n)
      if (nbrs[n] == u) peer_to_nbr[p] = static_cast<int>(n);
    if (peer_to_nbr[p] < 0)
      throw std::invalid_argument("config: net.peers[" + std::to_string(p) + "].id = " + std::to_string(u + 1) + " is not a neighbour of station " +
                                  std::to_string(S.id) + " in topology " + (S.topology.empty() ? "of " + spec.name : S.topology));
    if (nbr_to_peer[static_cast<std::size_t>(peer_to_nbr[p])] >= 0)
      throw std::invalid_argument("config: net.peers lists station " + std::to_string(u + 1) + " twice");
    nbr_to_peer[static_cast<std::size_t>(peer_to_nbr[p])] = static_cast<int>(p);
    sender_to_nbr[static_cast<std::size_t>(u + 1)] = peer_to_nbr[p];
  }
  for (std::size_t n = 0; n < nbrs.size(); ++n)
    if (nbr_to_peer[n] < 0)
      throw std::invalid_argument("config: net.peers lacks station " + std::to_string(nbrs[n] + 1) + ", a neighbour of station " + std::to_string(S.id) +
                                  " in the topology");
  // Impairment: the simulator's link model and seed scheme (receiver*64 + sender, 0-based).
  const std::uint64_t seed_base = f.impairment_seed_set ? 0 : S.seed;
  for (std::size_t p = 0; p < nc.endpoint.peers.size(); ++p) {
    auto& l = nc.endpoint.peers[p];
    if (!l.impaired) continue;
    const int u = l.station_id - 1;
    bool mean_given = false;
    for (const auto& [id, given] : f.peer_mean_delay_set)
      if (id == l.station_id) mean_given = given;
    if (!mean_given) {
      auto keep = l.impairment;
      l.impairment = net::LinkImpairment::preset(f.impairment_preset, spec.delay_ms(u, me) * 1e-3);
      l.impairment.delay_trace = keep.delay_trace;
      l.impairment.blackout_start_s = keep.blackout_start_s;
      l.impairment.blackout_length_s = keep.blackout_length_s;
    }
    if (f.impairment_preset == "paper") {
      l.impairment.jitter_fraction = spec.jitter_fraction;
      l.impairment.loss_probability = spec.loss_probability;
      l.impairment.duplicate_probability = spec.duplicate_probability;
    }
    if (!f.impairment_seed_set) l.seed = seed_base * 1000003ULL + static_cast<std::uint64_t>(u * 64 + me);
  }

  // Common epoch of k = 0 on CLOCK_MONOTONIC.
  const std::int64_t mono_now = clock_ns(CLOCK_MONOTONIC);
  double start_at = o.start_at >= 0 ? o.start_at : S.start_at;
  std::int64_t epoch_ns;
  if (start_at <= 0 && S.start_align_s > 0) {
    const std::int64_t clk_now = S.start_clock == "realtime" ? clock_ns(CLOCK_REALTIME) : mono_now;
    const auto align = static_cast<std::int64_t>(S.start_align_s * 1e9);
    const std::int64_t earliest = clk_now + static_cast<std::int64_t>(S.start_delay_s * 1e9);
    epoch_ns = ((earliest + align - 1) / align) * align - (clk_now - mono_now);
  } else if (start_at <= 0) {
    epoch_ns = mono_now + static_cast<std::int64_t>(S.start_delay_s * 1e9);
  } else if (S.start_clock == "realtime") {
    epoch_ns = static_cast<std::int64_t>(start_at * 1e9) - (clock_ns(CLOCK_REALTIME) - mono_now);
  } else {
    epoch_ns = static_cast<std::int64_t>(start_at * 1e9);
  }
  const std::int64_t probe_ticks = static_cast<std::int64_t>(std::llround(S.probe_s / T));
  const std::int64_t gap_ticks = static_cast<std::int64_t>(std::llround(S.setup_gap_s / T));
  const std::int64_t run_k0 = probe_ticks + gap_ticks;
  const std::int64_t run_ticks = static_cast<std::int64_t>(std::llround(spec.duration_s / T));
  if (mono_now > epoch_ns + (probe_ticks / 2) * period_ns)
    throw std::runtime_error("started " + std::to_string((mono_now - epoch_ns) * 1e-9) +
                             " s after the common epoch (station.start_at / --start-at), more than half the probing phase: start earlier");
  nc.endpoint.impairment_epoch_s = static_cast<double>(epoch_ns + run_k0 * period_ns) * 1e-9;
  nc.endpoint.tx_period_s = T;  // tick-synchronous TX (net.tx_spin) needs the tick period

  // Device.
  drivers::DeviceSelection sel;
  sel.kind = f.device.kind;
  sel.safety.max_force_N = f.device.max_force_N;
  sel.safety.max_power_W = f.device.max_power_W;
  sel.safety.max_speed_m_per_s = f.device.max_speed_m_per_s;
  sel.simulated.device = spec.device;
  sel.simulated.hand = spec.hand;
  sel.simulated.script = built.goal_script(me);
  const Eigen::Vector3d p0 = built.vp_start[static_cast<std::size_t>(me)];
  for (int a = 0; a < 3; ++a) sel.simulated.start_position_m[a] = p0[a];
  sel.simulated.max_force_N = f.device.sim_max_force_N;
  sel.simulated.workspace_radius_m = std::max(0.1, 2.0 * p0.norm() + spec.script.retract_depth_m);
  drivers::OpenedDevice dev = drivers::open_device(sel);
  say("device: " + std::string(dev.device->capabilities().name) + (dev.simulated ? " (simulated user: scenario script of user " + std::to_string(S.id) + ")" : ""));
  if (!o.quiet && !dev.report.empty()) std::cerr << dev.report << (dev.report.back() == '\n' ? "" : "\n");
  const double b_d = dev.device->capabilities().min_damping_Ns_per_m;

  auto transport = nc.make_transport();
  net::Endpoint ep(nc.endpoint, std::move(transport));
  platform::GpioToggler gpio(f.gpio);
  std::unique_ptr<platform::Telemetry> telemetry;
  if (!f.telemetry.path.empty()) {
    platform::TelemetryConfig tc = f.telemetry;
    tc.period_s = T;
    tc.value_names = {"force_x_N", "force_y_N", "force_z_N", "device_x_m", "device_y_m", "device_z_m", "port_energy_J", "controller_energy_J", "vo_energy_J",
                      "contact", "edge_drops"};
    telemetry = std::make_unique<platform::Telemetry>(tc);
  }

  // Records (preallocated: the tick only writes into them).
  const std::size_t n_trace = static_cast<std::size_t>(run_ticks / S.trace_every + 2);
  const std::size_t n_state = static_cast<std::size_t>(run_ticks / S.state_every + 2);
  if (n_trace > kMaxTraceRecords) throw std::invalid_argument("config: station.trace_every too small for duration_s (over 4e6 records)");
  if (n_state * static_cast<std::size_t>(dofs) > kMaxStateValues) throw std::invalid_argument("config: station.state_every too small for duration_s and nodes");
  std::vector<TraceRec> trace(n_trace);
  std::vector<std::int64_t> state_k(n_state);
  std::vector<double> state_x(n_state * static_cast<std::size_t>(dofs));
  std::vector<double> x0(built.scene.x_d.data(), built.scene.x_d.data() + dofs), v0(static_cast<std::size_t>(dofs), 0.0);

  // Shared between the RT loop and the non-RT main thread.
  std::atomic<bool> build_requested{false}, loop_done{false};
  std::atomic<rt::StationCore*> core_ptr{nullptr};
  std::unique_ptr<rt::StationCore> core_owner;
  MeasuredBounds mb;
  std::string fatal;
  net::EndpointStats stats_at_run{};
  std::uint64_t late_core_ticks = 0;
  std::int64_t first_run_k = -1, last_k = -1;
  bool stopped_by_signal = false;
  RunTick rtc;
  rtc.ep = &ep;
  rtc.device = dev.device.get();
  rtc.simulated = dev.simulated;
  rtc.gpio = &gpio;
  rtc.telemetry = telemetry.get();
  rtc.sender_to_nbr = sender_to_nbr.data();
  rtc.dofs = dofs;
  rtc.trace_node = built.trace_node;
  rtc.trace_every = S.trace_every;
  rtc.state_every = S.state_every;
  rtc.T = T;
  rtc.run_k0 = run_k0;
  rtc.trace = trace.data();
  rtc.trace_cap = trace.size();
  rtc.state_k = state_k.data();
  rtc.state_x = state_x.data();
  rtc.state_cap = state_k.size();
  const std::size_t& trace_n = rtc.trace_n;
  const std::size_t& state_n = rtc.state_n;
  const std::uint64_t &foreign_packets = rtc.foreign_packets, &probe_packets_after_run = rtc.probe_packets_after_run, &rx_offered = rtc.rx_offered;
  std::uint64_t &push_failures = rtc.push_failures, &device_faults_ticks = rtc.device_fault_ticks;
  const std::int64_t& ticks_run = rtc.ticks_run;
  const bool& diverged = rtc.diverged;
  const double &diverged_at_s = rtc.diverged_at_s, &port_min = rtc.port_min, &max_speed = rtc.max_speed;
  platform::LoopStats loop_stats{};
  std::string rt_summary;
  std::vector<std::string> rt_warnings;

  // The I/O thread inherits the scheduling of the thread that starts it: SCHED_FIFO at
  // station.io_priority, so round trips measure the network rather than CPU contention.
  std::string io_sched = "SCHED_OTHER";
  if (S.io_priority > 0) {
    sched_param sp{};
    sp.sched_priority = S.io_priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (rc == 0) io_sched = "SCHED_FIFO " + std::to_string(S.io_priority);
    else say("warning: I/O thread stays SCHED_OTHER (SCHED_FIFO " + std::to_string(S.io_priority) + " refused: " + std::strerror(rc) + "); running anyway");
  }
  ep.start();
  if (S.io_priority > 0) {
    sched_param sp{};
    sp.sched_priority = 0;
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
  }
  ep.begin_probing();
  {
    std::ostringstream os;
    os << "scenario " << spec.name << ", " << N << " users, " << built.scene.nodes << " nodes, neighbours";
    for (int j : nbrs) os << " " << j + 1;
    os << "; transport " << nc.transport << "; epoch in " << (epoch_ns - mono_now) * 1e-9 << " s, probing " << S.probe_s << " s, run "
       << spec.duration_s << " s";
    say(os.str());
  }

  platform::LoopConfig lc = f.loop;
  platform::PeriodicLoop<> loop(lc);
  {
    platform::RtThread rt_thread(f.rt, [&](const platform::RtReport&) {
      sleep_until_mono_ns(epoch_ns - period_ns);
      loop.run(
          [&](const platform::TickInfo& info) -> bool {
            const std::int64_t k = (info.scheduled_ns - epoch_ns + period_ns / 2) / period_ns;
            last_k = k;
            if (k < run_k0) {
              // Probing / gap: the rest state, zero coupling; drop whatever arrives.
              if (k >= probe_ticks) build_requested.store(true, std::memory_order_release);
              ep.drain([](std::uint16_t, std::uint64_t, double, const double*, const double*, std::uint32_t) {});
              if (k >= 0 && !ep.push_state(static_cast<std::uint64_t>(k), net::monotonic_s(), x0.data(), v0.data())) ++push_failures;
              return !stop.load(std::memory_order_acquire);
            }
            rt::StationCore* core = core_ptr.load(std::memory_order_acquire);
            if (core == nullptr) {
              ++late_core_ticks;
              ep.drain([](std::uint16_t, std::uint64_t, double, const double*, const double*, std::uint32_t) {});
              return late_core_ticks < 500 && !stop.load(std::memory_order_acquire);
            }
            const std::int64_t kr = k - run_k0;  // run tick index (script time kr*T)
            if (kr >= run_ticks) return false;
            if (first_run_k < 0) first_run_k = k;
            rtc.core = core;
            run_tick(rtc, k, kr, info);
            return !stop.load(std::memory_order_acquire);
          },
          stop);
      loop_stats = loop.stats();
      loop_done.store(true, std::memory_order_release);
    });
    rt_summary = rt_thread.setup_summary();
    rt_warnings = rt_thread.setup_warnings();
    if (!o.quiet) {
      std::cerr << rt_summary << (rt_summary.empty() || rt_summary.back() == '\n' ? "" : "\n");
      for (const auto& w : rt_warnings) std::cerr << tag << ": warning: " << w << " (running anyway; rt.require_rt = false)\n";
    }

    // Non-RT side: finish probing and build the core during the gap; print throttled reports.
    bool built_core = false;
    while (!loop_done.load(std::memory_order_acquire)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (!built_core && build_requested.load(std::memory_order_acquire)) {
        built_core = true;
        try {
          const bool all = ep.finish_probing();
          const net::EndpointStats st = ep.stats();
          std::vector<std::uint32_t> rtt(nbrs.size(), 0);
          std::string missing;
          for (std::size_t n = 0; n < nbrs.size(); ++n) {
            const auto p = static_cast<std::size_t>(nbr_to_peer[n]);
            if (!st.peers[p].rtt_has_bound) {
              if (!missing.empty()) missing += ", ";
              missing += std::to_string(nbrs[n] + 1);
            }
            rtt[n] = ep.rtt_bound_ticks(p, T);
          }
          if (!all || !missing.empty())
            throw std::runtime_error("probing: no round-trip bound for neighbour(s) " + missing + " after " + std::to_string(S.probe_s) +
                                     " s (peer not running, wrong address/key/session, or fewer than net.rtt_min_probe_samples echoes)");
          mb = bounds_from_round_trips(built, me, rtt, S.loss_allowance_ticks, S.damping_margin, S.damping_Ns_per_m, S.agreement_ticks);
          rt::StationConfig sc = built.station_config(me);
          sc.damping_Ns_per_m = mb.damping_Ns_per_m;
          sc.device_damping_Ns_per_m = b_d;
          for (std::size_t n = 0; n < nbrs.size(); ++n) sc.neighbors[n].index_delay_bound_ticks = mb.index_guard_ticks[n];
          core_owner = std::make_unique<rt::StationCore>(sc);
          stats_at_run = ep.stats();
          core_ptr.store(core_owner.get(), std::memory_order_release);
          std::ostringstream os;
          os << "probing done: round-trip bounds (ticks incl. allowance)";
          for (std::size_t n = 0; n < nbrs.size(); ++n) os << " " << nbrs[n] + 1 << ":" << mb.round_trip_ticks[n];
          os << "; B_i = " << mb.damping_Ns_per_m << " N s/m (eq. 18 minimum " << mb.damping_min_Ns_per_m << ", model " << built.damping[static_cast<std::size_t>(me)]
             << ")";
          say(os.str());
        } catch (const std::exception& ex) {
          fatal = ex.what();
          stop.store(true, std::memory_order_release);
        }
      }
      platform::LoopReport rep;
      if (loop.take_report(rep) && !o.quiet && rep.window_overruns > 0) say("loop: " + platform::format_report(rep));
    }
    rt_thread.join();
  }
  stopped_by_signal = stop.load(std::memory_order_acquire) && fatal.empty() && ticks_run < run_ticks;
  ep.stop();
  if (dev.device) dev.device->stop();
  if (telemetry) telemetry->flush();
  if (!fatal.empty()) {
    std::cerr << tag << ": error: " << fatal << "\n";
  } else if (late_core_ticks >= 500) {
    fatal = "the station core was not ready by the run start (station.setup_gap_s too short?)";
    std::cerr << tag << ": error: " << fatal << "\n";
  }

  // ---- outputs (non-RT) ---------------------------------------------------------------------
  const net::EndpointStats st = ep.stats();
  using nlohmann::json;
  json j;
  j["station"] = S.id;
  j["scenario"] = spec.name;
  j["users"] = N;
  j["dt_s"] = T;
  j["duration_s"] = spec.duration_s;
  j["seed"] = spec.seed;
  json topo = json::array();
  for (const auto& l : spec.topology) topo.push_back({l[0] + 1, l[1] + 1});
  j["topology"] = topo;
  j["scene_nodes"] = built.scene.nodes;
  j["trace_node"] = built.trace_node;
  j["x_d"] = std::vector<double>(built.scene.x_d.data(), built.scene.x_d.data() + dofs);
  j["transport"] = nc.transport;
  j["impairment_preset"] = f.impairment_preset;
  j["epoch_monotonic_s"] = static_cast<double>(epoch_ns) * 1e-9;
  j["probe_ticks"] = probe_ticks;
  j["run_k0"] = run_k0;
  j["first_run_k"] = first_run_k;
  j["run_ticks_planned"] = run_ticks;
  j["ticks_run"] = ticks_run;
  j["release_time_s"] = spec.script.release_s;
  j["push_end_s"] = spec.script.push_end_s;
  j["damping_Ns_per_m"] = mb.damping_Ns_per_m;
  j["damping_min_Ns_per_m"] = mb.damping_min_Ns_per_m;
  j["damping_model_Ns_per_m"] = built.damping[static_cast<std::size_t>(me)];
  j["damping_model_min_Ns_per_m"] = built.damping_min[static_cast<std::size_t>(me)];
  j["damping_margin"] = S.damping_margin;
  j["loss_allowance_ticks"] = S.loss_allowance_ticks;
  j["agreement_ticks"] = S.agreement_ticks;
  j["passivity_condition_met"] = core_owner != nullptr && mb.damping_Ns_per_m >= mb.damping_min_Ns_per_m * (1 - 1e-12);
  j["diverged"] = diverged;
  j["diverged_at_s"] = diverged ? json(diverged_at_s) : json(nullptr);
  j["max_node_speed_m_per_s"] = std::isfinite(max_speed) ? json(max_speed) : json("inf");
  j["port_energy_min_J"] = port_min;
  j["stopped_by_signal"] = stopped_by_signal;
  j["error"] = fatal.empty() ? json(nullptr) : json(fatal);
  j["late_core_ticks"] = late_core_ticks;
  j["push_failures"] = push_failures;
  j["device_fault_ticks"] = device_faults_ticks;
  j["device"] = dev.device ? dev.device->capabilities().name : "";
  j["device_fault"] = dev.device ? drivers::fault_name(dev.device->fault()) : "";
  j["foreign_packets"] = foreign_packets;
  j["probe_packets_after_run"] = probe_packets_after_run;
  j["rx_offered"] = rx_offered;
  if (core_owner) {
    const auto& e = core_owner->energy();
    j["port_energy_final_J"] = e.port_J;
    j["controller_energy_final_J"] = e.controller_J;
    j["edge_drop_events"] = core_owner->edge_drop_events();
    j["safe_state_ticks"] = core_owner->safe_state_ticks();
  }
  j["rt"] = {{"summary", rt_summary}, {"warnings", rt_warnings}, {"fully_real_time", rt_warnings.empty()}};
  j["loop"] = {{"ticks", loop_stats.ticks}, {"overruns", loop_stats.overruns}, {"missed_cycles", loop_stats.missed_cycles},
               {"overrun_storms", loop_stats.overrun_storms}};
  j["gpio"] = gpio.status();
  j["io_thread_scheduling"] = io_sched;
  j["drops"] = {{"datagrams_received", st.datagrams_received}, {"receive_errors", st.receive_errors}, {"rx_ring_full", st.rx_ring_full},
                {"tx_overruns", st.tx_overruns}, {"wrong_scene_size", st.wrong_scene_size}};
  j["io_thread"] = {{"cpu_s", st.io_thread_cpu_s},
                    {"tx_spin", nc.endpoint.tx_spin},
                    {"tx_packets", st.tx_packets},
                    {"tx_caught_spinning", st.tx_caught_spinning},
                    {"tx_spin_windows", st.tx_spin_windows},
                    {"tx_handoff_mean_us", st.tx_handoff_mean_s * 1e6},
                    {"tx_handoff_max_us", st.tx_handoff_max_s * 1e6}};
  json links = json::array();
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const auto p = static_cast<std::size_t>(nbr_to_peer[n]);
    const auto& ps = st.peers[p];
    const net::PeerStats ps0 = p < stats_at_run.peers.size() ? stats_at_run.peers[p] : net::PeerStats{};
    json l;
    l["peer"] = nbrs[n] + 1;
    // receive side (peer -> me)
    l["rx_packets_run"] = ps.packets_received - ps0.packets_received;
    l["rx_packets_total"] = ps.packets_received;
    l["rx_loss_fraction_measured"] = ps.loss_fraction;
    l["one_way_mean_ms"] = 1e3 * ps.one_way_mean_s;
    l["one_way_max_ms"] = 1e3 * ps.one_way_max_s;
    // send side (me -> peer) incl. the impairment emulator's fate
    l["tx_packets_run"] = ps.packets_sent - ps0.packets_sent;
    l["tx_impair_lost_run"] = ps.impair_lost - ps0.impair_lost;
    l["tx_impair_duplicated_run"] = ps.impair_duplicated - ps0.impair_duplicated;
    l["tx_send_errors"] = ps.send_errors;
    l["tx_delay_queue_full"] = ps.delay_queue_full;
    l["rtt_samples"] = ps.rtt_samples;
    l["rtt_mean_ms"] = 1e3 * ps.rtt_mean_s;
    l["rtt_min_ms"] = 1e3 * ps.rtt_min_s;
    l["rtt_max_ms"] = 1e3 * ps.rtt_max_s;
    l["rtt_bound_ms_now"] = 1e3 * ps.rtt_bound_s;
    l["rtt_over_bound_events"] = ps.rtt_over_bound_events;
    if (!mb.round_trip_ticks.empty()) {
      l["round_trip_bound_ticks"] = mb.round_trip_ticks[n];
      l["index_delay_bound_ticks"] = mb.index_guard_ticks[n];
      l["assumed_round_trip_ticks"] = mb.assumed_sum_ticks[n];
    }
    l["model_index_delay_bound_ticks"] = built.nbar_ticks(me, nbrs[n]);
    if (core_owner) {
      const auto& rc = core_owner->rx(static_cast<int>(n)).counters();
      l["rx_accepted"] = rc.accepted;
      l["rx_stale_reordered"] = rc.stale;
      l["rx_duplicate"] = rc.duplicate;
      l["rx_sustained_ticks"] = rc.sustained_ticks;
      l["max_index_delay_ticks"] = rc.max_index_delay;
      l["bound_violations"] = core_owner->edge_drop_events(static_cast<int>(n));
    }
    links.push_back(l);
  }
  j["links"] = links;
  j["wall_time_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  {
    std::ofstream jf(base + ".json");
    jf << j.dump(2) << "\n";
  }
  {
    std::FILE* tf = std::fopen((base + "-trace.csv").c_str(), "w");
    if (!tf) throw std::runtime_error("cannot write " + base + "-trace.csv");
    std::fprintf(tf, "k,t_s,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,device_x_m,device_y_m,device_z_m,"
                     "port_energy_J,controller_energy_J,vo_energy_J,contact,flags,max_speed_m_per_s,wake_latency_ns\n");
    for (std::size_t i = 0; i < trace_n; ++i) {
      const TraceRec& r = trace[i];
      std::fprintf(tf, "%lld,%.4f,%.9g,%.9g,%.9g,%.7g,%.7g,%.7g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%d,%u,%.6g,%d\n", static_cast<long long>(r.k),
                   static_cast<double>(r.k + 1) * T, r.node[0], r.node[1], r.node[2], r.force[0], r.force[1], r.force[2], r.vp[0], r.vp[1], r.vp[2],
                   r.device[0], r.device[1], r.device[2], r.port_J, r.ctrl_J, r.vo_J, r.contact, r.flags, r.max_speed, r.wake_latency_ns);
    }
    std::fclose(tf);
  }
  {
    std::FILE* sf = std::fopen((base + "-state.csv").c_str(), "w");
    if (!sf) throw std::runtime_error("cannot write " + base + "-state.csv");
    std::fprintf(sf, "k");
    for (int d = 0; d < dofs; ++d) std::fprintf(sf, ",x%d", d);
    std::fprintf(sf, "\n");
    for (std::size_t i = 0; i < state_n; ++i) {
      std::fprintf(sf, "%lld", static_cast<long long>(state_k[i]));
      const double* x = state_x.data() + i * static_cast<std::size_t>(dofs);
      for (int d = 0; d < dofs; ++d) std::fprintf(sf, ",%.10g", x[d]);
      std::fprintf(sf, "\n");
    }
    std::fclose(sf);
  }
  std::cout << tag << ": " << (fatal.empty() ? (stopped_by_signal ? "stopped by signal" : "done") : "FAILED") << ", " << ticks_run << " ticks, "
            << loop_stats.overruns << " overruns, " << (diverged ? "DIVERGED" : "stable") << ", B_i " << mb.damping_Ns_per_m << " N s/m, edge drops "
            << (core_owner ? core_owner->edge_drop_events() : 0) << "; wrote " << base << ".json, -trace.csv, -state.csv\n";
  return fatal.empty() ? 0 : 3;
}

}  // namespace haptic::firmware
