#include "firmware/station_run.hpp"

#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#include "drivers/device_factory.hpp"
#include "platform/gpio.hpp"
#include "platform/telemetry.hpp"

namespace haptic::firmware {

namespace {

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
  std::string io_sched = "not started";
};

// Everything the phases returned, owned here so the report can point into it.
struct PhaseResults {
  ProbeResult probe;
  BuildResult build;
  RunPhaseResult run;
  bool probed = false, built = false, ran = false;
  TickCounters counters;
  TickRecords records;
  std::string failure;
  PhaseStatus failure_status = PhaseStatus::kOk;
  void fail(PhaseStatus s, const std::string& message) {
    if (!failure.empty()) return;
    failure = message;
    failure_status = s;
  }
};

// The endpoint's I/O thread inherits the scheduling of the thread that starts it: SCHED_FIFO at
// station.io_priority, so round trips measure the network rather than CPU contention.
std::string start_io_thread(net::Endpoint& ep, int io_priority, const Log& log) {
  std::string sched = "SCHED_OTHER";
  if (io_priority > 0) {
    sched_param sp{};
    sp.sched_priority = io_priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (rc == 0) sched = "SCHED_FIFO " + std::to_string(io_priority);
    else log.say("warning: I/O thread stays SCHED_OTHER (SCHED_FIFO " + std::to_string(io_priority) + " refused: " + std::strerror(rc) + "); running anyway");
  }
  ep.start();
  if (io_priority > 0) {
    sched_param sp{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
  }
  return sched;
}

// open: output directory, device, transport + endpoint (I/O thread started, probing), GPIO, telemetry.
void open_resources(const StationPlan& plan, StationResources& res, const Log& log) {
  std::filesystem::create_directories(plan.out_dir);
  res.dev = drivers::open_device(plan.device);
  log.say("device: " + std::string(res.dev.device->capabilities().name) +
          (res.dev.simulated ? " (simulated user: scenario script of user " + std::to_string(plan.station_id) + ")" : ""));
  if (!log.quiet && !res.dev.report.empty()) std::cerr << res.dev.report << (res.dev.report.back() == '\n' ? "" : "\n");
  res.ep = std::make_unique<net::Endpoint>(plan.net.endpoint, plan.net.make_transport());
  res.gpio = std::make_unique<platform::GpioToggler>(plan.file.gpio);
  if (!plan.file.telemetry.path.empty()) {
    platform::TelemetryConfig tc = plan.file.telemetry;
    tc.period_s = plan.built->spec.period_s;
    tc.value_names = {"force_x_N", "force_y_N", "force_z_N", "device_x_m", "device_y_m", "device_z_m", "port_energy_J", "controller_energy_J", "vo_energy_J",
                      "contact", "edge_drops"};
    res.telemetry = std::make_unique<platform::Telemetry>(tc);
  }
  res.io_sched = start_io_thread(*res.ep, plan.file.station.io_priority, log);
  res.ep->begin_probing();
}

void say_plan(const StationPlan& plan, const Log& log) {
  std::ostringstream os;
  const ScenarioSpec& spec = plan.built->spec;
  os << "scenario " << spec.name << ", " << spec.users << " users, " << plan.built->scene.nodes << " nodes, neighbours";
  for (int j : plan.neighbours()) os << " " << j + 1;
  os << "; transport " << plan.net.transport << "; epoch in " << plan.times.epoch_in_s << " s, probing " << plan.file.station.probe_s << " s, run "
     << spec.duration_s << " s";
  log.say(os.str());
  for (const auto& w : plan.warnings) log.say("warning: " + w);
}

void say_bounds(const StationPlan& plan, const BuildResult& b, const Log& log) {
  std::ostringstream os;
  os << "probing done: round-trip bounds (ticks incl. allowance)";
  for (std::size_t n = 0; n < plan.neighbours().size(); ++n) os << " " << plan.neighbours()[n] + 1 << ":" << b.bounds.round_trip_ticks[n];
  os << "; B_i = " << b.bounds.damping_Ns_per_m << " N s/m (eq. 18 minimum " << b.bounds.damping_min_Ns_per_m << ", model "
     << plan.built->damping[static_cast<std::size_t>(plan.me)] << ")";
  log.say(os.str());
  if (!b.passivity_condition_met)
    log.say("warning: station.damping_Ns_per_m = " + std::to_string(b.bounds.damping_Ns_per_m) + " is below eq. (18) on the measured bounds (" +
            std::to_string(b.bounds.damping_min_Ns_per_m) + "): the passivity condition is not met (exit code " + std::to_string(kExitPassivityNotMet) + ")");
}

TickInputs tick_inputs(const StationPlan& plan, StationResources& res, rt::StationCore* core) {
  TickInputs in;
  in.core = core;
  in.ep = res.ep.get();
  in.device = res.dev.device.get();
  in.simulated = res.dev.simulated;
  in.gpio = res.gpio.get();
  in.telemetry = res.telemetry.get();
  in.sender_to_nbr = plan.peers.sender_to_nbr.data();
  in.dofs = plan.built->scene.dofs;
  in.trace_node = plan.built->trace_node;
  in.trace_every = plan.file.station.trace_every;
  in.state_every = plan.file.station.state_every;
  in.period_s = plan.built->spec.period_s;
  in.run_k0 = plan.times.run_k0;
  return in;
}

// run: refuses a core that is ready more than a second after the run start; else the loop.
void run_phase(const StationPlan& plan, StationResources& res, PhaseResults& pr, std::atomic<bool>& stop, const Log& log) {
  const double late_s = static_cast<double>(read_clocks().monotonic_ns - plan.times.run_epoch_ns()) * 1e-9;
  if (late_s > 1.0) {
    pr.fail(PhaseStatus::kFailed, "the station core was ready " + std::to_string(late_s) + " s after the run start (station.setup_gap_s too short?)");
    return;
  }
  pr.records.reserve(plan.trace_capacity, plan.state_capacity, plan.built->scene.dofs);
  const TickInputs in = tick_inputs(plan, res, pr.build.core.get());
  RunObserver observer;
  observer.rt_ready = [&](const std::string& summary, const std::vector<std::string>& warnings) {
    if (!summary.empty() && !log.quiet) std::cerr << summary << (summary.back() == '\n' ? "" : "\n");
    for (const auto& w : warnings) log.say("warning: " + w + " (running anyway; rt.require_rt = false)");
  };
  observer.report = [&](const platform::LoopReport& rep) {
    if (rep.window_overruns > 0) log.say(platform::format_report(rep));
  };
  pr.run = run_loop(plan, in, pr.records, pr.counters, stop, observer);
  pr.ran = true;
  if (pr.run.status == PhaseStatus::kFailed) pr.fail(PhaseStatus::kFailed, pr.run.message);
}

// open -> probe -> build -> run; each phase's failure ends the sequence.
void run_phases(const StationPlan& plan, StationResources& res, PhaseResults& pr, std::atomic<bool>& stop, const Log& log) {
  try {
    open_resources(plan, res, log);
  } catch (const std::exception& e) {
    pr.fail(PhaseStatus::kFailed, std::string("start-up: ") + e.what());
    return;
  }
  say_plan(plan, log);
  pr.probe = probe_neighbours(plan, *res.ep, stop);
  pr.probed = true;
  if (pr.probe.status == PhaseStatus::kStopped) return;
  if (pr.probe.status != PhaseStatus::kOk) return pr.fail(pr.probe.status, pr.probe.message);
  pr.build = build_station_core(plan, pr.probe, res.dev.device->capabilities().min_damping_Ns_per_m);
  pr.built = true;
  if (pr.build.status != PhaseStatus::kOk) return pr.fail(pr.build.status, pr.build.message);
  say_bounds(plan, pr.build, log);
  run_phase(plan, res, pr, stop, log);
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
  o.endpoint = res.ep.get();
  o.failure = pr.failure;
  o.failure_status = pr.failure_status;
  o.io_sched = res.io_sched;
  o.wall_time_s = wall_s;
  if (res.dev.device) {
    o.device_name = res.dev.device->capabilities().name;
    o.device_fault = drivers::fault_name(res.dev.device->fault());  // before stop(), which latches "not started"
    if (res.dev.device->fault() == drivers::DeviceFault::kNone) o.device_fault = "none";
  }
  if (res.ep) res.ep->stop();
  if (res.dev.device) res.dev.device->stop();
  if (res.telemetry) res.telemetry->flush();
  if (!pr.failure.empty()) log.error(pr.failure);
  const RunConditions c = run_conditions(o);
  const int code = exit_code(c);
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
            << pr.run.loop.overruns << " overruns, " << (pr.counters.diverged ? "DIVERGED" : "stable") << ", B_i "
            << (pr.built ? std::to_string(pr.build.bounds.damping_Ns_per_m) : std::string("none")) << " N s/m; exit " << code << "; wrote "
            << plan.base_path << ".json, -trace.csv, -state.csv\n";
  return code;
}

}  // namespace

std::string exit_code_help() {
  return "Exit codes (when several hold, the first in this list): 0 done; 2 configuration error (the key is named as written in the file); "
         "4 diverged; 5 safe state latched (loop exception or device fault); 6 passivity condition not met (B_i below eq. (18) on the measured "
         "round-trip bounds); 7 no neighbour (none answered probing, or none within its bound for more than station.max_no_neighbour_fraction "
         "of the run); 3 other run-time failure; 8 the run ended before the scripted release (e.g. --duration shorter than station.release_s). "
         "station-<id>.json names each condition under \"conditions\".";
}

int check_station_config(const StationFile& file, const RunOverrides& overrides, std::ostream& out, std::ostream& err) {
  const PlanResult pr = plan_station(file, overrides, read_clocks());
  if (pr.status != PhaseStatus::kOk) {
    err << "haptic-station run: error: " << pr.error << "\n";
    return kExitConfigError;
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
  const Log log{"haptic-station run [station " + std::to_string(f.station.id) + "]", o.quiet};
  const PlanResult plan = plan_station(f, o, read_clocks());
  if (plan.status != PhaseStatus::kOk) {
    log.error(plan.error);
    return kExitConfigError;
  }
  StationResources res;
  PhaseResults pr;
  run_phases(*plan.plan, res, pr, stop, log);
  return report_phase(*plan.plan, res, pr, std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(), log);
}

}  // namespace haptic::firmware
