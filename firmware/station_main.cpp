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
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "firmware/session/log_command.hpp"
#include "firmware/run/merge.hpp"
#include "firmware/run/summary.hpp"
#include "firmware/scenario.hpp"
#include "firmware/session/replay.hpp"
#include "firmware/sim/simulator.hpp"
#include "firmware/view/timeline.hpp"
#include "firmware/station/config.hpp"
#include "firmware/station/option_cli.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/run.hpp"
#include "platform/command_line.hpp"
#include "platform/install_paths.hpp"

namespace fs = std::filesystem;
using namespace haptic::firmware;

namespace {

// Numbers >= 0, > 0 and unsigned integers (platform/command_line.hpp). The `sim` options whose -1
// default means "the scenario's" check them, so that a negative value is an error naming the
// option, never silently the default.
using haptic::platform::kNonNegative;
using haptic::platform::kNonNegativeInteger;
using haptic::platform::kPositive;

// The figure script (tools/plots/plot_run.py --after-go --expect SNAPSHOTS USERS DIR), started
// before the simulation: it imports matplotlib, warms up and makes the figures' empty axes while the
// run goes, and draws DIR's figures once told that the run's files are written. Explains plainly
// when it cannot run. Not RT-safe.
class FigureDrawer {
 public:
  FigureDrawer(const std::string& dir, std::size_t snapshots, int users) {
    const std::string script = haptic::platform::tools_dir() + "/plots/plot_run.py";
    if (!fs::exists(script)) {
      std::cerr << "haptic-station: no figures: " << script
                << " not found (looked next to this executable's ../share/haptic/tools; set HAPTIC_TOOLS_DIR)\n";
      return;
    }
    if (!fs::exists(kPython)) {
      std::cerr << "haptic-station: no figures: " << kPython << " is missing (apt-get install python3-matplotlib)\n";
      return;
    }
    std::vector<std::string> args{kPython, script, "--after-go", "--expect", std::to_string(snapshots), std::to_string(users), dir};
    for (const auto& x : args) command_ += (command_.empty() ? "" : " ") + x;
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) return;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[0], STDIN_FILENO);  // dup2 clears close-on-exec on stdin
    std::vector<char*> argv;
    for (auto& x : args) argv.push_back(x.data());
    argv.push_back(nullptr);
    std::fflush(nullptr);
    const int rc = posix_spawn(&pid_, kPython, &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fds[0]);
    if (rc != 0) {
      close(fds[1]);
      pid_ = -1;
      std::cerr << "haptic-station: no figures: could not start " << command_ << "\n";
      return;
    }
    go_fd_ = fds[1];
  }
  FigureDrawer(const FigureDrawer&) = delete;
  FigureDrawer& operator=(const FigureDrawer&) = delete;
  // Not told to draw (the run failed): stopped at once, nothing drawn.
  ~FigureDrawer() {
    if (pid_ <= 0) return;
    close(go_fd_);
    kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
  }
  // Tells the script to draw and waits for it: true when it drew.
  bool draw() {
    if (pid_ <= 0) return false;
    const auto previous = std::signal(SIGPIPE, SIG_IGN);  // a script that already ended: a failed write, not our end
    const bool told = write(go_fd_, "go\n", 3) == 3;
    std::signal(SIGPIPE, previous);
    close(go_fd_);
    int status = 0;
    const bool waited = waitpid(pid_, &status, 0) == pid_;
    pid_ = -1;
    if (told && waited && WIFEXITED(status) && WEXITSTATUS(status) == 0) return true;
    std::cerr << "haptic-station: figure script failed (" << (!told ? "it ended before the run did" : "exit " + std::to_string(WEXITSTATUS(status)))
              << "): " << command_ << "\n";
    return false;
  }

 private:
  static constexpr const char* kPython = "/usr/bin/python3";
  std::string command_;
  pid_t pid_ = -1;
  int go_fd_ = -1;
};

std::atomic<bool> g_stop{false};
void on_stop_signal(int) { g_stop.store(true, std::memory_order_release); }
// Ctrl-C and SIGTERM set g_stop: a run or a served view (replay, sim) ends cleanly and reports.
void stop_on_signals() {
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
}

std::string fmt(double v, int prec = 3) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

std::string opt_fmt(const std::optional<double>& v, double scale, int prec, const std::string& unit, const std::string& none) {
  return v ? fmt(*v * scale, prec) + unit : none;
}

// The one-line result of `sim`. Not RT-safe.
std::string sim_result_line(const std::string& name, const SimResult& r) {
  const RunMetricsResult& m = r.metrics;
  const std::string growth = m.growth_detected_at_s ? ", GROWING consensus error from " + fmt(*m.growth_detected_at_s, 2) + " s (x" +
                                                          fmt(std::exp(m.growth_rate_per_s.value_or(0)), 2) + " per s)" : std::string();
  const GateSummary g = sim_gate_summary(r);
  const std::string gate = gate_clause(g);
  return "scenario " + name + ": " + (m.diverged ? "DIVERGED at " + fmt(m.diverged_at_s.value_or(0), 2) + " s" : verdict_words(sim_verdict(r))) +
         (gate.empty() ? "" : " (" + gate + ")") + growth +
         ", consensus error at end " + opt_fmt(m.consensus_error_m, 1e3, 4, " mm", "n/a") + ", consensus time after release " +
         opt_fmt(m.consensus_time_s, 1, 2, " s", "never") + " (< 1 mm), " + opt_fmt(m.consensus_time_10pct_s, 1, 2, " s", "never") + " (10 %), " +
         opt_fmt(m.consensus_time_1pct_s, 1, 2, " s", "never") + " (1 %) of the error at release " +
         opt_fmt(m.consensus_error_at_release_m, 1e3, 3, " mm", "n/a") + ", hold |sum u| " + opt_fmt(m.hold_force_sum_N, 1, 4, " N", "n/a") +
         " vs mean |u_i| " + opt_fmt(m.hold_force_mean_N, 1, 4, " N", "n/a") + ", min port energy " + opt_fmt(m.port_energy_min_J, 1, 6, " J", "n/a") +
         " (bound -" + fmt(r.passivity_bound_J, 6) + " J)";
}

