// haptic-station: one station of the consensus-based P2P multi-user haptics runtime.
//   haptic-station sim --scenario NAME --out DIR [overrides]   deterministic N-station simulation
//   haptic-station run --config FILE.toml [--start-at S] [--out DIR] one real-time station process
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include "firmware/scenario.hpp"
#include "firmware/simulator.hpp"
#include "firmware/station_config.hpp"
#include "firmware/station_phase.hpp"
#include "firmware/station_run.hpp"

namespace fs = std::filesystem;
using namespace haptic::firmware;

namespace {

std::string tools_dir() {
  if (const char* e = std::getenv("HAPTIC_TOOLS_DIR")) return e;
  return HAPTIC_TOOLS_DIR;
}

// Runs the matplotlib figure script on a run directory; explains plainly when it cannot.
bool make_plots(const std::string& dir) {
  const std::string script = tools_dir() + "/plots/plot_run.py";
  if (!fs::exists(script)) {
    std::cerr << "haptic-station: no figures: " << script << " not found (set HAPTIC_TOOLS_DIR)\n";
    return false;
  }
  if (!fs::exists("/usr/bin/python3")) {
    std::cerr << "haptic-station: no figures: /usr/bin/python3 is missing (apt-get install python3-matplotlib)\n";
    return false;
  }
  const std::string cmd = "/usr/bin/python3 '" + script + "' '" + dir + "'";
  const int rc = std::system(cmd.c_str());
  if (rc != 0) {
    std::cerr << "haptic-station: figure script failed (exit " << rc << "): " << cmd << "\n";
    return false;
  }
  return true;
}

std::atomic<bool> g_stop{false};
void on_stop_signal(int) { g_stop.store(true, std::memory_order_release); }

std::string fmt(double v, int prec = 3) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "haptic-station: a station of the consensus-based peer-to-peer multi-user haptics runtime\n"
      "(Huang & Lee, IEEE T-RO 2013). Subcommands:\n"
      "  sim  run N stations in one process in simulated time over the paper's stochastic network\n"
      "  run  run one station in real time over real sockets (--config FILE.toml)"};
  app.require_subcommand(1);

  auto* sim = app.add_subcommand("sim", "Deterministic simulation of all stations (simulated users, impaired network)");
  std::string scenario, out, topology, damping, delay_matrix;
  double duration = -1, loss = -1, dup = -1, margin = -1, p_gain = -1, d_gain = -1;
  std::uint64_t seed = 1;
  int nodes = -1, trace_every = 1, allowance = -1, trace_node = -1;
  bool no_plots = false, quiet = false;
  std::string names;
  for (const auto& n : scenario_names()) names += (names.empty() ? "" : ", ") + n;
  sim->add_option("--scenario", scenario, "Scenario: " + names)->required();
  sim->add_option("--out", out, "Output directory (created): summary.json, trace.csv, series.csv, snapshots.json, *.png")->required();
  sim->add_option("--topology", topology, "Links overriding the scenario's, users from 1, e.g. 1-2,1-3,1-4");
  sim->add_option("--damping", damping, "Local damping B_i in N s/m, one per user, e.g. 14,5,4,5 (default: eq. (18) plus the margin)");
  sim->add_option("--duration", duration, "Simulated time in s (default: the scenario's: 20, 80 or 10)");
  sim->add_option("--seed", seed, "Seed of the network impairment (default 1)");
  sim->add_option("--delay-matrix", delay_matrix,
                  "Mean one-way delays in ms, row i receives from column j, rows separated by ';' "
                  "(default: the paper's 0,4,4,4;8,0,80,200;4,100,0,200;6,240,200,0)");
  sim->add_option("--loss", loss, "Packet loss probability per packet (default 0.05)");
  sim->add_option("--duplication", dup, "Packet duplication probability (default 0.01)");
  sim->add_option("--p-gain", p_gain, "Consensus stiffness scale p in P_ij = p[I/2 + K_int/(2 lambda_max)], N/m (default 1000)");
  sim->add_option("--d-gain", d_gain, "Consensus damping D_ij = d I, N s/m (default 5)");
  sim->add_option("--nodes", nodes, "Scene size: 33 is the paper's ball, other values a lattice ball of about that many nodes (default 33)");
  sim->add_option("--damping-margin", margin, "B_i = (1 + margin) x eq. (18) minimum (default 0.05)");
  sim->add_option("--loss-allowance", allowance, "Ticks added to ceil(max delay / T) for the bound Nbar_ij (default 1)");
  sim->add_option("--trace-every", trace_every, "Write every k-th tick to trace.csv and series.csv (default 1)");
  sim->add_option("--trace-node", trace_node, "Node (0-based) whose position trace.csv records (default: first node of user 2's contact mesh)");
  double push_end = -1, release = -1;
  sim->add_option("--push-end", push_end, "Push-hold-release script: end of the push in s (default: the scenario's, 3)");
  sim->add_option("--release", release, "Push-hold-release script: release time in s (default: the scenario's, 12 for paper-best)");
  sim->add_flag("--no-plots", no_plots, "Do not draw the PNG figures");
  sim->add_flag("--quiet", quiet, "No progress lines");

  auto* run = app.add_subcommand("run", "One station in real time: its device, its neighbours over UDP or raw Ethernet (see firmware/README.md)");
  std::string run_config, run_out;
  double run_start_at = -1, run_duration = -1;
  bool run_quiet = false, run_check = false;
  run->add_option("--config", run_config, "Station file (TOML): [station], [device], [net], [rt], [loop], [gpio], [telemetry]")->required();
  run->add_option("--start-at", run_start_at, "Common epoch of tick k = 0 in seconds on station.start_clock (default: station.start_at, else now + start_delay_s)");
  run->add_option("--out", run_out, "Output directory for station-<id>.json/-trace.csv/-state.csv (default: station.out_dir)");
  run->add_option("--duration", run_duration, "Run time in s after probing (default: station.duration_s, else the scenario's)");
  run->add_flag("--check-config", run_check,
                "Run every check `run` makes before it opens a socket (the plan phase), print a summary and exit: 0 valid, 2 configuration error");
  run->footer(exit_code_help());
  run->add_flag("--quiet", run_quiet, "Only the final line");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints help, or the usage error
    return rc == 0 ? 0 : kExitConfigError;
  }

  if (run->parsed()) {
    StationFile file;
    RunOverrides ov;
    ov.start_at = run_start_at;
    ov.out_dir = run_out;
    ov.duration_s = run_duration;
    ov.quiet = run_quiet;
    try {
      file = load_station_file(run_config);
    } catch (const std::exception& e) {
      std::cerr << "haptic-station run: error: " << e.what() << "\n";
      return kExitConfigError;
    }
    if (run_check) return check_station_config(file, ov, std::cout, std::cerr);
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    try {
      return run_station(file, ov, g_stop);
    } catch (const std::exception& e) {  // the phases report their own failures; this is a bug's last resort
      std::cerr << "haptic-station run: error: " << e.what() << "\n";
      return kExitRunFailed;
    }
  }
  if (sim->parsed()) {
    try {
      ScenarioSpec spec = make_scenario(scenario);
      if (!delay_matrix.empty()) spec.delay_ms = parse_delay_matrix(delay_matrix, spec.users);
      if (!topology.empty()) spec.topology = parse_topology(topology, spec.users);
      if (!damping.empty()) spec.damping_Ns_per_m = parse_list(damping, "--damping");
      if (push_end >= 0) spec.script.push_end_s = push_end;
      if (release >= 0) spec.script.release_s = release;
      if (duration >= 0) {
        if (spec.script.kind == UserScriptSpec::Kind::kPushHoldRelease && duration <= spec.script.release_s)
          std::cerr << "haptic-station: note: --duration " << duration << " s ends before the release at " << spec.script.release_s << " s\n";
        spec.duration_s = duration;
      }
      spec.seed = seed;
      if (loss >= 0) spec.loss_probability = loss;
      if (dup >= 0) spec.duplicate_probability = dup;
      if (nodes > 0) spec.scene_nodes = nodes;
      if (p_gain >= 0) spec.p_gain_N_per_m = p_gain;
      if (d_gain >= 0) spec.d_gain_Ns_per_m = d_gain;
      if (margin >= 0) spec.damping_margin = margin;
      if (allowance >= 0) spec.loss_allowance_ticks = allowance;
      spec.trace_node = trace_node;
      const BuiltScenario built = build_scenario(spec);
      fs::create_directories(out);
      SimOptions opt;
      opt.out_dir = out;
      opt.trace_every = trace_every;
      opt.progress = !quiet;
      const auto& sc = spec.script;
      if (sc.kind == UserScriptSpec::Kind::kPushHoldRelease)
        opt.snapshot_times_s = {0.0, sc.push_end_s, 0.5 * (sc.push_end_s + sc.release_s), sc.release_s, spec.duration_s};
      else
        opt.snapshot_times_s = {0.0, sc.perturb_at_s + sc.perturb_duration_s, spec.duration_s};
      if (!quiet) {
        std::cerr << "haptic-station sim: scenario " << spec.name << ", " << spec.users << " users, " << built.scene.nodes
                  << " nodes, " << spec.duration_s << " s, seed " << spec.seed << "\n  B_i used (N s/m):";
        for (double b : built.damping) std::cerr << " " << fmt(b, 2);
        std::cerr << "\n  eq. (18) minimum:";
        for (double b : built.damping_min) std::cerr << " " << fmt(b, 2);
        std::cerr << (built.passivity_condition_met ? "  (met)\n" : "  (VIOLATED)\n");
      }
      const SimResult r = run_simulation(built, opt);
      write_summary_json(out + "/summary.json", built, r);
      std::cout << "scenario " << spec.name << ": " << (r.diverged ? "DIVERGED at " + fmt(r.diverged_at_s, 2) + " s" : "stable")
                << ", consensus error at end " << fmt(r.consensus_error_m * 1e3, 4) << " mm"
                << ", consensus time after release " << (r.consensus_time_s ? fmt(*r.consensus_time_s, 2) + " s" : std::string("never"))
                << ", hold |sum u| " << fmt(r.hold_force_sum_N, 4) << " N vs mean |u_i| " << fmt(r.hold_force_mean_N, 4) << " N"
                << ", min port energy " << fmt(r.port_energy_min_J, 6) << " J (bound -" << fmt(r.passivity_bound_J, 6) << " J)\n";
      std::cout << "wrote " << out << "/summary.json, trace.csv, series.csv\n";
      if (!no_plots && make_plots(out)) std::cout << "wrote " << out << "/*.png\n";
      return 0;
    } catch (const std::exception& e) {
      std::cerr << "haptic-station sim: error: " << e.what() << "\n";
      return 2;
    }
  }
  return 0;
}
