// haptic-study: the speed-against-accuracy study, stability maps and model selector.
// Subcommands: accuracy, energy, stability, consensus, select. See tools/study/README.md.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "firmware/scenario.hpp"
#include "firmware/sim/simulator.hpp"
#include "rt/spatial_matrix.hpp"
#include "tools/study/study.hpp"
#include "platform/command_line.hpp"

using namespace haptic;
using json = nlohmann::json;

namespace {

struct Row {
  std::string kind, integrator;
  int nodes = 0, modes = 0;
  double step_s = 0, force_self = 0, shape_self = 0, force_ref = 0, cost_s = 0;
  double load() const { return cost_s / step_s; }  // CPU fraction at real time
};

std::string num(double v) {
  if (std::isinf(v)) return "inf";
  if (std::isnan(v)) return "nan";
  std::ostringstream o;
  o << std::setprecision(6) << v;
  return o.str();
}

void write_rows_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << "kind,integrator,nodes,modes,step_s,force_error_self,shape_error_self,force_error_ref,cost_s_per_tick,cpu_load\n";
  for (const auto& r : rows)
    f << r.kind << ',' << r.integrator << ',' << r.nodes << ',' << r.modes << ',' << num(r.step_s) << ','
      << num(r.force_self) << ',' << num(r.shape_self) << ',' << num(r.force_ref) << ',' << num(r.cost_s) << ','
      << num(r.load()) << '\n';
}

std::vector<Row> read_rows_csv(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("--from: cannot read " + path + " (run `haptic-study accuracy` first)");
  std::string line;
  std::getline(f, line);
  std::vector<Row> rows;
  while (std::getline(f, line)) {
    std::vector<std::string> c;
    std::stringstream ss(line);
    std::string it;
    while (std::getline(ss, it, ',')) c.push_back(it);
    if (c.size() < 9) continue;
    Row r;
    r.kind = c[0];
    r.integrator = c[1];
    r.nodes = std::stoi(c[2]);
    r.modes = std::stoi(c[3]);
    r.step_s = std::stod(c[4]);
    r.force_self = std::stod(c[5]);
    r.shape_self = std::stod(c[6]);
    r.force_ref = std::stod(c[7]);
    r.cost_s = std::stod(c[8]);
    rows.push_back(r);
  }
  return rows;
}

// Pareto front of (cpu load, error): indices of non-dominated finite rows, by increasing load.
std::vector<std::size_t> pareto(const std::vector<Row>& rows, bool against_ref) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const double e = against_ref ? rows[i].force_ref : rows[i].force_self;
    if (std::isfinite(e)) idx.push_back(i);
  }
  std::sort(idx.begin(), idx.end(), [&](auto a, auto b) { return rows[a].load() < rows[b].load(); });
  std::vector<std::size_t> front;
  double best = INFINITY;
  for (auto i : idx) {
    const double e = against_ref ? rows[i].force_ref : rows[i].force_self;
    if (e < best) {
      front.push_back(i);
      best = e;
    }
  }
  return front;
}

study::PushProblemParams problem_params(double damping_per_s) {
  study::PushProblemParams p;
  p.damping_per_s = damping_per_s;
  return p;
}

json problem_json(const study::PushProblemParams& p) {
  return {{"radius_m", p.radius_m},
          {"total_mass_kg", p.total_mass_kg},
          {"reference_edge_stiffness_N_per_m", p.reference_edge_stiffness_N_per_m},
          {"damping_per_s", p.damping_per_s},
          {"contact_stiffness_N_per_m", p.contact_stiffness_N_per_m},
          {"support_stiffness_N_per_m", p.support_stiffness_N_per_m},
          {"cap_radius_m", p.cap_radius_m},
          {"push_depth_m", p.push_depth_m},
          {"push_frequency_Hz", p.push_frequency_Hz}};
}

// Candidates for the selector and the accuracy table: NPMI at `step` on every mesh, and the
// reduced models of the reference mesh.
struct Study {
  std::vector<Row> rows;
  json meta;
};