struct SimArgs {
  std::string scenario, out, topology, damping, delay_matrix, topology_file, pushes = "spread", script, receive_rule = "newest",
              consensus_passivity = "eq18";
  double pspm_reservoir_J = 0.0;
  int resilient_f = 0;
  double state_check_kinematic_m = 0, state_check_disagreement_m = 0, edge_energy_hold_s = 0;  // off (0) in the simulator
  double timer_jitter_ms = 0, step_jitter = 0, clock_drift_ppm = 0;  // station clocks (variable steps T_k)
  double jitter = -1, delay_correlation = 0, node_mass_kg = -1;     // delay model and object (stability maps)
  double burst_enter = 0, burst_length = 5, burst_loss = 1;         // Gilbert-Elliott burst loss (off at 0)
  std::string delay_trace;                                          // recorded one-way delays (ms per line)
  std::optional<int> users;  // unset: the scenario's (or --topology-file's) user count
  std::uint64_t push_seed = 1;
  double duration = -1, loss = -1, dup = -1, margin = -1, p_gain = -1, d_gain = -1, push_end = -1, release = -1;
  std::uint64_t seed = 1;
  int nodes = -1, allowance = -1, trace_node = -1, tx_interval = 1;
  std::optional<int> trace_every;  // unset: trace.csv at default_trace_every(users), series.csv every tick
  double tx_deadband_mm = 0, edge_energy_bound = -1, edge_energy_leak = -1, drop_fade = 0;
  std::string scene;                          // --scene FILE
  std::string solver = "auto";                // --solver
  double scene_unit_m = 1, density = 0, youngs = 0;
  bool no_plots = false, quiet = false, record = false, tx_predict = false;
  double record_ring_s = 0;
  int record_deflate = 0;
  double record_max_mb = 0;
  std::string command_line;
  int view_port = 0, view_station = 1;
  std::string view_bind = "127.0.0.1";
  double view_for = 0;
};

struct ReplayArgs {
  std::string log, trace, state_json;
  double damping = -1, p_scale = 1, d_scale = 1;
  std::int64_t from = -1, to = -1;
  int view_port = 0;
  std::string view_bind = "127.0.0.1";
  double view_for = 0;
};

// --view-port, --view-bind, --view-for of `sim` and `replay`. Not RT-safe.
void add_view_options(CLI::App* app, int& port, std::string& bind, double& seconds) {
  app->add_option("--view-port", port, "Serve the web view with a timeline on this port after the run (HTTP + WebSocket; 0 = none); it draws every "
                  "user's proxy from the station-<j>.h5 logs of the same run next to it; page options ?exaggerate=E&seek=N&pause=1")
      ->check(CLI::Range(0, 65535));
  app->add_option("--view-bind", bind, "Interface the view listens on (default 127.0.0.1: this machine only)");
  app->add_option("--view-for", seconds, "Stop serving the view after this many seconds (default 0: until Ctrl-C)")->check(kNonNegative);
}

struct RunArgs {
  std::vector<std::pair<std::string, std::string>> sets;  // --SECTION.KEY VALUE overrides of the station file
  std::string config, out;
  double start_at = -1, duration = -1;
  bool quiet = false, check = false, probe_only = false;
};

// --scene and its material options (firmware/scene, rt::Material). Not RT-safe.
void add_scene_options(CLI::App& sim, SimArgs& a, CLI::Option* nodes) {
  const haptic::rt::Material paper = haptic::rt::paper_ball_material();
  auto* scene = sim.add_option("--scene", a.scene,
                               "Scene from a mesh file instead of the ball: Gmsh .msh (ASCII 2.2 or 4.1), TetGen .node/.ele, legacy VTK .vtk "
                               "(ASCII unstructured grid), or a closed surface .obj/.stl/.off tetrahedralized by TetGen")
                    ->excludes(nodes)
                    ->check(CLI::ExistingFile);
  sim.add_option("--scene-unit-m", a.scene_unit_m, "Metres per unit of the --scene file's coordinates (default 1; 0.001 for a file in mm)")->needs(scene)->check(CLI::PositiveNumber);
  sim.add_option("--density", a.density, "Density of the --scene object in kg/m^3 (default " + fmt(paper.density_kg_per_m3, 1) +
                                             ": the paper ball's 1.32 kg in its volume)")->needs(scene)->check(CLI::PositiveNumber);
  sim.add_option("--youngs", a.youngs, "Young's modulus of the --scene object in Pa (default " + fmt(paper.youngs_modulus_Pa, 1) +
                                           ": the paper ball's mean edge spring 100 N/m)")->needs(scene)->check(CLI::PositiveNumber);
}

// The `sim` options of the script times (--push-end, --release) and of what a run writes (traces, figures,
// live view, session logs) into `a`. Not RT-safe.
void add_sim_output_options(CLI::App* sim, SimArgs& a) {
  sim->add_option("--trace-every", a.trace_every, "Write every k-th tick to trace.csv and series.csv (default: series.csv every tick, trace.csv "
                                                  "every ceil(N/8)-th tick for N users: every tick up to 8 users, every 8th at 64)")
      ->check(kPositive);
  sim->add_option("--trace-node", a.trace_node, "Node (0-based) whose position trace.csv records (default: first node of user 2's contact mesh)")
      ->check(kNonNegative);
  sim->add_option("--push-end", a.push_end, "Push-hold-release script: end of the push in s (default: the scenario's, 3)")->check(kNonNegative);
  sim->add_option("--release", a.release, "Push-hold-release script: release time in s (default: the scenario's, 12 for paper-best)")
      ->check(kNonNegative);
  sim->add_flag("--no-plots", a.no_plots, "Do not draw the PNG figures");
  add_view_options(sim, a.view_port, a.view_bind, a.view_for);
  sim->add_option("--view-station", a.view_station, "Station (1-based) the view shows (default 1; needs --record)")->check(CLI::Range(1, 64));
  sim->add_flag("--record", a.record, "Write each station's session log OUT/station-<i>.h5 (HDF5; `haptic-station replay` re-runs it bit-exactly)");
  sim->add_option("--record-deflate", a.record_deflate, "With --record: HDF5 shuffle + deflate of the packet values at this level (1-9; 0 none, the "
                                                        "default; as station.record_deflate; lossless, the replay stays bit-exact)")
      ->check(CLI::Range(0, 9));
  sim->add_option("--record-max-mb", a.record_max_mb, "With --record: each log stops growing at this many MB of rows and says at which tick "
                                                      "(truncated_at_tick; replay re-runs up to there); as station.record_max_mb (default 0: unbounded)")
      ->check(CLI::Range(0.0, 1e6));
  sim->add_option("--record-ring-s", a.record_ring_s, "With --record: keep only the last S seconds in each log (a ring of bounded size; for inspection, not replay)")
      ->check(CLI::Range(0.0, 86400.0));
  sim->add_flag("--quiet", a.quiet, "No progress lines");
}

