#include "firmware/station/run.hpp"

#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "drivers/device_factory.hpp"
#include "firmware/station/explain.hpp"
#include "firmware/station/neighbours.hpp"
#include "firmware/station/rejoin.hpp"
#include "firmware/session/recorder.hpp"
#include "firmware/view/server.hpp"
#include "platform/gpio.hpp"
#include "platform/telemetry.hpp"

namespace haptic::firmware {

namespace {

// solo: the run's first tick this long after the loop is started: the RT thread's set-up (memory
// locked, heap prefaulted) took 0.14 s on a loaded 2-core host; a later start joins the grid late.
constexpr std::int64_t kSoloStartNs = 250'000'000;

// Progress lines on stderr, prefixed with the station; silent with --quiet. Not RT-safe.
struct Log {
  std::string tag;
  bool quiet = false;
  void say(const std::string& line) const {
    if (!quiet) std::cerr << tag << ": " << line << "\n";
  }
  void error(const std::string& line) const { std::cerr << tag << ": error: " << line << "\n"; }
};

// What the station opens between plan and probe (sockets, the device, files).
struct StationResources {
  drivers::OpenedDevice dev;
  std::unique_ptr<net::Endpoint> ep;
  std::unique_ptr<platform::GpioToggler> gpio;
  std::unique_ptr<platform::Telemetry> telemetry;
  std::unique_ptr<SessionRecorder> recorder;  // station.record: the session log
  std::unique_ptr<ViewPublisher> view;        // station.view_port: frames from the tick
  std::unique_ptr<ViewServer> view_server;    // ... served to browsers
  std::string io_sched = "not started";
};

// Everything the phases returned, owned here so the report can point into it.
struct PhaseResults {
  ProbeResult probe;
  RejoinResult rejoin;  // when the station rejoined a running session (plan.times.rejoin)
  AdoptedState adopted;
  BuildResult build;
  RunPhaseResult run;
  bool probed = false, built = false, ran = false;
  TickCounters counters;
  TickRecords records;
  std::unique_ptr<RecordFiles> record_files;  // drains `records` into the CSV files during the run
  nlohmann::json lifecycle = nlohmann::json::object();  // rejoin, clock offsets, neighbour events
  std::string failure;
  PhaseStatus failure_status = PhaseStatus::kOk;
  void fail(PhaseStatus s, const std::string& message) {
    if (!failure.empty()) return;
    failure = message;
    failure_status = s;
  }
};

// The endpoint's I/O thread: platform::RtThread at station.io_priority (net.io_cpu pins it), so
// round trips measure the network rather than CPU contention; a refusal is a warning.
std::string start_io_thread(net::Endpoint& ep, const Log& log) {
  ep.start();
  for (const auto& w : ep.io_setup_warnings()) log.say("warning: " + w + "; running anyway");
  return ep.io_scheduling();
}

void open_telemetry(const StationPlan& plan, StationResources& res) {
  if (plan.file.telemetry.path.empty()) return;
  platform::TelemetryConfig tc = plan.file.telemetry;
  tc.period_s = plan.built->spec.period_s;
  tc.value_names = {"force_x_N", "force_y_N", "force_z_N", "device_x_m", "device_y_m", "device_z_m", "port_energy_J", "controller_energy_J", "vo_energy_J",
                    "contact", "edge_drops"};
  res.telemetry = std::make_unique<platform::Telemetry>(tc);
}

// open: output directory, device, GPIO, telemetry, transport + endpoint (I/O thread started, probing; not solo).
void open_resources(const StationPlan& plan, StationResources& res, const Log& log) {
  std::filesystem::create_directories(plan.out_dir);
  res.dev = drivers::open_device(plan.device);
  log.say("device: " + std::string(res.dev.device->capabilities().name) +
          (res.dev.simulated ? " (simulated user: scenario script of user " + std::to_string(plan.station_id) + ")" : ""));
  if (!log.quiet && !res.dev.report.empty()) std::cerr << res.dev.report << (res.dev.report.back() == '\n' ? "" : "\n");
  res.gpio = std::make_unique<platform::GpioToggler>(plan.file.gpio);
  open_telemetry(plan, res);
  if (plan.overrides.solo) return;  // no network: no endpoint, no I/O thread, no probing
  // its sequence ceiling lets a neighbour's grid run up to station.clock_offset_limit_ms ahead of ours
  res.ep = std::make_unique<net::Endpoint>(plan.endpoint_config(), plan.net.make_transport());
  log.say("incarnation " + std::to_string(res.ep->incarnation()) + " announced to the neighbours (a restart announces a newer one; they " +
          "accept it once this one has been silent for net.peer_silence_s)");
  res.io_sched = start_io_thread(*res.ep, log);
  res.ep->begin_probing();
}

void say_plan(const StationPlan& plan, const Log& log) {
  std::ostringstream os;
  const ScenarioSpec& spec = plan.built->spec;
  if (plan.overrides.solo) {
    os << "solo: scenario " << spec.name << ", 1 user, " << plan.built->scene.nodes << " nodes anchored by " << spec.scene.ground_stiffness_N_per_m
       << " N/m each, no network; run " << spec.duration_s << " s (Ctrl-C ends it sooner)";
    log.say(os.str());
    for (const auto& w : plan.warnings) log.say("warning: " + w);
    return;
  }
  os << "scenario " << spec.name << ", " << spec.users << " users, " << plan.built->scene.nodes << " nodes, neighbours";
  for (int j : plan.neighbours()) os << " " << j + 1;
  os << "; transport " << plan.net.transport << "; epoch in " << plan.times.epoch_in_s << " s, probing " << plan.file.station.probe_s << " s, run "
     << spec.duration_s << " s";
  log.say(os.str());
  for (const auto& w : plan.warnings) log.say("warning: " + w);
}

void say_bounds(const StationPlan& plan, const BuildResult& b, const Log& log) {
  std::ostringstream os;
  os << (plan.overrides.solo ? "no neighbour" : "probing done: round-trip bounds (ticks incl. allowance)");
  for (std::size_t n = 0; n < plan.neighbours().size(); ++n) os << " " << plan.neighbours()[n] + 1 << ":" << b.bounds.round_trip_ticks[n];
  os << "; B_i = " << b.bounds.damping_Ns_per_m << " N s/m (eq. 18 minimum " << b.bounds.damping_min_Ns_per_m << ", model "
     << plan.built->damping[static_cast<std::size_t>(plan.me)] << ")";
  log.say(os.str());
  if (!b.passivity_condition_met)
    log.say("warning: station.damping_Ns_per_m = " + std::to_string(b.bounds.damping_Ns_per_m) + " is below eq. (18) on the measured bounds (" +
            std::to_string(b.bounds.damping_min_Ns_per_m) + "): the passivity condition is not met (exit code " + std::to_string(kExitPassivityNotMet) + ")");
}

TickInputs tick_inputs(const StationPlan& plan, StationResources& res, rt::StationCore* core, rt::TxDeadband* tx, const drivers::WorkspaceMap* map) {
  TickInputs in;
  in.map = map;
  in.ramp_ticks = plan.ramp_in_ticks;
  in.core = core;
  in.tx_deadband = tx;
  in.ep = res.ep.get();
  in.device = res.dev.device.get();
  in.simulated = res.dev.simulated;
  in.gpio = res.gpio.get();
  in.telemetry = res.telemetry.get();
  in.recorder = res.recorder.get();
  in.view = res.view.get();
  in.sender_to_nbr = plan.peers.sender_to_nbr.data();
  in.dofs = plan.built->scene.dofs;
  in.trace_node = plan.built->trace_node;
  in.trace_every = plan.file.station.trace_every;
  in.state_every = plan.file.station.state_every;
  in.period_s = plan.built->spec.period_s;
  in.run_k0 = plan.times.run_k0;
  return in;
}

// The session log of this station (record.enabled): header and core configuration written here,
// before the RT thread exists. Not RT-safe.
std::unique_ptr<SessionRecorder> open_recorder(const StationPlan& plan, const BuildResult& build) {
  const rt::StationCore& core = *build.core;
  RecorderConfig rc;
  rc.path = plan.base_path + ".h5";
  rc.max_bytes = static_cast<std::uint64_t>(plan.file.record.max_mb * 1024 * 1024);
  rc.deflate_level = plan.file.record.deflate;
  rc.ring_ticks = record_ring_ticks(plan);
  SessionInfo info;
  info.source = "station";
  info.scenario = plan.file.station.scenario;
  info.station_id = plan.station_id;
  info.config_text = plan.file.text;
  info.fingerprint = fingerprint_text(plan.fingerprint);
  info.damping_min_Ns_per_m = build.bounds.damping_min_Ns_per_m;
  info.passivity_condition_met = build.passivity_condition_met;
  info.packets_float32 = plan.net.endpoint.wire.encoding == net::ValueEncoding::float32;
  return std::make_unique<SessionRecorder>(rc, info, core.config());
}

// One frame for the browsers: the tick's frame plus the endpoint's per-link delay, loss and up/down.
// Called on the view server's thread. Not RT-safe.
// What GET /status.json answers (haptic-lab's console polls it): the latest frame's state, compact.
// Built on the view server's thread from the frame the tick published (never on the RT thread).
std::string station_status_json(const StationPlan& plan, const nlohmann::json& frame) {
  const double duration = plan.built->spec.duration_s, t = frame.value("t", 0.0);
  nlohmann::json links = nlohmann::json::array();
  for (const auto& l : frame["links"])
    links.push_back({{"peer", l["peer"]}, {"N", l["index_delay"]}, {"Nbar", l["bound"]}, {"within", l["within"]}, {"up", l.value("up", true)},
                     {"delay_ms", l.value("delay_ms", 0.0)}, {"loss", l.value("loss", 0.0)}});
  const nlohmann::json s = {{"station", plan.station_id},
                            {"users", plan.built->spec.users},
                            {"phase", t < duration ? "running" : "run over"},
                            {"t", t},
                            {"k", frame["k"]},
                            {"seq", frame["seq"]},
                            {"duration_s", duration},
                            {"links", links},
                            {"overruns", frame["loop"]["overruns"]},
                            {"missed_cycles", frame["loop"]["missed_cycles"]},
                            {"port_J", frame["port_J"]},
                            {"controller_J", frame["controller_J"]},
                            {"vo_J", frame["vo_J"]},
                            {"gate", frame["gate"]},
                            {"safe_state", frame["safe_state"]},
                            {"host_starving", frame["host"]["starving"]}};
  return s.dump();
}

bool station_view_frame(const StationPlan& plan, StationResources& res, ViewFrame& f, std::uint64_t& missed, LinkSince& since, std::string& out,
                        std::string& status) {
  const std::uint64_t before = f.seq;
  if (!res.view->take(f)) return false;
  if (before > 0 && f.seq > before + 1) missed += f.seq - before - 1;
  nlohmann::json j = view_frame_json(f);
  const net::EndpointStats st = res.ep ? res.ep->stats() : net::EndpointStats{};
  nlohmann::json proxies = nlohmann::json::array();  // the neighbours' proxies, from their newest state packets
  for (std::size_t n = 0; n < plan.neighbours().size() && n < j["links"].size(); ++n) {
    const auto p = static_cast<std::size_t>(plan.peers.nbr_to_peer[n]);
    if (p >= st.peers.size()) continue;
    const net::PeerStats& ps = st.peers[p];
    j["links"][n]["delay_ms"] = ps.one_way_mean_s * 1e3;
    j["links"][n]["loss"] = ps.loss_fraction;
    j["links"][n]["up"] = ps.up;
    if (ps.has_proxy)
      proxies.push_back({{"station", j["links"][n]["peer"]}, {"vp", {ps.proxy_m[0], ps.proxy_m[1], ps.proxy_m[2]}}, {"seq", ps.proxy_seq}});
  }
  j["proxies"] = std::move(proxies);
  since.annotate(j);
  j["frames_dropped"] = missed;  // frames the tick published that this thread never took (the server adds its own count)
  status = station_status_json(plan, j);
  out = j.dump();
  return true;
}

// The live view (station.view_port > 0): the tick's frame mailbox and the web server, both built
// here before the RT thread exists. Not RT-safe.
void open_view(const StationPlan& plan, StationResources& res, const BuildResult& build) {
  const double T = plan.built->spec.period_s;
  res.view = std::make_unique<ViewPublisher>(static_cast<int>(std::lround(1.0 / (plan.file.view.rate_hz * T))));
  nlohmann::json scene = view_scene_json(*build.core, plan.station_id, "station");
  scene["damping_min_Ns_per_m"] = build.bounds.damping_min_Ns_per_m;
  scene["passivity_condition_met"] = build.passivity_condition_met;
  scene["proxies_from"] = {{"stations", scene["neighbours"]}, {"source", "their state packets"},
                           {"missing", "not its neighbours: the wire brings a station only its neighbours' proxies"}};
  const std::string scene_text = scene.dump();
  auto frame = std::make_shared<ViewFrame>();
  auto missed = std::make_shared<std::uint64_t>(0);
  ViewCallbacks cb;
  cb.scene = [scene_text] { return scene_text; };
  auto since = std::make_shared<LinkSince>();
  // the latest status (GET /status.json); both callbacks run on the view server's thread
  auto status = std::make_shared<std::string>(
      nlohmann::json({{"station", plan.station_id}, {"users", plan.built->spec.users}, {"phase", "starting"}, {"duration_s", plan.built->spec.duration_s}})
          .dump());
  cb.next_frame = [&plan, &res, frame, missed, since, status](std::string& out) {
    return station_view_frame(plan, res, *frame, *missed, *since, out, *status);
  };
  cb.status = [status] { return *status; };
  ViewServerConfig vc;
  vc.bind = plan.file.view.bind;
  vc.port = plan.file.view.port;
  vc.rate_hz = plan.file.view.rate_hz;
  res.view_server = std::make_unique<ViewServer>(vc, cb);
}

// run: refuses a core that is ready more than a second after the run start; else the loop.
// After the run loop (no race with the tick): the energy gate's trips and the round trips measured
// above the bound, one line per neighbour each, logged and kept in the neighbour events.
void say_after_run(const StationPlan& plan, StationResources& res, PhaseResults& pr, nlohmann::json& ev, const Log& log) {
  std::vector<std::string> lines = energy_bound_events(plan, *pr.build.core);
  for (auto& line : return_ramp_events(plan, *pr.build.core)) lines.push_back(std::move(line));
  if (res.ep)
    for (auto& line : round_trip_over_bound_events(plan, res.ep->stats(), pr.build.bounds.round_trip_ticks)) lines.push_back(std::move(line));
  for (const auto& line : lines) {
    log.say(line);
    ev.push_back(line);
  }
}

// The record windows and their writer thread (station/records.hpp), before the run stage is handed to the loop.
bool open_records(const StationPlan& plan, PhaseResults& pr) {
  pr.records.reserve(plan.trace_capacity, plan.state_capacity, plan.built->scene.dofs);
  try {
    pr.record_files = std::make_unique<RecordFiles>(plan.base_path, plan.built->spec.period_s, pr.records);
  } catch (const std::exception& e) {
    pr.fail(PhaseStatus::kFailed, std::string("station records: ") + e.what());
    return false;
  }
  return true;
}

// After the tick's last row: the writer drains the windows and closes the CSV files; rows the tick
// dropped because the writer fell behind are said here (and counted in station-<id>.json "records").
void finish_records(PhaseResults& pr, const Log& log) {
  const std::string err = pr.record_files->finish();
  if (!err.empty()) pr.fail(PhaseStatus::kFailed, "station records: " + err);
  const TickRecords& r = pr.records;
  if (r.trace_lost > 0 || r.state_lost > 0)
    log.say("warning: the record writer fell behind the tick: " + std::to_string(r.trace_lost) + " trace rows and " + std::to_string(r.state_lost) +
            " state rows were dropped (the tick never waits for it; the CSV files miss those ticks; windows of " + std::to_string(r.trace_window.slots()) +
            " and " + std::to_string(r.state_window.slots()) + " rows)");
}

// The output side of the run (record windows, recorder, live view) and the tick's inputs; false on a failure.
bool prepare_run(const StationPlan& plan, StationResources& res, PhaseResults& pr, TickInputs& in, const Log& log) {
  if (!open_records(plan, pr)) return false;
  if (plan.file.record.enabled) {
    try {
      res.recorder = open_recorder(plan, pr.build);
      log.say("recording the session to " + res.recorder->path());
    } catch (const std::exception& e) {
      pr.fail(PhaseStatus::kFailed, std::string("session log: ") + e.what());
      return false;
    }
  }
  if (plan.file.view.port > 0) {
    try {
      open_view(plan, res, pr.build);
      log.say("live view at " + res.view_server->url());
      if (plan.overrides.solo) std::cout << log.tag << ": live view at " << res.view_server->url() << " (open it in a browser)" << std::endl;
    } catch (const std::exception& e) {
      pr.fail(PhaseStatus::kFailed, e.what());
      return false;
    }
  }
  in = tick_inputs(plan, res, pr.build.core.get(), &pr.build.tx_deadband, &pr.build.map);
  if (!pr.build.max_age_s.empty()) in.max_age_s = pr.build.max_age_s.data();  // the age guard
  if (pr.probe.clock.shift_ticks.size() == plan.neighbours().size()) in.seq_shift_ticks = pr.probe.clock.shift_ticks.data();  // grid offsets
  return true;
}

// run: refuses a core that is ready more than a second after the run start; else hands the run
// stage to the station's loop (a rejoining station's moves the loop onto the session's grid) and
// waits for the loop to end, logging neighbour events meanwhile.
void run_phase(StationPlan& plan, StationResources& res, PhaseResults& pr, StationLoop& loop, const RunObserver& base, std::atomic<bool>& stop,
               const Log& log) {
  const double late_s = static_cast<double>(read_clocks().monotonic_ns - plan.times.run_epoch_ns()) * 1e-9;
  if (late_s > 1.0 && !plan.times.rejoin && !plan.overrides.solo) {
    pr.fail(PhaseStatus::kFailed, "the station core was ready " + std::to_string(late_s) + " s after the run start (station.setup_gap_s too short?)");
    return;
  }
  TickInputs in;
  if (!prepare_run(plan, res, pr, in, log)) return;
  RunObserver observer = base;
  // Neighbours going silent and coming back: logged once each (station id, session time). The edges'
  // safeguards (an isolation, a gate trip or release) when they act, from the tick's event ring.
  PeerEventLog events(plan, plan.times.run_epoch_ns(), plan.net.endpoint.peer_silence_s + 0.1);
  nlohmann::json& ev = pr.lifecycle["neighbour_events"] = nlohmann::json::array();
  EdgeEventWatch edge_watch;
  in.edge_events = &edge_watch;
  const auto say_edge_events = [&] {
    for (const EdgeEvent& e : edge_watch.drain()) {
      const std::string line = edge_event_line(e, plan.neighbours()[static_cast<std::size_t>(e.edge)] + 1, *pr.build.core);
      log.say(line);
      ev.push_back(line);
    }
  };
  observer.idle = [&] {
    if (res.ep)
      for (const auto& line : events.poll(res.ep->stats())) {
        log.say(line);
        ev.push_back(line);
      }
    say_edge_events();
  };
  if (res.ep) res.ep->sending_resumes(net::monotonic_ns());  // echoes held through the set-up gap are no round trips
  // A rejoining station refreshes the adopted state at its first tick (RT-safe, preallocated).
  Eigen::VectorXd x = pr.build.core->x(), v = pr.build.core->v();
  bool first = plan.times.rejoin;
  const auto& hook = plan.overrides.test_tick_hook;  // in-process tests only (a simulated host stall)
  const RunTickFn tick = [&](std::int64_t k, std::int64_t kr, const platform::TickInfo& info) {
    if (first) {
      refresh_adopted_state(plan, *res.ep, *pr.build.core, x, v, pr.adopted);
      first = false;
    }
    if (hook) hook(kr);
    run_tick(in, pr.records, pr.counters, k, kr, info);
  };
  int run_index = 0;
  if (plan.overrides.solo) {  // the loop's first and only stage, from now (solo: nothing to wait for)
    plan.times.epoch_ns = net::monotonic_ns() + kSoloStartNs;
    try {
      loop.start(run_stage(plan, tick, stop, false), observer);
    } catch (const std::exception& e) {  // RtThread set-up refused (rt.require_rt)
      pr.fail(PhaseStatus::kFailed, std::string("real-time set-up: ") + e.what());
      return;
    }
  } else {
    run_index = loop.hand_over(run_stage(plan, tick, stop, plan.times.rejoin));
  }
  pr.run = loop.run_result(run_index, observer);
  pr.ran = true;
  say_edge_events();  // the last events (the loop ended before the next serve)
  if (edge_watch.dropped() > 0) log.say("warning: " + std::to_string(edge_watch.dropped()) + " edge events did not fit the tick's event ring (the totals follow)");
  pr.counters.outages.finish();  // the loop ended: a span still open closes at the last tick
  finish_records(pr, log);
  say_after_run(plan, res, pr, ev, log);
  pr.lifecycle["device"]["outside_workspace_ticks"] = pr.counters.outside_workspace_ticks;
  if (plan.times.rejoin) {
    pr.lifecycle["rejoin"]["state_from_station"] = pr.adopted.from_station;
    pr.lifecycle["rejoin"]["state_tick"] = pr.adopted.seq;
    pr.lifecycle["rejoin"]["coupled_at_tick"] = pr.run.first_run_k;
  }
  if (pr.run.status == PhaseStatus::kFailed) pr.fail(PhaseStatus::kFailed, pr.run.message);
}

// The probe's warnings and what the report keeps of the neighbours' clocks.
void note_probe(const StationPlan& plan, PhaseResults& pr, const Log& log) {
  for (const auto& w : pr.probe.warnings) log.say("warning: " + w);
  nlohmann::json offs = nlohmann::json::object();
  for (std::size_t n = 0; n < pr.probe.clock.grid_offset_s.size(); ++n) {
    const double o = pr.probe.clock.grid_offset_s[n], u = pr.probe.clock.uncertainty_s[n];
    const std::int64_t shift = n < pr.probe.clock.shift_ticks.size() ? pr.probe.clock.shift_ticks[n] : 0;
    offs[std::to_string(plan.neighbours()[n] + 1)] = {{"tick_grid_offset_ms", std::isfinite(o) ? nlohmann::json(o * 1e3) : nlohmann::json(nullptr)},
                                                      {"uncertainty_ms", std::isfinite(u) ? nlohmann::json(u * 1e3) : nlohmann::json(nullptr)},
                                                      {"sequence_shift_ticks", shift}};
    if (shift != 0)
      log.say("station " + std::to_string(plan.neighbours()[n] + 1) + "'s tick grid is " + std::to_string(std::lround(std::abs(o) * 1e3)) + " ms " +
              (o > 0 ? "behind" : "ahead of") + " ours: its sequence numbers are mapped onto our grid (" + std::to_string(shift) +
              " ticks; used up to station.clock_offset_limit_ms = " + std::to_string(plan.file.station.clock_offset_limit_ms) + ")");
  }
  pr.lifecycle["clock_offsets"] = offs;
  pr.lifecycle["clock_offset_exceeded"] = pr.probe.clock.exceeded;
}

// rejoin (instead of probe): the loop's stage `index` (rejoin_stage) learns the session's epoch and
// measures round trips; the plan's epoch becomes the learned one.
bool rejoin_session(StationPlan& plan, StationResources& res, PhaseResults& pr, StationLoop& loop, int index, const RunObserver& obs,
                    std::atomic<bool>& stop, const Log& log) {
  loop.wait_stage(index, obs);
  end_rejoin_probe(plan, *res.ep, stop, loop.stage(index), pr.rejoin);
  pr.probe = pr.rejoin.probe;
  pr.probed = true;
  if (pr.probe.status == PhaseStatus::kStopped) return false;
  if (pr.probe.status != PhaseStatus::kOk) {
    pr.fail(pr.probe.status, pr.probe.message);
    return false;
  }
  plan.times.epoch_ns = pr.rejoin.epoch_ns;
  std::ostringstream os;
  os << "rejoining: the session's epoch from station " << pr.rejoin.epoch_from_station << " is " << pr.rejoin.epoch_shift_s * 1e3
     << " ms from the planned one (+- " << pr.rejoin.epoch_uncertainty_s * 1e3 << " ms)";
  log.say(os.str());
  pr.lifecycle["rejoin"] = {{"epoch_from_station", pr.rejoin.epoch_from_station},
                            {"epoch_shift_ms", pr.rejoin.epoch_shift_s * 1e3},
                            {"epoch_uncertainty_ms", pr.rejoin.epoch_uncertainty_s * 1e3},
                            {"provisional_pushes", pr.rejoin.provisional_pushes}};
  return true;
}

// Before a rejoining station couples: a neighbour's current object state becomes its own.
bool adopt_state(const StationPlan& plan, StationResources& res, PhaseResults& pr, const Log& log) {
  pr.adopted = adopt_neighbour_state(plan, *res.ep, *pr.build.core, 0.5);
  if (!pr.adopted.ok) {
    pr.fail(PhaseStatus::kFailed, pr.adopted.message);
    return false;
  }
  const std::int64_t k_now = plan.times.tick_at(read_clocks().monotonic_ns);
  pr.build.core->arm_return_ramps();  // the other neighbours' copies drifted from the adopted one: ramp each edge in
  log.say("rejoining: took over station " + std::to_string(pr.adopted.from_station) + "'s object state of tick " + std::to_string(pr.adopted.seq) +
          " (now tick " + std::to_string(k_now) + "; refreshed at the first run tick); coupling, each edge ramped in over station.return_ramp_s = " +
          std::to_string(plan.file.station.return_ramp_s) + " s");
  return true;
}

// The device's current position (device frame) before the core is built, to place the virtual
// proxy there: the newest sample, waiting up to 0.2 s for a first one. Non-RT (the loop reads the
// device only in run ticks, which have not begun, so this thread is the mailbox's only reader).
bool initial_device_position(drivers::HapticDevice& dev, double out[3]) {
  drivers::DeviceSample s{};
  for (int i = 0; i < 100; ++i) {
    if (dev.read_newest(s)) {
      for (int a = 0; a < 3; ++a) out[a] = s.position_m[a];
      return true;
    }
    if (dev.fault() != drivers::DeviceFault::kNone) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return false;
}

// Start-up lines and lifecycle.device: gains, b_d, force limit, the map, where the proxy starts, the ramp.
void note_device_coupling(const StationPlan& plan, PhaseResults& pr, const Log& log) {
  const BuildResult& b = pr.build;
  const DeviceCoupling& c = b.coupling;
  const Eigen::Vector3d& y0 = b.proxy_start_m;
  std::ostringstream os;
  os << "device coupling: b_d " << c.b_d_Ns_per_m << " N s/m (" << c.b_d_source << "), K_vc " << c.gains.K_vc_N_per_m << " N/m, B_vc "
     << c.gains.B_vc_Ns_per_m << " N s/m, b_v " << c.gains.b_v_Ns_per_m << " N s/m, force limit " << c.force_limit_N << " N, map scale "
     << b.map.scale() << "; proxy starts at (" << y0.x() << ", " << y0.y() << ", " << y0.z() << ") m"
     << (b.proxy_from_device ? (b.proxy_projected ? " (the mapped device position was inside the object: projected onto its face)" : " (the mapped device position)")
                             : " (the scenario's start)")
     << "; force ramp-in " << static_cast<double>(plan.ramp_in_ticks) * plan.built->spec.period_s << " s";
  log.say(os.str());
  nlohmann::json& d = pr.lifecycle["device"];
  d["b_d_Ns_per_m"] = c.b_d_Ns_per_m;
  d["b_d_source"] = c.b_d_source;
  d["K_vc_N_per_m"] = c.gains.K_vc_N_per_m;
  d["B_vc_Ns_per_m"] = c.gains.B_vc_Ns_per_m;
  d["b_v_Ns_per_m"] = c.gains.b_v_Ns_per_m;
  d["force_limit_N"] = c.force_limit_N;
  d["force_feedback"] = c.force_feedback;
  d["map_scale"] = b.map.scale();
  d["proxy_start_m"] = {y0.x(), y0.y(), y0.z()};
  d["proxy_from_device"] = b.proxy_from_device;
  d["proxy_projected"] = b.proxy_projected;
  d["ramp_in_s"] = static_cast<double>(plan.ramp_in_ticks) * plan.built->spec.period_s;
}

// What the non-RT side does with the loop's set-up report and its throttled reports.
RunObserver loop_observer(const Log& log) {
  RunObserver observer;
  observer.rt_ready = [&log](const std::string& summary, const std::vector<std::string>& warnings) {
    if (!summary.empty() && !log.quiet) std::cerr << summary << (summary.back() == '\n' ? "" : "\n");
    for (const auto& w : warnings) log.say("warning: " + w + " (running anyway; rt.require_rt = false)");
  };
  observer.report = [&log](const platform::LoopReport& rep) {
    if (rep.window_overruns > 0) log.say(platform::format_report(rep));
  };
  return observer;
}

// The measured step bounds stay where eq. (26) holds for the opened device (probe.hpp StepSet). A
// coupling that fails even at the period is refused by the build, which says why.
void note_eq26_step_margin(const StationPlan& plan, const StationResources& res, PhaseResults& pr) {
  try {
    const DeviceCoupling c = device_coupling(plan.file, plan.built->spec, res.dev.device->capabilities());
    const double T = plan.built->spec.period_s;
    if (c.force_feedback) pr.probe.steps.eq26_margin_max_s = eq26_largest_step_margin_s(c, T, plan.file.station.step_margin_max * T);
  } catch (const std::invalid_argument&) {
    pr.probe.steps.eq26_margin_max_s = 0.0;
  }
}

// probe (or rejoin): the loop's first stages. The loop starts here, with probing (or, for a station
// planned as a rejoin, the provisional probes) and keeps running, on the timeline's grid, through
// the build to the end of the run. False when the sequence ends here.
bool probe_phase(StationPlan& plan, StationResources& res, PhaseResults& pr, StationLoop& loop, const RunObserver& obs, std::atomic<bool>& stop,
                 const Log& log) {
  const char* probe_only_late = "probe only: the session already runs (or its probing is over); give every station the same future --start-at";
  if (plan.times.rejoin && plan.overrides.probe_only) {  // never joins a running session
    pr.fail(PhaseStatus::kFailed, probe_only_late);
    return false;
  }
  note_eq26_step_margin(plan, res, pr);
  try {
    const std::int64_t now = net::monotonic_ns();
    loop.start(plan.times.rejoin ? rejoin_stage(plan, *res.ep, pr.rejoin, now) : probe_stage(plan, *res.ep, pr.probe, now), obs);
  } catch (const std::exception& e) {  // RtThread set-up refused (rt.require_rt)
    pr.fail(PhaseStatus::kFailed, std::string("real-time set-up: ") + e.what());
    return false;
  }
  if (plan.times.rejoin) return rejoin_session(plan, res, pr, loop, 0, obs, stop, log);
  loop.wait_stage(0, obs);
  end_probe(plan, *res.ep, stop, loop.stage(0), pr.probe);
  pr.probed = true;
  if (pr.probe.status == PhaseStatus::kStopped) return false;
  if (pr.probe.status != PhaseStatus::kOk) {
    pr.fail(pr.probe.status, pr.probe.message);
    return false;
  }
  if (pr.probe.running_session_from == 0) return true;
  // a restart with a fresh epoch (relative start_delay_s): rejoin
  if (plan.overrides.probe_only) {
    pr.fail(PhaseStatus::kFailed, probe_only_late);
    return false;
  }
  log.say("rejoining: " + pr.probe.message + "; this station is a restart, its own epoch is not the session's");
  plan.times.rejoin = true;
  pr.lifecycle["rejoin_detected_from_station"] = pr.probe.running_session_from;
  const int index = loop.hand_over(rejoin_stage(plan, *res.ep, pr.rejoin, net::monotonic_ns()));
  return rejoin_session(plan, res, pr, loop, index, obs, stop, log);
}

// open -> probe (or rejoin) -> build -> run; each phase's failure ends the sequence. Probe, rejoin
// and run are stages of one loop (loop.hpp); the build runs on this thread while the loop keeps
// the grid with set-up ticks.
void run_phases(StationPlan& plan, StationResources& res, PhaseResults& pr, std::atomic<bool>& stop, const Log& log) {
  try {
    open_resources(plan, res, log);
  } catch (const drivers::DeviceMissing& e) {
    pr.fail(PhaseStatus::kDeviceMissing, std::string("start-up: ") + e.what());
    return;
  } catch (const std::exception& e) {
    pr.fail(PhaseStatus::kFailed, std::string("start-up: ") + e.what());
    return;
  }
  pr.lifecycle["device"] = {{"kind", plan.device.kind},
                            {"name", res.dev.device->capabilities().name},
                            {"simulated_user", plan.device.kind == "simulated"}};
  say_plan(plan, log);
  StationLoop loop(plan, res.dev.device.get(), stop);  // ends (joined) when this function returns
  const RunObserver obs = loop_observer(log);
  if (!plan.overrides.solo) {  // solo: no neighbour to probe; build (eq. 18 over no link) and run
    if (!probe_phase(plan, res, pr, loop, obs, stop, log)) return;
    note_probe(plan, pr, log);
    if (plan.overrides.probe_only) {  // --probe-only: reachability, round trips, loss and clock offsets measured; nothing coupled
      pr.lifecycle["probe_only"] = true;
      log.say("probe only: every neighbour answered with a matching fingerprint; stopping before coupling (no run)");
      return;
    }
  }
  double q0[3];
  const bool have_q0 = initial_device_position(*res.dev.device, q0);
  if (!have_q0) log.say("warning: the device gave no sample before coupling: the virtual proxy starts at the scenario's start");
  pr.build = build_station_core(plan, pr.probe, res.dev.device->capabilities(), have_q0 ? q0 : nullptr);
  pr.built = true;
  if (pr.build.status != PhaseStatus::kOk) return pr.fail(pr.build.status, pr.build.message);
  note_device_coupling(plan, pr, log);
  say_bounds(plan, pr.build, log);
  if (pr.probe.steps.fixed) log.say(pr.probe.steps.text);
  if (plan.times.rejoin && !adopt_state(plan, res, pr, log)) return;
  run_phase(plan, res, pr, loop, obs, stop, log);
}

nlohmann::json recording_json(const RecorderStats& s, const std::string& path) {
  return {{"path", path}, {"ticks", s.ticks}, {"packets", s.packets}, {"dropped_records", s.dropped_records}, {"bytes", s.bytes},
          {"truncated_at_tick", s.truncated_at_tick}, {"lossy_packet_values", s.lossy_packet_values}, {"error", s.error},
          {"first_tick", s.first_tick}, {"packets_complete_from_tick", s.packets_complete_from_tick}};
}

// report: stop what was opened, name the conditions, write the outputs; returns the exit code.
int report_phase(const StationPlan& plan, StationResources& res, PhaseResults& pr, double wall_s, const Log& log) {
  StationOutcome o;
  o.plan = &plan;
  o.probe = pr.probed ? &pr.probe : nullptr;
  o.build = pr.built ? &pr.build : nullptr;
  o.run = pr.ran ? &pr.run : nullptr;
  o.counters = &pr.counters;
  o.records = &pr.records;
  o.records_streamed = pr.record_files != nullptr;
  o.endpoint = res.ep.get();
  o.failure = pr.failure;
  o.failure_status = pr.failure_status;
  o.io_sched = res.io_sched;
  o.wall_time_s = wall_s;
  o.lifecycle = pr.lifecycle;
  if (res.dev.device) {
    o.device_name = res.dev.device->capabilities().name;
    o.device_fault = drivers::fault_name(res.dev.device->fault());  // before stop(), which latches "not started"
    if (res.dev.device->fault() == drivers::DeviceFault::kNone) o.device_fault = "none";
  }
  if (res.ep) res.ep->stop();
  if (res.dev.device) res.dev.device->stop();
  if (res.telemetry) res.telemetry->flush();
  if (res.recorder) o.recording = recording_json(res.recorder->finish(), res.recorder->path());
  if (res.view_server) {
    const ViewServerStats v = res.view_server->stats();
    o.recording["view"] = {{"frames", v.frames}, {"frames_sent", v.frames_sent}, {"frames_dropped", v.frames_dropped}, {"browsers", v.clients_total},
                           {"service_errors", v.service_errors}, {"last_browser_status", v.last_browser_status}};
    res.view_server.reset();
  }
  if (!pr.failure.empty()) log.error(pr.failure);
  const RunConditions c = run_conditions(o);
  const int code = exit_code(c);
  for (const auto& m : c.key_compromise_messages) log.error(m);
  for (const auto& m : c.isolation_messages) log.error(m);
  if (c.missed_cycles)
    log.error("missed " + std::to_string(c.missed_cycles_total) + " cycles (more than station.max_missed_cycles = " +
              std::to_string(plan.file.station.max_missed_cycles) + "): the host stalled this station (SIGSTOP, swap, a starved CPU); " +
              "its neighbours saw it silent meanwhile");
  for (const auto& line : explain_exit(o, c, code).lines) log.error(line);  // the links, the times, the measured cause
  try {
    write_station_outputs(o, c);
  } catch (const std::exception& e) {
    log.error(e.what());
    return code == kExitOk ? kExitRunFailed : code;
  }
  std::string names;
  for (const auto& n : c.names()) {
    if (!names.empty()) names += ", ";
    names += n;
  }
  std::cout << log.tag << ": " << (code == kExitOk ? "done" : "FAILED (" + names + ")") << ", " << pr.counters.ticks_run << " ticks, "
            << pr.run.loop.overruns << " overruns (" << c.missed_cycles_total << " missed cycles), "
            << verdict_words(station_verdict(o))
            << ", B_i "
            << (pr.built ? std::to_string(pr.build.bounds.damping_Ns_per_m) : std::string("none")) << " N s/m; exit " << code << "; wrote "
            << plan.base_path << ".json, -trace.csv, -state.csv\n";
  return code;
}

}  // namespace

std::string exit_code_help() {
  return "Exit codes (when several hold, the first in this list): 0 done; 2 configuration error (the key is named as written in the file); "
         "9 device missing (device.kind names a device that could not be started; a station never substitutes a simulated user: "
         "device.kind = \"simulated\" asks for one); "
         "4 diverged; 5 safe state latched (loop exception or device fault); 6 passivity condition not met (B_i below eq. (18) on the measured "
         "round-trip bounds); 4, 5 and 6 are safety stops: the systemd unit does not restart them, the operator re-arms; "
         "12 key compromise suspected (a neighbour's key was seen in two live incarnations: both refused for the rest of the run, the station "
         "ran without that neighbour; station-<id>.json \"key_compromise\" names it; not restarted by the systemd unit: revoke the key); "
         "13 neighbour isolated (the neighbour state check, station.state_check_*, found a neighbour's reported states inconsistent with "
         "its own velocities or far from this copy: its edge acted as a damper until re-admitted; the log and station-<id>.json "
         "\"isolation\" name the station, the reason and the times; not restarted by the systemd unit: a restart would forget it); "
         "11 missed cycles (the run loop skipped more than station.max_missed_cycles periods: the host stalled the station; not a safety stop, "
         "the systemd unit restarts it); 7 no neighbour (none answered probing, or none within its bound for more than station.max_no_neighbour_fraction "
         "of the run); 3 other run-time failure; 8 the run ended before the scripted release (e.g. --duration shorter than station.release_s); "
         "10 held by the gate (the per-edge energy gate tripped: the run stayed bounded by the gate, not by eq. (18) alone). "
         "station-<id>.json names each condition under \"conditions\" (also edge_drop_rule_acted, which has no code of its own) "
         "and what the gate did under \"gate\". Every non-zero exit prints why, as measured: this host's wake-up P99/max, overruns and "
         "skipped periods (\"STARVING\" when it skipped 1 % of the periods or its wake-up P99 reached a period), and for 7 each span "
         "without a usable neighbour with its times, each link SILENT or LATE against N-bar, and the host in it; for 11 the longest "
         "stall (station-<id>.json \"explanation\" and \"host\").";
}

int check_station_config(const StationFile& file, const RunOverrides& overrides, std::ostream& out, std::ostream& err) {
  const PlanResult pr = plan_station(file, overrides, read_clocks());
  if (pr.status != PhaseStatus::kOk) {
    err << "haptic-station run: error: " << pr.error << "\n";
    return pr.status == PhaseStatus::kDeviceMissing ? kExitDeviceMissing : kExitConfigError;
  }
  const StationPlan& p = *pr.plan;
  const ScenarioSpec& spec = p.built->spec;
  out << "config ok: station " << p.station_id << " of " << spec.users << ", scenario " << spec.name << ", " << p.built->scene.nodes << " nodes, "
      << p.neighbours().size() << " neighbour(s), duration " << spec.duration_s << " s, release " << spec.script.release_s << " s, out_dir "
      << p.out_dir << "\n";
  for (const auto& w : p.warnings) out << "warning: " << w << "\n";
  return kExitOk;
}

int run_station(const StationFile& f, const RunOverrides& o, std::atomic<bool>& stop) {
  const auto wall0 = std::chrono::steady_clock::now();
  const Log log{o.solo ? std::string("haptic-station solo") : "haptic-station run [station " + std::to_string(f.station.id) + "]", o.quiet};
  PlanResult plan = plan_station(f, o, read_clocks());
  if (plan.status != PhaseStatus::kOk) {
    log.error(plan.error);
    return plan.status == PhaseStatus::kDeviceMissing ? kExitDeviceMissing : kExitConfigError;
  }
  StationResources res;
  PhaseResults pr;
  run_phases(*plan.plan, res, pr, stop, log);
  return report_phase(*plan.plan, res, pr, std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(), log);
}

}  // namespace haptic::firmware