Study run_accuracy(const std::vector<int>& nodes_list, const std::vector<double>& steps_ms, const std::vector<int>& modes_list,
                   double duration_s, double sample_ms, double damping, bool all_integrators, bool verbose) {
  Study st;
  const auto params = problem_params(damping);
  const int ref_nodes = *std::max_element(nodes_list.begin(), nodes_list.end());
  std::map<int, study::ExactCase> cases;
  for (int n : nodes_list) {
    if (verbose) std::cerr << "exact solution for " << n << " nodes..." << std::flush;
    cases.emplace(n, study::make_exact_case(n, params, duration_s, sample_ms * 1e-3, true));
    const auto& c = cases.at(n);
    if (verbose)
      std::cerr << " " << c.problem.model.nodes << " nodes, eig " << num(c.eig_seconds) << " s, omega_max "
                << num(std::sqrt(c.basis.omega2.maxCoeff())) << " rad/s\n";
    st.meta["meshes"].push_back({{"requested_nodes", n},
                                 {"nodes", c.problem.model.nodes},
                                 {"description", c.problem.mesh.description},
                                 {"edge_stiffness_N_per_m", c.problem.edge_stiffness_N_per_m},
                                 {"node_mass_kg", c.problem.model.node_mass_kg},
                                 {"contact_nodes", c.problem.contact_nodes.size()},
                                 {"support_nodes", c.problem.support_nodes.size()},
                                 {"omega_max_rad_per_s", std::sqrt(c.basis.omega2.maxCoeff())},
                                 {"eig_seconds", c.eig_seconds},
                                 {"peak_force_N", c.force_scale}});
  }
  const auto& ref = cases.at(ref_nodes);
  const auto methods = all_integrators ? study::all_integrators() : std::vector<study::Integrator>{study::Integrator::kNpmi};
  for (int n : nodes_list) {
    const auto& c = cases.at(n);
    for (auto m : methods) {
      const double cost = study::time_full_step(c.problem, m, 0.002);
      for (double hms : steps_ms) {
        const auto e = study::run_full(c, m, hms * 1e-3, &ref);
        Row r{"mesh", study::integrator_name(m), n, 0, hms * 1e-3, e.force_error_self, e.shape_error_self, e.force_error_ref, cost};
        if (verbose)
          std::cerr << "  " << std::setw(5) << n << " " << std::setw(20) << r.integrator << " h " << std::setw(5) << hms
                    << " ms: force err " << std::setw(11) << num(r.force_self) << " shape err " << std::setw(11)
                    << num(r.shape_self) << " vs ref " << std::setw(11) << num(r.force_ref) << " cost "
                    << num(cost * 1e6) << " us\n";
        st.rows.push_back(r);
      }
    }
  }
  for (int r : modes_list) {
    if (r > ref.basis.modes()) continue;
    for (bool sc : {false, true}) {
      const double cost = study::time_modal_step(ref.basis, ref.problem, r, sc, 0.002);
      for (double hms : steps_ms) {
        const auto e = study::run_modal(ref, r, sc, hms * 1e-3);
        Row row{sc ? "modal+sc" : "modal", "npmi", ref_nodes, r, hms * 1e-3, e.force_error_self, e.shape_error_self, e.force_error_ref, cost};
        st.rows.push_back(row);
      }
      if (verbose) std::cerr << "  modal r=" << r << (sc ? "+sc" : "") << " done (cost " << num(cost * 1e6) << " us)\n";
    }
  }
  st.meta["problem"] = problem_json(params);
  st.meta["reference_nodes"] = ref_nodes;
  st.meta["duration_s"] = duration_s;
  st.meta["sample_interval_s"] = sample_ms * 1e-3;
  st.meta["cost_note"] =
      "cost_s_per_tick: wall-clock seconds per step + felt-force output of the allocation-free loop, median of 5 "
      "batches (steady_clock), measured at h = 2 ms (independent of h); not a Google Benchmark figure; shared 2-core "
      "machine";
  return st;
}