// The consensus law's options of `sim` (how eq. 14 is kept, the resilient rule) into `a`. Not RT-safe.
void add_sim_consensus_options(CLI::App* sim, SimArgs& a) {
  sim->add_option("--consensus-passivity", a.consensus_passivity,
                  "How eq. (14) is kept: eq18 (the paper: damping B_i from eq. 18 over the delay bound Nbar) or pspm (passive "
                  "set-position modulation per edge: B_i = 0 unless --damping, no delay bound; rt/set_position_modulation.hpp) "
                  "(default eq18)");
  sim->add_option("--pspm-reservoir-J", a.pspm_reservoir_J, "With --consensus-passivity pspm: each edge's initial energy reservoir, J (default 0)");
  sim->add_option("--resilient-f", a.resilient_f,
                  "Resilient consensus: each station leaves out, every tick, the F neighbours whose received object is farthest from "
                  "its copy (rt/resilient.hpp; W-MSR needs a (2F+1)-robust topology: haptic-topology --robustness) (default 0: off)");
  sim->add_option("--state-check-kinematic-m", a.state_check_kinematic_m,
                  "Neighbour state check (rt/edge_monitor.hpp): isolate a neighbour whose reported positions moved this much more than its "
                  "reported velocities explain, m (the station's station.state_check_kinematic_m, default 2e-4 there) (default 0: off)")
      ->check(CLI::Range(0.0, 1.0));
  sim->add_option("--state-check-disagreement-m", a.state_check_disagreement_m,
                  "Neighbour state check: isolate a neighbour whose state, filtered over 0.2 s, stays this far from the copy, m (default 0: off)")
      ->check(CLI::Range(0.0, 1.0));
  sim->add_option("--edge-energy-hold-s", a.edge_energy_hold_s,
                  "The energy gate releases a tripped edge after holding it this long, doubled per further trip, forgiving its account's "
                  "excess over the release level (the station's station.edge_energy_hold_s, default 2 there) (default 0: off)")
      ->check(CLI::Range(0.0, 3600.0));
}

// The safeguards' options of `sim` (the state check, the gate's timed release) into the spec.
void apply_sim_safeguards(const SimArgs& a, haptic::firmware::ScenarioSpec& spec) {
  if (a.state_check_kinematic_m > 0) spec.state_check.kinematic_bound_m = a.state_check_kinematic_m;
  if (a.state_check_disagreement_m > 0) spec.state_check.disagreement_bound_m = a.state_check_disagreement_m;
  spec.edge_energy_hold_s = a.edge_energy_hold_s;
}

// The `sim` subcommand's options into `a`. Not RT-safe.
// The delay and loss model beyond the paper's (stability maps): jitter, correlation, burst loss.
void add_sim_network_options(CLI::App* sim, SimArgs& a) {
  sim->add_option("--jitter", a.jitter, "Delay jitter: each delay in mean x [1 - this, 1 + this], in [0, 1] (default 0.5, the paper's)")
      ->check(CLI::Range(0.0, 1.0));
  sim->add_option("--delay-correlation", a.delay_correlation,
                  "Time-correlated delays: AR(1) coefficient per packet of a latent Gaussian mapped onto the same uniform support "
                  "(net::LinkImpairment), in [0, 1); 0 = i.i.d. (default 0)");
  sim->add_option("--delay-trace", a.delay_trace,
                  "Recorded one-way delays, one per line in ms ('#' comments), replayed by every link in place of the uniform draw "
                  "(Nbar from the trace's smallest and largest delay)")
      ->check(CLI::ExistingFile);
  sim->add_option("--burst-enter", a.burst_enter,
                  "Gilbert-Elliott burst loss on every link: probability per packet of entering a burst, in [0, 1]; the loss "
                  "allowance then comes from the burst model (default 0: off)")
      ->check(CLI::Range(0.0, 1.0));
  sim->add_option("--burst-length", a.burst_length, "Mean burst length in packets, >= 1 (default 5)")->check(CLI::Range(1.0, 1e6));
  sim->add_option("--burst-loss", a.burst_loss, "Loss probability inside a burst, in [0, 1] (default 1)")->check(CLI::Range(0.0, 1.0));
}

CLI::App* add_sim_options(CLI::App& app, SimArgs& a) {
  auto* sim = app.add_subcommand("sim", "Deterministic simulation of all stations (simulated users, impaired network)");
  std::string names;
  for (const auto& n : scenario_names()) names += (names.empty() ? "" : ", ") + n;
  sim->add_option("--scenario", a.scenario, "Scenario: " + names)->required();
  sim->add_option("--out", a.out, "Output directory (created): summary.json, trace.csv, series.csv, snapshots.json, *.png")->required();
  sim->add_option("--users", a.users,
                  "Number of users 2..64 (default: the scenario's 4; other N: uniform 10 ms delays and a tree of degree <= 4 "
                  "unless --topology-file, --topology or --delay-matrix say otherwise)");
  sim->add_option("--topology-file", a.topology_file,
                  "haptic-topology --json output: its users, mean delays and best graph (eq. 27) replace the scenario's");
  sim->add_option("--pushes", a.pushes,
                  "spread: push directions summing to zero by construction; asymmetric: each tilted by up to 30 deg and its depth "
                  "scaled in [0.5, 1.5] (seeded by --push-seed), so hold-force balance is measured (default spread)");
  sim->add_option("--push-seed", a.push_seed, "Seed of the asymmetric pushes and of --script random (default 1)")->check(kNonNegativeInteger);
  sim->add_option("--script", a.script,
                  "Users' script: push-hold-release, random (every hand wanders through seeded keyframes all run: the object never "
                  "rests) or hold (default: the scenario's)")
      ->check(CLI::IsMember({"push-hold-release", "random", "hold"}));
  sim->add_option("--topology", a.topology, "Links overriding the scenario's, users from 1, e.g. 1-2,1-3,1-4");
  sim->add_option("--damping", a.damping, "Local damping B_i in N s/m, one per user, e.g. 14,5,4,5 (default: eq. (18) plus the margin)");
  sim->add_option("--duration", a.duration, "Simulated time in s (default: the scenario's: 20, 80 or 10)")->check(kPositive);
  sim->add_option("--seed", a.seed, "Seed of the network impairment (default 1)")->check(kNonNegativeInteger);
  sim->add_option("--delay-matrix", a.delay_matrix,
                  "Mean one-way delays in ms, row i receives from column j, rows separated by ';' "
                  "(default: the paper's 0,4,4,4;8,0,80,200;4,100,0,200;6,240,200,0)");
  sim->add_option("--loss", a.loss, "Packet loss probability per packet (default 0.05)")->check(CLI::Range(0.0, 1.0));
  sim->add_option("--duplication", a.dup, "Packet duplication probability (default 0.01)")->check(CLI::Range(0.0, 1.0));
  sim->add_option("--p-gain", a.p_gain, "Consensus stiffness scale p in P_ij = p[I/2 + K_int/(2 lambda_max)], N/m (default 1000)")
      ->check(kNonNegative);
  sim->add_option("--d-gain", a.d_gain, "Consensus damping D_ij = d I, N s/m (default 5)")->check(kNonNegative);
  auto* nodes = sim->add_option("--nodes", a.nodes, "Scene size: 33 is the paper's ball, other values a lattice ball of about that many nodes (default 33)")
                    ->check(CLI::Range(7, 20000));
  add_scene_options(*sim, a, nodes);
  sim->add_option("--solver", a.solver, "Linear step solver (rt/README.md \"Solver by size\"; station.solver): auto (the direct sparse LDL^T below 600 "
                                        "factor rows: nodes, or 3 per node when a matrix is not isotropic; Jacobi-preconditioned CG above), "
                                        "direct or iterative (default auto)")
      ->check(CLI::IsMember({"auto", "direct", "iterative"}));
  sim->add_option("--damping-margin", a.margin, "B_i = (1 + margin) x eq. (18) minimum (default 0.05)")->check(CLI::Range(0.0, 10.0));
  sim->add_option("--loss-allowance", a.allowance, "Ticks added to ceil(max delay / T) for the bound Nbar_ij (default: from the loss model, the smallest L with run ticks x directed links x "
                  "P(L+1 packets in a row lost) <= 0.01: loss^(L+1), or from the burst chain with --burst-enter)")
      ->check(CLI::Range(0, 1000));
  auto* band = sim->add_option("--tx-deadband-mm", a.tx_deadband_mm,
                               "Send a state only when some node moved more than this since the last one sent, in mm (default 0: every tick)");
  sim->add_option("--tx-max-interval", a.tx_interval,
                  "With --tx-deadband-mm: a state at least every this many ticks; Nbar_ij grows by (L + 1)(this - 1), L the loss allowance (default 1)")
      ->needs(band);
  sim->add_flag("--tx-predict", a.tx_predict,
                "With --tx-deadband-mm and --consensus-passivity pspm: predictive deadband, the band applies to the error against the last "
                "sent state extrapolated by its velocity, and receivers extrapolate a held state the same way (rt/tx_deadband.hpp); "
                "without --tx-deadband-mm every state is sent and receivers extrapolate only the states held for lost packets");
  sim->add_option("--edge-energy-bound", a.edge_energy_bound,
                  "Per-edge damage bound in J: an edge whose energy account (eq. 14 split per edge) exceeds it acts as a damper "
                  "until the account has fallen to half of it; 0 = off (default " + std::to_string(haptic::rt::kDefaultEdgeEnergyBoundJ) + ")")
      ->check(kNonNegative);
  sim->add_option("--edge-energy-leak-W", a.edge_energy_leak,
                  "Energy that left a station's copy (to its user, its object's damping) is taken off each edge's energy account up "
                  "to this power, W, so a station that only receives does not fill its accounts; 0 = no leak (default " +
                      std::to_string(haptic::rt::kDefaultEdgeEnergyLeakW) + ")")
      ->check(kNonNegative);
  sim->add_option("--drop-fade-s", a.drop_fade,
                  "An edge whose data ages out (over its delay bound) holds the last state it used and fades its stiffness to 0 over "
                  "this long instead of dropping at once (rt/drop_fade.hpp; isolated or gated edges drop at once); 0 = the paper's "
                  "immediate drop (default 0)")
      ->check(kNonNegative);
  sim->add_option("--receive-rule", a.receive_rule,
                  "Which packet a tick uses: newest (by sequence number) or paper (the most recently received, Fig. 4; late data used) (default newest)");
  sim->add_option("--node-mass-kg", a.node_mass_kg, "Mass of each of the ball's nodes in kg (default: the paper ball's 0.04)")->check(kPositive);
  sim->add_option("--timer-jitter-ms", a.timer_jitter_ms,
                  "Each station's wake is late by a uniform draw in [0, this] ms after its grid time; the core integrates each tick over "
                  "the wake-to-wake step T_k (rt/README.md, Variable steps), in [0, T/2) (default 0)");
  sim->add_option("--step-jitter", a.step_jitter,
                  "Free-running loops: each station's grid interval is T (1 + F u), u uniform in [-1, 1], F = this in [0, 0.5] (default 0)");
  sim->add_option("--clock-drift-ppm", a.clock_drift_ppm,
                  "Clock drift: station i ticks every T (1 + c_i 1e-6), c_i spread evenly over [-this, +this] ppm (user 1 shortest), in [0, 10000]; its tick count drifts against the others (default 0)");
  add_sim_consensus_options(sim, a);
  add_sim_output_options(sim, a);
  add_sim_network_options(sim, a);
  return sim;
}

// The `run` subcommand's options into `a`. Not RT-safe.
CLI::App* add_run_options(CLI::App& app, RunArgs& a) {
  auto* run = app.add_subcommand("run", "One station in real time: its device, its neighbours over UDP or raw Ethernet (see firmware/README.md)");
  run->add_option("--config", a.config, "Station file (TOML): [station], [device], [net], [rt], [loop], [gpio], [telemetry]")->required();
  run->add_option("--start-at", a.start_at, "Common epoch of tick k = 0 in seconds on station.start_clock (default: station.start_at, else now + start_delay_s)")
      ->check(kNonNegative);
  run->add_option("--out", a.out, "Output directory for station-<id>.json/-trace.csv/-state.csv (default: station.out_dir)");
  run->add_option("--duration", a.duration, "Run time in s after probing (default: station.duration_s, else the scenario's)")->check(kPositive);
  run->add_flag("--check-config", a.check,
                "Run every check `run` makes before it opens a socket (the plan phase), print a summary and exit: 0 valid, 2 configuration error, 9 device missing (device.kind = \"auto\" with no device here)");
  run->add_flag("--probe-only", a.probe_only,
                "Plan, open the device and endpoint, probe the neighbours (round trips, loss, clock offsets, fingerprints) at the common "
                "epoch, write station-<id>.json and stop before coupling: 0 every neighbour answered and matches, 7 none answered, 3 otherwise "
                "(start every station of the lab with the same --start-at; `haptic-lab check --probe` does)");
  run->footer(exit_code_help());
  run->add_flag("--quiet", a.quiet, "Only the final line");
  add_option_overrides(run, all_option_decls(), a.sets);
  return run;
}