void print_front(const std::vector<Row>& rows, bool against_ref, std::ostream& o) {
  o << (against_ref ? "Pareto front (felt-force error vs the reference mesh's exact solution, against CPU load at real time)\n"
                    : "Pareto front (integration error vs each model's own exact solution)\n");
  o << "  kind       integrator            nodes modes  h_ms   error        cost_us/tick  cpu_load\n";
  for (auto i : pareto(rows, against_ref)) {
    const auto& r = rows[i];
    o << "  " << std::left << std::setw(10) << r.kind << " " << std::setw(20) << r.integrator << std::right << std::setw(6)
      << r.nodes << std::setw(6) << r.modes << std::setw(6) << r.step_s * 1e3 << "   " << std::setw(11)
      << num(against_ref ? r.force_ref : r.force_self) << "  " << std::setw(12) << num(r.cost_s * 1e6) << "  "
      << num(r.load()) << "\n";
  }
}

json rows_json(const std::vector<Row>& rows, const std::vector<std::size_t>& idx) {
  json a = json::array();
  for (auto i : idx) {
    const auto& r = rows[i];
    a.push_back({{"kind", r.kind}, {"integrator", r.integrator}, {"nodes", r.nodes}, {"modes", r.modes},
                 {"step_s", r.step_s}, {"force_error_self", r.force_self}, {"force_error_ref", r.force_ref},
                 {"cost_s_per_tick", r.cost_s}, {"cpu_load", r.load()}});
  }
  return a;
}

void write_json(const std::string& path, const json& j) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << j.dump(1) << "\n";
}

std::vector<study::ModelCandidate> candidates_from(const std::vector<Row>& rows, double step_s) {
  std::vector<study::ModelCandidate> c;
  for (const auto& r : rows) {
    if (r.integrator != "npmi" || std::abs(r.step_s - step_s) > 1e-12 || !std::isfinite(r.force_ref)) continue;
    c.push_back({r.kind, r.nodes, r.modes, r.step_s, r.force_ref, r.cost_s});
  }
  return c;
}


// The command line: the subcommand that was given and every option of every subcommand.
struct StudyOptions {
  std::string out = "tools/study/results";

  // accuracy
  std::string nodes_s = "33,100,300,1000,3000", steps_s = "0.25,0.5,1,2,4,8", modes_s = "3,6,12,25,50,100,200,400";
  double duration = 2.0, sample_ms = 8.0, damping = 0.0;

  // energy
  int en_nodes = 33;
  double en_duration = 10.0;
  std::string en_steps = "2,0.5";

  // stability
  std::string st_scales = "0.25,1,4,16,64,256", st_sizes = "33,100,300,1000,3000", st_steps = "0.25,0.5,1,2,4,8";
  double st_duration = 2.0;

  // consensus
  std::string c_damp = "0,0.1,0.25,0.5,0.75,1,1.5", c_delay = "0.25,0.5,1,2,4,8", c_loss = "0,0.05,0.2";
  std::string c_gains = "1000:5,5000:0.5";
  double c_duration = 8.0;

  // select
  double accuracy = 0.05;
  std::string from, sel_nodes = "33,100,300,1000", sel_modes = "3,6,12,25,50,100,200";

  std::string command;  // the subcommand given: accuracy, energy, stability, consensus or select

  // Returns -1 to go on, else the exit code (--help: 0; a usage error: CLI11's).
  int parse(int argc, char** argv);
};

int StudyOptions::parse(int argc, char** argv) {
  CLI::App app{"haptic-study: speed against accuracy, stability maps, model selector"};
  app.require_subcommand(1);
  app.add_option("--out", out, "Output folder for CSV/JSON (default tools/study/results)");

  // accuracy
  auto* acc = app.add_subcommand("accuracy", "Integrators x step sizes x scene sizes x reduced models against the exact solution");
  acc->add_option("--nodes", nodes_s, "Mesh sizes (33 = paper ball, else lattice ball); the largest is the reference");
  acc->add_option("--steps-ms", steps_s, "Step sizes (ms); each must divide --sample-ms");
  acc->add_option("--modes", modes_s, "Modal truncations r of the reference mesh");
  acc->add_option("--duration", duration, "Simulated seconds (default 2)")->check(haptic::platform::kPositive);
  acc->add_option("--sample-ms", sample_ms, "Error sampling interval (ms, default 8)")->check(haptic::platform::kPositive);
  acc->add_option("--damping-per-s", damping, "b/m of the VO (default 0: the paper's B = 0)")->check(haptic::platform::kNonNegative);

  // energy
  auto* en = app.add_subcommand("energy", "Energy drift of each integrator, free vibration, B = 0");
  en->add_option("--nodes", en_nodes, "Mesh size (default 33, the paper ball)")->check(CLI::Range(7, 20000));
  en->add_option("--duration", en_duration, "Seconds (default 10)")->check(haptic::platform::kPositive);
  en->add_option("--steps-ms", en_steps, "Step sizes (ms, default 2,0.5)");

  // stability
  auto* stab = app.add_subcommand("stability", "Where each integrator blows up: step x stiffness scale and step x scene size");
  stab->add_option("--stiffness-scales", st_scales, "Edge stiffness multipliers on the 33-node scene");
  stab->add_option("--sizes", st_sizes, "Scene sizes");
  stab->add_option("--steps-ms", st_steps, "Step sizes (ms)");
  stab->add_option("--duration", st_duration, "Free-vibration seconds per cell (default 2)")->check(haptic::platform::kPositive);

  // consensus
  auto* con = app.add_subcommand("consensus", "4-user consensus stability over damping scale x delay scale x loss (run_simulation)");
  con->add_option("--damping-scales", c_damp, "B_i / eq. (18) value");
  con->add_option("--delay-scales", c_delay, "x the paper's delay matrix");
  con->add_option("--losses", c_loss, "Loss probabilities");
  con->add_option("--gains", c_gains, "P:D gain sets (N/m : N s/m), comma-separated");
  con->add_option("--duration", c_duration, "Seconds per run (default 8)")->check(haptic::platform::kPositive);

  // select
  auto* sel = app.add_subcommand("select", "Smallest model meeting a felt-force accuracy; prints the --nodes for haptic-station sim");
  sel->add_option("--accuracy", accuracy, "Requested max relative felt-force error (fraction, e.g. 0.05)")->required()->check(haptic::platform::kPositive);
  sel->add_option("--from", from, "Read candidates from an accuracy.csv instead of computing them");
  sel->add_option("--nodes", sel_nodes, "Mesh family when computing (largest = reference)");
  sel->add_option("--modes", sel_modes, "Modal truncations of the reference when computing");

  haptic::platform::add_version_flag(app, "haptic-study");
  // --help/--version: 0; a usage error (an unknown option or subcommand with "did you mean"): 2.
  if (const int rc = haptic::platform::parse_command_line(app, argc, argv, 2); rc >= 0) return rc;
  for (const CLI::App* sub : {acc, en, stab, con, sel})
    if (sub->parsed()) command = sub->get_name();
  return -1;
}