// The `replay` subcommand's options into `a`. Not RT-safe.
CLI::App* add_replay_options(CLI::App& app, ReplayArgs& a) {
  auto* rp = app.add_subcommand("replay", "Re-run a station's core from its session log (sim --record, [record] enabled) and compare every tick's state hash");
  rp->add_option("log", a.log, "Session log (station-<id>.h5)")->required()->check(CLI::ExistingFile);
  rp->add_option("--damping", a.damping, "Re-run with this B_i in N s/m instead of the recorded one (no bit-exact comparison; open loop: the neighbours' "
                                         "recorded states are replayed as they were, they do not react to the change)")
      ->check(CLI::Range(0.0, 1e6));
  rp->add_option("--p-scale", a.p_scale, "Re-run with P_ij scaled by this factor (default 1)");
  rp->add_option("--d-scale", a.d_scale, "Re-run with D_ij scaled by this factor (default 1)");
  rp->add_option("--from", a.from, "Step through: print one line per tick from this run index on (device sample, force, VP, energies, flags, "
                                   "replayed and recorded state hash)")->check(kNonNegative);
  rp->add_option("--to", a.to, "Stop after this run index (the comparison and --trace end there; with --from, the last tick printed)")
      ->check(kNonNegative);
  rp->add_option("--state-json", a.state_json, "Write the core's full state after the last tick replayed (--to) to this JSON file: x, v, VP, energies, links");
  add_view_options(rp, a.view_port, a.view_bind, a.view_for);
  rp->add_option("--trace", a.trace, "Write the replayed ticks to this CSV (force, VP, energies, the recorded force, hash match)");
  rp->footer("Exit status: 0 bit-exact at every tick (or, with changed gains, re-run done); 3 a tick's state differs from the recording, "
             "or the log's inputs are incomplete (dropped records, size bound) before the last tick replayed, or it is a ring log that wrapped; 2 not a session log or bad options.");
  return rp;
}

TimelineOptions timeline_options(int port, const std::string& bind, double seconds, const std::string& mode) {
  TimelineOptions t;
  t.server.port = port;
  t.server.bind = bind;
  t.serve_s = seconds;
  t.mode = mode;
  return t;
}

// `haptic-station replay`: 0 bit-exact / re-run done, 3 differs or incomplete, 2 bad log. Not RT-safe.
int replay_command(const ReplayArgs& a) {
  ReplayOptions o;
  o.damping_Ns_per_m = a.damping;
  o.p_scale = a.p_scale;
  o.d_scale = a.d_scale;
  o.trace_csv = a.trace;
  o.from_tick = a.from;
  o.to_tick = a.to;
  o.state_json = a.state_json;
  if (!(o.p_scale > 0) || !(o.d_scale >= 0)) {
    std::cerr << "haptic-station replay: error: --p-scale must be > 0 and --d-scale >= 0\n";
    return kExitConfigError;
  }
  if (a.from >= 0 && a.to >= 0 && a.to < a.from) {
    std::cerr << "haptic-station replay: error: --to " << a.to << " is before --from " << a.from << "\n";
    return kExitConfigError;
  }
  if (a.view_port > 0) stop_on_signals();  // the served timeline ends and says what the page showed
  try {
    const ReplayResult r = a.view_port > 0 ? serve_timeline(a.log, o, timeline_options(a.view_port, a.view_bind, a.view_for, "replay"), g_stop)
                                           : replay_session(a.log, o);
    std::cout << r.summary() << "\n";
    if (r.gains_changed) return r.ticks > 0 ? 0 : kExitRunFailed;
    return r.bit_exact() && r.inputs_complete() ? 0 : kExitRunFailed;
  } catch (const NotReplayable& e) {
    std::cerr << "haptic-station replay: " << a.log << ": cannot replay " << e.what() << "\n";
    return kExitRunFailed;
  } catch (const std::exception& e) {
    std::cerr << "haptic-station replay: error: " << a.log << ": " << e.what() << "\n";
    return kExitConfigError;
  }
}

// run and solo: the station's phases, with SIGINT/SIGTERM ending the run; the phases report their own
// failures, an exception here is a bug's last resort.
int run_station_guarded(const StationFile& file, const RunOverrides& ov, const char* command) {
  stop_on_signals();
  try {
    return run_station(file, ov, g_stop);
  } catch (const std::exception& e) {
    std::cerr << "haptic-station " << command << ": error: " << e.what() << "\n";
    return kExitRunFailed;
  }
}

// `haptic-station run`: returns the exit code (firmware/station/phase.hpp). Not RT-safe.
int run_command(const RunArgs& a) {
  StationFile file;
  RunOverrides ov;
  ov.start_at = a.start_at;
  ov.out_dir = a.out;
  ov.duration_s = a.duration;
  ov.quiet = a.quiet;
  ov.probe_only = a.probe_only;
  try {
    file = load_station_file(a.config, a.sets);
  } catch (const std::exception& e) {
    std::cerr << "haptic-station run: error: " << e.what() << "\n";
    return kExitConfigError;
  }
  if (a.check) return check_station_config(file, ov, std::cout, std::cerr);
  return run_station_guarded(file, ov, "run");
}

// `haptic-station solo`'s options: each a key of the station file (an override of --config's), so the
// station's own parser checks it; its errors name the option as the user wrote it.
struct SoloArgs {
  std::string config, out, device, scene, script;
  int view_port = 0, nodes = 0;
  double duration = -1;
  double anchor = -1;
  bool quiet = false;
};

constexpr double kSoloDefaultDurationS = 60;
constexpr double kSoloDefaultAnchorNPerM = 2.0;