// accuracy: the table, both Pareto fronts (printed too) and the run's metadata.
void accuracy_command(const StudyOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  auto st = run_accuracy(study::parse_int_list(o.nodes_s, "--nodes"), study::parse_double_list(o.steps_s, "--steps-ms"),
                         study::parse_int_list(o.modes_s, "--modes"), o.duration, o.sample_ms, o.damping, true, true);
  write_rows_csv(o.out + "/accuracy.csv", st.rows);
  st.meta["pareto_front_ref"] = rows_json(st.rows, pareto(st.rows, true));
  st.meta["pareto_front_self"] = rows_json(st.rows, pareto(st.rows, false));
  st.meta["wall_time_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_json(o.out + "/accuracy.json", st.meta);
  print_front(st.rows, false, std::cout);
  print_front(st.rows, true, std::cout);
  std::cout << "wrote " << o.out << "/accuracy.csv, accuracy.json\n";
}

// energy: E(t)/E0 of every integrator at every step, free vibration from the pushed shape.
void energy_command(const StudyOptions& o) {
  const auto p = study::make_push_problem(study::make_ball_mesh(o.en_nodes, 0.05), problem_params(0));
  std::ofstream f(o.out + "/energy.csv");
  f << "integrator,step_s,t_s,energy_ratio\n";
  json summary;
  for (double hms : study::parse_double_list(o.en_steps, "--steps-ms")) {
    const double h = hms * 1e-3;
    const int every = std::max(1, static_cast<int>(std::lround(0.01 / h)));
    for (auto m : study::all_integrators()) {
      const auto tr = study::energy_trace(p, m, h, o.en_duration, every);
      for (std::size_t k = 0; k < tr.t_s.size(); ++k)
        f << study::integrator_name(m) << ',' << num(h) << ',' << num(tr.t_s[k]) << ',' << std::setprecision(16) << tr.energy_ratio[k] << '\n';
      summary.push_back({{"integrator", study::integrator_name(m)}, {"step_s", h}, {"class", study::classify_energy(tr)},
                         {"final_ratio", tr.energy_ratio.back()}, {"final_t_s", tr.t_s.back()},
                         {"max_ratio", *std::max_element(tr.energy_ratio.begin(), tr.energy_ratio.end())}});
      std::cout << std::setw(20) << study::integrator_name(m) << " h " << hms << " ms: E(" << num(tr.t_s.back())
                << " s)/E0 = " << num(tr.energy_ratio.back()) << " (" << study::classify_energy(tr) << ")\n";
    }
  }
  write_json(o.out + "/energy.json", {{"nodes", p.model.nodes}, {"runs", summary},
                                      {"initial_state", "static deformation under the full push, v = 0, no input, B = 0"}});
}

// One cell of the stability map (one problem, every integrator over --steps-ms): a CSV row per
// step, a summary entry and a printed line per integrator.
void stability_cell(const StudyOptions& o, std::ofstream& f, json& summary, const std::string& axis, double value,
                    const study::PushProblem& p) {
  const double wmax = std::sqrt(rt::lambda_max(rt::SpatialMatrix::isotropic(p.model.K)) / p.model.node_mass_kg);
  for (auto m : study::all_integrators()) {
    double first_bad = -1;
    for (double hms : study::parse_double_list(o.st_steps, "--steps-ms")) {
      const double h = hms * 1e-3;
      const auto tr = study::energy_trace(p, m, h, o.st_duration, 1);
      const auto cls = study::classify_energy(tr);
      double mx = 0;
      for (double r : tr.energy_ratio) mx = std::isfinite(r) ? std::max(mx, r) : INFINITY;
      f << axis << ',' << num(value) << ',' << p.model.nodes << ',' << study::integrator_name(m) << ',' << num(h) << ','
        << num(wmax * h) << ',' << cls << ',' << num(mx) << '\n';
      if ((cls == "blows-up" || cls == "grows") && first_bad < 0) first_bad = h;
    }
    summary.push_back({{"axis", axis}, {"value", value}, {"nodes", p.model.nodes}, {"integrator", study::integrator_name(m)},
                       {"omega_max_rad_per_s", wmax}, {"smallest_unstable_step_s", first_bad}});
    std::cout << axis << "=" << num(value) << " " << std::setw(20) << study::integrator_name(m) << " omega_max "
              << num(wmax) << " rad/s: first growing/blowing step " << (first_bad < 0 ? std::string("none") : num(first_bad * 1e3) + " ms")
              << "\n";
  }
}

// stability: step x stiffness scale on the 33-node scene, then step x scene size.
void stability_command(const StudyOptions& o) {
  std::ofstream f(o.out + "/stability.csv");
  f << "axis,value,nodes,integrator,step_s,omega_max_h,class,max_energy_ratio\n";
  json summary = json::array();
  for (double s : study::parse_double_list(o.st_scales, "--stiffness-scales")) {
    auto params = problem_params(0);
    params.reference_edge_stiffness_N_per_m *= s;
    stability_cell(o, f, summary, "stiffness_scale", s, study::make_push_problem(study::make_ball_mesh(33, 0.05), params));
  }
  for (int n : study::parse_int_list(o.st_sizes, "--sizes"))
    stability_cell(o, f, summary, "nodes", n, study::make_push_problem(study::make_ball_mesh(n, 0.05), problem_params(0)));
  write_json(o.out + "/stability.json", {{"duration_s", o.st_duration}, {"cells", summary},
                                         {"classes", "blows-up: max E/E0 > 100; grows: max > 1.01 and 2nd-half max > 1.1 x 1st-half max; dissipative: final < 0.99; bounded: oscillates above 1.01 without trend; stable: within 1%"}});
}

// --gains "P:D,P:D": the gain sets of the consensus map.
std::vector<std::pair<double, double>> parse_gains(const std::string& text) {
  std::vector<std::pair<double, double>> gains;
  std::stringstream ss(text);
  std::string it;
  while (std::getline(ss, it, ',')) {
    const auto colon = it.find(':');
    if (colon == std::string::npos) throw std::invalid_argument("--gains: expected P:D pairs, got '" + it + "'");
    gains.emplace_back(std::stod(it.substr(0, colon)), std::stod(it.substr(colon + 1)));
  }
  return gains;
}

// One cell of the consensus map: the paper-best run with gains P, D, loss, delays x ds and every
// B_i = bs x its eq. (18) minimum; a CSV row and a summary entry.
void consensus_cell(const StudyOptions& o, std::ofstream& f, json& summary, double P, double D, double loss, double ds, double bs) {
  auto spec = firmware::make_scenario("paper-best");
  spec.duration_s = o.c_duration;
  spec.delay_ms = spec.delay_ms * ds;
  spec.loss_probability = loss;
  spec.p_gain_N_per_m = P;
  spec.d_gain_Ns_per_m = D;
  spec.script.kind = firmware::UserScriptSpec::Kind::kRandom;
  spec.damping_margin = 0.0;
  spec.edge_energy_bound_J = 0;  // the map is about eq. (18) alone: no per-edge energy bound
  auto probe = firmware::build_scenario(spec);
  std::vector<double> B(probe.damping_min.size());
  for (std::size_t i = 0; i < B.size(); ++i) B[i] = bs * probe.damping_min[i];
  spec.damping_Ns_per_m = B;
  const auto built = firmware::build_scenario(spec);
  const auto r = firmware::run_simulation(built, firmware::SimOptions{});
  const auto& m = r.metrics;
  const double port_min = m.port_energy_min_J.value_or(0.0);
  const std::string cls = m.diverged ? "diverged" : model::eq13_broken(m.port_energy_min_J, r.passivity_bound_J) ? "energy-generated" : "stable";
  std::uint64_t violations = 0, lost = 0;
  for (const auto& l : r.links) {
    violations += l.bound_violations;
    lost += l.lost;
  }
  const double bmax = *std::max_element(probe.damping_min.begin(), probe.damping_min.end());
  f << P << ',' << D << ',' << bs << ',' << ds << ',' << loss << ',' << num(bmax) << ',' << m.diverged << ','
    << num(port_min) << ',' << num(r.passivity_bound_J) << ',' << cls << ','
    << num(m.max_node_speed_m_per_s.value_or(0.0)) << ',' << violations << ',' << lost << '\n';
  f.flush();
  summary.push_back({{"P", P}, {"D", D}, {"damping_scale", bs}, {"delay_scale", ds}, {"loss", loss},
                     {"damping_min", probe.damping_min}, {"class", cls}});
}

// consensus: every gain set x loss x delay scale x damping scale; progress on stderr.
void consensus_command(const StudyOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  std::ofstream f(o.out + "/consensus.csv");
  f << "p_gain,d_gain,damping_scale,delay_scale,loss,damping_min_max,diverged,port_energy_min_J,passivity_bound_J,class,max_speed,bound_violations,edge_lost\n";
  const std::vector<std::pair<double, double>> gains = parse_gains(o.c_gains);
  json summary = json::array();
  for (auto [P, D] : gains) {
    for (double loss : study::parse_double_list(o.c_loss, "--losses")) {
      for (double ds : study::parse_double_list(o.c_delay, "--delay-scales")) {
        for (double bs : study::parse_double_list(o.c_damp, "--damping-scales")) consensus_cell(o, f, summary, P, D, loss, ds, bs);
        std::cerr << "P " << P << " D " << D << " loss " << loss << " delay x" << ds << " done ("
                  << num(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()) << " s)\n";
      }
    }
  }
  write_json(o.out + "/consensus.json",
             {{"duration_s", o.c_duration}, {"script", "random (every user's goal wanders through random keyframes)"},
              {"scenario", "paper-best topology and delays, scaled"}, {"cells", summary},
              {"wall_time_s", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
}

std::string describe(const study::ModelCandidate& c) {
  std::ostringstream o;
  o << c.kind << " " << c.nodes << " nodes";
  if (c.modes) o << ", " << c.modes << " modes";
  o << " (felt-force error " << num(c.force_error * 100) << " %, " << num(c.cost_s_per_tick * 1e6) << " us/tick)";
  return o.str();
}

// select: the smallest mesh meeting --accuracy, as "--nodes N" on stdout (the reasons on stderr).
// Returns 0, or 2 when no mesh of the family meets it (the reference mesh is printed then).
int select_command(const StudyOptions& o) {
  std::vector<Row> rows;
  if (!o.from.empty()) {
    rows = read_rows_csv(o.from);
  } else {
    rows = run_accuracy(study::parse_int_list(o.sel_nodes, "--nodes"), {2.0}, study::parse_int_list(o.sel_modes, "--modes"),
                        2.0, 8.0, 0.0, false, false)
               .rows;
  }
  const auto cands = candidates_from(rows, 0.002);
  const auto mesh = study::select_model(cands, o.accuracy, {"mesh"});
  const auto any = study::select_model(cands, o.accuracy, {});
  std::cerr << "requested felt-force accuracy " << num(o.accuracy * 100) << " % (NPMI, T = 2 ms, vs the "
            << (mesh.reference.nodes ? std::to_string(mesh.reference.nodes) : std::string("?")) << "-node exact solution)\n";
  if (any.found)
    std::cerr << "  cheapest model of all kinds: " << describe(any.chosen) << ", saves x" << num(any.cost_saving_factor)
              << " against " << describe(any.reference) << "\n";
  if (!mesh.found) {
    std::cerr << "  no mesh of the family meets " << num(o.accuracy * 100) << " %; use the reference mesh\n";
    std::cout << "--nodes " << mesh.reference.nodes << "\n";
    return 2;
  }
  std::cerr << "  smallest mesh: " << describe(mesh.chosen) << ", saves x" << num(mesh.cost_saving_factor) << " against "
            << describe(mesh.reference) << "\n";
  {
    const auto chosen = study::make_push_problem(study::make_ball_mesh(mesh.chosen.nodes, 0.05), problem_params(0));
    std::cerr << "  the study's physics for this mesh (same ball at every resolution): node_mass_kg "
              << num(chosen.model.node_mass_kg) << ", edge_stiffness_N_per_m " << num(chosen.edge_stiffness_N_per_m)
              << " (the station's --nodes keeps 0.04 kg / 100 N/m per node/edge; see tools/study/README.md)\n";
  }
  std::cout << "--nodes " << mesh.chosen.nodes << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  StudyOptions options;
  if (const int rc = options.parse(argc, argv); rc >= 0) return rc;
  try {
    std::filesystem::create_directories(options.out);
    if (options.command == "accuracy") accuracy_command(options);
    else if (options.command == "energy") energy_command(options);
    else if (options.command == "stability") stability_command(options);
    else if (options.command == "consensus") consensus_command(options);
    else if (options.command == "select") return select_command(options);
  } catch (const std::exception& e) {
    std::cerr << "haptic-study: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