CLI::App* add_solo_options(CLI::App& app, SoloArgs& a) {
  auto* solo = app.add_subcommand("solo", "One station, one user, no network: touch the object with your device (or the simulated one), "
                                          "with the live view; the first thing a new lab runs (see firmware/README.md)");
  solo->add_option("--device", a.device, "simulated (a simulated user touches the object by itself: the random script), touch, falcon or auto "
                                         "(default: --config's device.kind, else simulated)")
      ->check(CLI::IsMember({"simulated", "touch", "falcon", "auto"}));
  solo->add_option("--config", a.config, "Station file (TOML) for its [device], [scene], [station] (nodes, out_dir, damping_margin, ...), [rt], [loop] "
                                         "keys; its [net] is not used (only its key names are checked), nor station.id, users, topology")
      ->check(CLI::ExistingFile);
  solo->add_option("--view-port", a.view_port, "Serve the live web view on http://127.0.0.1:P/ (default: --config's station.view_port, else none)")
      ->check(CLI::Range(1, 65535));
  solo->add_option("--duration", a.duration, "Run time in s (default: --config's station.duration_s, else " + fmt(kSoloDefaultDurationS, 0) +
                                                 "); Ctrl-C or SIGTERM ends it sooner, with the same report")
      ->check(CLI::Range(1e-3, 3600.0));
  auto* nodes = solo->add_option("--nodes", a.nodes, "Scene size (station.nodes: 33 = the paper's ball, else a lattice ball)");
  solo->add_option("--scene", a.scene, "Scene from a mesh file (scene.file: .msh, .node/.ele, .vtk, .obj/.stl/.off)")
      ->excludes(nodes)
      ->check(CLI::ExistingFile);
  solo->add_option("--script", a.script, "The simulated user's script (station.script; default: --config's, else random: the hand wanders "
                                         "around the contact point and leans in, all run)")
      ->check(CLI::IsMember({"random", "push-hold-release", "hold"}));
  solo->add_option("--anchor", a.anchor, "Ground spring on every node, N/m (the scene's K_gnd): alone, one hand would push the paper's floating "
                                         "object away; 0 = floating (default " + fmt(kSoloDefaultAnchorNPerM, 1) + ")")
      ->check(CLI::Range(0.0, 1e4));
  solo->add_option("--out", a.out, "Output directory for station-1.json/-trace.csv/-state.csv (default: --config's station.out_dir, else .)");
  solo->add_flag("--quiet", a.quiet, "Only the view's address and the final line");
  solo->footer("Exit status: as `run` (firmware/README.md): 0 done; 2 bad option or configuration (named); 9 device missing; 4 diverged; "
               "5 safe state latched (device fault); 11 missed cycles; 3 other failure. A simulated device is never substituted for a missing one.");
  return solo;
}

// `haptic-station solo`: the station's phases without the network (firmware/station/run.cpp, RunOverrides::solo). Not RT-safe.
int solo_command(const SoloArgs& a) {
  std::vector<std::pair<std::string, std::string>> sets;  // (key, value), and the option that set it
  std::vector<std::pair<std::string, std::string>> named;
  auto set = [&](const std::string& key, const std::string& value, const std::string& option) {
    sets.emplace_back(key, value);
    named.emplace_back(key, option);
  };
  if (!a.device.empty()) set("device.kind", "\"" + a.device + "\"", "--device");
  else if (a.config.empty()) set("device.kind", "\"simulated\"", "--device");
  if (a.view_port > 0) set("station.view_port", std::to_string(a.view_port), "--view-port");
  if (!a.script.empty()) set("station.script", "\"" + a.script + "\"", "--script");
  if (a.nodes != 0) set("station.nodes", std::to_string(a.nodes), "--nodes");
  if (!a.scene.empty()) set("scene.file", nlohmann::json(std::filesystem::absolute(a.scene).string()).dump(), "--scene");  // not relative to --config
  StationFile file;
  try {
    file = load_station_file(a.config, sets, true);
  } catch (const std::exception& e) {
    std::string m = e.what();
    for (const auto& [key, option] : named)
      if (const auto at = m.find(key); at != std::string::npos) m.replace(at, key.size(), option + " (" + key + ")");
    std::cerr << "haptic-station solo: error: " << m << "\n";
    return kExitConfigError;
  }
  RunOverrides ov;
  ov.solo = true;
  ov.solo_anchor_N_per_m = a.anchor >= 0 ? a.anchor : kSoloDefaultAnchorNPerM;
  ov.out_dir = a.out;
  ov.duration_s = a.duration > 0 ? a.duration : file.station.duration_s > 0 ? -1 : kSoloDefaultDurationS;
  ov.quiet = a.quiet;
  return run_station_guarded(file, ov, "solo");
}

// `sim`'s options -> the scenario they describe; throws std::invalid_argument naming the option. Not RT-safe.
ScenarioSpec sim_scenario_spec(const SimArgs& a) {
  ScenarioSpec spec = make_scenario(a.scenario, "--scenario");
  if (!a.topology_file.empty()) apply_topology_file(spec, a.topology_file, "--topology-file");
  if (a.users) {
    if (!a.topology_file.empty() && *a.users != spec.users)
      throw std::invalid_argument("--users " + std::to_string(*a.users) + " differs from the " + std::to_string(spec.users) + " users of --topology-file");
    set_user_count(spec, *a.users, "--users");
  }
  spec.script.push_pattern = parse_push_pattern(a.pushes, "--pushes");
  spec.script.push_seed = a.push_seed;
  apply_script_kind(spec.script, a.script, a.push_seed, "--script");
  if (!a.delay_matrix.empty()) spec.delay_ms = haptic::model::parse_delay_matrix(a.delay_matrix, "--delay-matrix", spec.users);
  if (!a.topology.empty()) spec.topology = haptic::model::parse_graph_1based(a.topology, spec.users, "--topology");
  if (!a.damping.empty()) spec.damping_Ns_per_m = parse_list(a.damping, "--damping");
  if (a.push_end >= 0) spec.script.push_end_s = a.push_end;
  if (a.release >= 0) spec.script.release_s = a.release;
  if (a.duration >= 0) {
    if (spec.script.kind == UserScriptSpec::Kind::kPushHoldRelease && a.duration <= spec.script.release_s)
      std::cerr << "haptic-station: note: --duration " << a.duration << " s ends before the release at " << spec.script.release_s << " s\n";
    spec.duration_s = a.duration;
  }
  spec.seed = a.seed;
  if (a.loss >= 0) spec.loss_probability = a.loss;
  if (a.dup >= 0) spec.duplicate_probability = a.dup;
  if (a.nodes > 0) spec.scene_nodes = a.nodes;
  spec.scene_file.path = a.scene;
  spec.scene_file.unit_m = a.scene_unit_m;
  spec.scene_file.density_kg_per_m3 = a.density;
  spec.scene_file.youngs_modulus_Pa = a.youngs;
  if (a.p_gain >= 0) spec.p_gain_N_per_m = a.p_gain;
  if (a.d_gain >= 0) spec.d_gain_Ns_per_m = a.d_gain;
  if (a.margin >= 0) spec.damping_margin = a.margin;
  if (a.allowance >= 0) spec.loss_allowance_ticks = a.allowance;
  if (a.edge_energy_bound != -1) spec.edge_energy_bound_J = a.edge_energy_bound;
  if (a.edge_energy_leak != -1) spec.edge_energy_leak_W = a.edge_energy_leak;
  spec.drop_fade_s = a.drop_fade;
  spec.tx_deadband.position_deadband_m = a.tx_deadband_mm * 1e-3;
  spec.tx_deadband.max_interval_ticks = a.tx_interval;
  spec.tx_deadband.predictive = a.tx_predict;
  spec.trace_node = a.trace_node;
  spec.receive_rule = haptic::rt::parse_rx_rule(a.receive_rule, "--receive-rule");
  spec.solver = haptic::rt::parse_step_solver_kind(a.solver);
  if (a.jitter != -1) spec.jitter_fraction = a.jitter;
  spec.delay_correlation = a.delay_correlation;
  if (!a.delay_trace.empty()) spec.delay_trace = haptic::net::load_delay_trace(a.delay_trace);
  spec.burst_enter_probability = a.burst_enter;
  spec.burst_mean_packets = a.burst_length;
  spec.burst_loss_probability = a.burst_loss;
  if (a.node_mass_kg != -1) spec.scene.node_mass_kg = a.node_mass_kg;
  spec.timer_jitter_s = a.timer_jitter_ms * 1e-3;
  spec.step_jitter = a.step_jitter;
  spec.clock_drift_ppm = a.clock_drift_ppm;
  spec.consensus_passivity = haptic::rt::parse_consensus_passivity(a.consensus_passivity, "--consensus-passivity");
  if (!(a.pspm_reservoir_J >= 0 && std::isfinite(a.pspm_reservoir_J)))
    throw std::invalid_argument("--pspm-reservoir-J = " + std::to_string(a.pspm_reservoir_J) + " must be finite and >= 0");
  spec.pspm_reservoir0_J = a.pspm_reservoir_J;
  spec.resilient_f = a.resilient_f;
  apply_sim_safeguards(a, spec);
  return spec;
}

// `haptic-station sim`: returns 0, or 2 on a bad option. Not RT-safe.
int sim_command(const SimArgs& a) {
  try {
    const ScenarioSpec spec = sim_scenario_spec(a);
    const BuiltScenario built = build_scenario(spec);
    fs::create_directories(a.out);
    SimOptions opt;
    opt.out_dir = a.out;
    opt.trace_every = a.trace_every.value_or(default_trace_every(spec.users));
    opt.series_every = a.trace_every.value_or(1);
    opt.progress = !a.quiet;
    opt.record = a.record;
    opt.record_ring_s = a.record_ring_s;
    opt.record_deflate = a.record_deflate;
    opt.record_max_mb = a.record_max_mb;
    opt.command_line = a.command_line;
    opt.snapshot_times_s = snapshot_times_s(spec);
    if (!a.quiet) {
      std::cerr << "haptic-station sim: scenario " << spec.name << ", " << spec.users << " users, " << built.scene.nodes
                << " nodes, " << spec.duration_s << " s, seed " << spec.seed << "\n  B_i used (N s/m):";
      for (double b : built.damping) std::cerr << " " << fmt(b, 2);
      std::cerr << "\n  eq. (18) minimum:";
      for (double b : built.damping_min) std::cerr << " " << fmt(b, 2);
      std::cerr << (built.passivity_condition_met ? "  (met)\n" : "  (VIOLATED)\n");
    }
    std::optional<FigureDrawer> figures;
    if (!a.no_plots) figures.emplace(a.out, opt.snapshot_times_s.size(), spec.users);  // imports matplotlib while the simulation runs
    const SimResult r = run_simulation(built, opt);
    if (!a.quiet) std::cerr << "  solver of the linear step: " << r.solver.front() << " (station 1; summary.json \"solver\")\n";
    write_summary_json(a.out + "/summary.json", built, r);
    std::cout << sim_result_line(spec.name, r) << "\n";
    const auto& m = r.metrics;
    if (spec.script.push_pattern == UserScriptSpec::PushPattern::kAsymmetric && m.hold_force_sum_N && m.hold_force_mean_N &&
        *m.hold_force_sum_N > 0.1 * *m.hold_force_mean_N)
      std::cerr << "haptic-station: note: with asymmetric pushes the users' forces balance (eq. 20) once the object has stopped "
                   "drifting; the damping drags the drift, so hold longer (--release, README \"Hold-force balance\"; "
                   "tools/study/hold_balance.py OUT shows the time constant)\n";
    std::cout << "wrote " << a.out << "/summary.json, trace.csv, series.csv, snapshots.json\n";
    if (a.record) std::cout << "wrote " << a.out << "/station-<i>.h5 (session logs)\n";
    if (figures && figures->draw()) std::cout << "wrote " << a.out << "/*.png\n";
    if (a.view_port > 0) {
      if (!a.record) throw std::invalid_argument("--view-port needs --record (the view replays the recorded session)");
      if (a.view_station < 1 || a.view_station > spec.users) throw std::invalid_argument("--view-station must be 1.." + std::to_string(spec.users));
      stop_on_signals();  // the view ends and says what the page showed
      serve_timeline(a.out + "/station-" + std::to_string(a.view_station) + ".h5", {}, timeline_options(a.view_port, a.view_bind, a.view_for, "sim"), g_stop);
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "haptic-station sim: error: " << e.what() << "\n";
    return 2;
  }
}

// The `merge` subcommand's options into `dir`. Not RT-safe.
CLI::App* add_merge_options(CLI::App& app, std::string& dir) {
  auto* merge = app.add_subcommand(
      "merge", "Merge the outputs of N `run` processes (DIR/station-<i>.json, -trace.csv, -state.csv) into DIR/summary.json, trace.csv, "
               "series.csv: the simulator's contract and metrics");
  merge->add_option("DIR", dir, "The stations' common output directory (station.out_dir)")->required();
  merge->footer("Exit status: 0 merged; 2 usage error; 3 the directory cannot be merged (missing or inconsistent station files, "
                "a station that reported an error, no tick recorded by every station).");
  return merge;
}

// `haptic-station merge DIR`: 0 merged, 3 not mergeable. Not RT-safe.
int merge_command(const std::string& dir) {
  try {
    const auto summary = merge_run(dir);
    std::cout << "haptic-station merge: " << merge_result_line(summary) << "\nwrote " << dir << "/summary.json, trace.csv, series.csv, snapshots.json\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "haptic-station merge: error: " << e.what() << "\n";
    return kExitRunFailed;
  }
}

// The `scenario` subcommand: prints a built-in scenario's users, links and mean delays as JSON, so
// tools (haptic-lab's topology.from_scenario, run4.sh) take them from the one definition in
// firmware/scenario.cpp instead of copying them. Not RT-safe.
struct ScenarioQuery {
  std::string name;
  int users = 0;         // 0: the scenario's
  std::string topology;  // "": the scenario's
};
CLI::App* add_scenario_options(CLI::App& app, ScenarioQuery& q) {
  auto* sc = app.add_subcommand("scenario", "Print a built-in scenario's users, links (1-based), each user's neighbours and mean one-way delays (ms) as JSON");
  std::string names;
  for (const auto& n : scenario_names()) names += (names.empty() ? "" : ", ") + n;
  sc->add_option("NAME", q.name, "Scenario: " + names)->required();
  sc->add_option("--users", q.users, "Number of users 2..64 (the scenario's delays and links for N users, as sim --users)");
  sc->add_option("--topology", q.topology, "Links \"1-2,1-3,1-4\" instead of the scenario's (checked: users 1..N, connected)");
  sc->footer("Exit status: 0 printed; 2 unknown scenario, bad users or links, or usage error.");
  return sc;
}

// `haptic-station scenario NAME [--users N] [--topology LINKS]`: 0 printed, 2 unknown name or bad
// option. "neighbours": each user's neighbours (1-based) in link order (model::adjacency), what
// haptic-lab writes as the stations' peers. Not RT-safe.
int scenario_command(const ScenarioQuery& q) {
  try {
    ScenarioSpec s = make_scenario(q.name);
    if (q.users != 0) set_user_count(s, q.users, "--users");
    if (!q.topology.empty()) s.topology = haptic::model::parse_graph_1based(q.topology, s.users, "--topology");
    haptic::model::validate_graph(s.topology, s.users, "--topology");
    nlohmann::json delays = nlohmann::json::array();
    for (int i = 0; i < s.delay_ms.rows(); ++i) {
      nlohmann::json row = nlohmann::json::array();
      for (int j = 0; j < s.delay_ms.cols(); ++j) row.push_back(s.delay_ms(i, j));
      delays.push_back(row);
    }
    nlohmann::json neighbours = nlohmann::json::array();
    for (const auto& nb : haptic::model::adjacency(s.topology, s.users).neighbours) {
      nlohmann::json one = nlohmann::json::array();
      for (int j : nb) one.push_back(j + 1);
      neighbours.push_back(one);
    }
    std::cout << nlohmann::json{{"name", s.name}, {"users", s.users}, {"topology", topology_json(s.topology)}, {"neighbours", neighbours},
                                {"delay_ms", delays}, {"duration_s", s.duration_s}, {"release_s", s.script.release_s}}.dump()
              << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "haptic-station scenario: error: " << e.what() << "\n";
    return kExitConfigError;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "haptic-station: a station of the consensus-based peer-to-peer multi-user haptics runtime\n"
      "(Huang & Lee, IEEE T-RO 2013). Subcommands:\n"
      "  sim  run N stations in one process in simulated time over the paper's stochastic network\n"
      "  run  run one station in real time over real sockets (--config FILE.toml)\n"
      "  solo  one station, one user, no network: touch the object with your device and the live view\n"
      "  replay  re-run a station's core from its session log, bit-exactly (LOG.h5)\n"
      "  log  what a session log holds (log info LOG.h5) and its fields as CSV with units (log export LOG.h5 --field force,q)\n"
      "  merge  merge the outputs of N run processes into the simulator's summary.json, trace.csv, series.csv, snapshots.json\n"
      "  scenario  print a built-in scenario's users, links and delays as JSON\n"
      "  options  print every station-file option as a Markdown table"};
  app.require_subcommand(1);
  haptic::platform::add_version_flag(app, "haptic-station");
  app.footer("Exit status: 0 done; 2 bad options or configuration. `run` also: " + exit_code_help() +
             " `replay`: see `replay --help`; `log`: see `log --help`.");

  SimArgs sim_args;
  RunArgs run_args;
  ReplayArgs replay_args;
  CLI::App* sim = add_sim_options(app, sim_args);
  CLI::App* run = add_run_options(app, run_args);
  CLI::App* replay = add_replay_options(app, replay_args);
  SoloArgs solo_args;
  CLI::App* solo = add_solo_options(app, solo_args);
  LogArgs log_args;
  const LogCommands log = add_log_options(app, log_args);
  for (int i = 0; i < argc; ++i) sim_args.command_line += (i ? " " : "") + std::string(argv[i]);
  std::string merge_dir;
  CLI::App* merge = add_merge_options(app, merge_dir);
  ScenarioQuery scenario_query;
  CLI::App* scenario = add_scenario_options(app, scenario_query);
  CLI::App* options = app.add_subcommand("options", "Print every station-file option (key, type, accepted values, default, meaning) "
                                                    "as the Markdown table of firmware/station/OPTIONS.md");
  bool markdown = true;
  options->add_flag("--markdown", markdown, "Markdown (the only format, the default)");

  // --help/--version: 0; a usage error (an unknown option or subcommand with "did you mean"): 2.
  if (const int rc = haptic::platform::parse_command_line(app, argc, argv, kExitConfigError); rc >= 0) return rc;

  if (run->parsed()) return run_command(run_args);
  if (solo->parsed()) return solo_command(solo_args);
  if (sim->parsed()) return sim_command(sim_args);
  if (replay->parsed()) return replay_command(replay_args);
  if (log.log->parsed()) return log_command(log, log_args);
  if (merge->parsed()) return merge_command(merge_dir);
  if (scenario->parsed()) return scenario_command(scenario_query);
  if (options->parsed()) std::cout << options_markdown();
  return 0;
}
