// haptic-topology: rank network topologies by |lambda_{n+1}(J(G, P_ij, N_ij))| (eq. 27) for a
// delay matrix, and report each user's eq. (18) round-trip sum. See tools/topology/README.md.
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "firmware/model/graph.hpp"
#include "firmware/model/passivity_budget.hpp"
#include "net/impairment.hpp"
#include "platform/install_paths.hpp"
#include "rt/mesh.hpp"
#include "rt/scene.hpp"
#include "tools/topology/topology.hpp"
#include "tools/topology/topology_io.hpp"
#include "platform/command_line.hpp"

namespace topo = haptic::topology;
namespace tio = haptic::tools::topology;
using nlohmann::json;

namespace {

struct Row {
  topo::Graph graph;
  topo::GraphScore score;
  Eigen::VectorXd eq18_ms;
  std::string label;
  int loss_allowance = 0;  // eq. (18)'s Nbar allowance for lost packets (steps per direction)
  int robustness = -1;     // the largest r for which the graph is r-robust (-1: not computed, N > 20)
};

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    json r = json::array();
    for (Eigen::Index j = 0; j < m.cols(); ++j)  // 0.1 us resolution keeps the files small
      r.push_back(std::isfinite(m(i, j)) ? json(std::round(m(i, j) * 1e4) / 1e4) : json(nullptr));
    rows.push_back(r);
  }
  return rows;
}

double time_constant_ms(double lambda_abs, double period_ms);

json row_json(const Row& r, int rank, double period_ms) {
  json edges = json::array();
  for (const auto& e : r.graph) edges.push_back({e.a + 1, e.b + 1});
  std::vector<double> eq18(r.eq18_ms.data(), r.eq18_ms.data() + r.eq18_ms.size());
  return json{{"rank", rank},
              {"label", r.label},
              {"edges", edges},
              {"lambda_next_abs", r.score.lambda_next_abs},
              {"time_constant_ms", std::isfinite(time_constant_ms(r.score.lambda_next_abs, period_ms))
                                       ? json(time_constant_ms(r.score.lambda_next_abs, period_ms)) : json(nullptr)},
              {"eq18_round_trip_sum_ms", eq18},
              {"nbar", r.score.nbar},
              {"loss_allowance_steps", r.loss_allowance},
              {"lifted_size", r.score.lifted_size},
              {"modes_evaluated", r.score.modes_evaluated},
              {"worst_mode_value", r.score.worst_mode_value},
              {"method", topo::to_string(r.score.method)},
              {"path", topo::to_string(r.score.path)},
              {"converged", r.score.converged},
              {"robustness", r.robustness >= 0 ? json(r.robustness) : json(nullptr)}};
}

std::string fmt_vec(const Eigen::VectorXd& v) {
  std::ostringstream os;
  os << '(';
  for (Eigen::Index i = 0; i < v.size(); ++i) os << (i ? ", " : "") << v(i);
  os << ')';
  return os.str();
}

// Residual time constant of the mixing model: |lambda|^k = e^{-kT/tau}, tau = -T / ln|lambda|.
double time_constant_ms(double lambda_abs, double period_ms) {
  // within 1e-9 of 1 (the ranking tie tolerance): periodic / not converging
  return lambda_abs >= 1.0 - 1e-9 ? std::numeric_limits<double>::infinity() : -period_ms / std::log(lambda_abs);
}

void print_row(const Row& r, int rank, double period_ms) {
  std::printf("%4d  %-28s  %.9f  %9.1f  %-7s %s%s\n", rank, topo::to_string_1based(r.graph).c_str(),
              r.score.lambda_next_abs, time_constant_ms(r.score.lambda_next_abs, period_ms),
              topo::to_string(r.score.method), fmt_vec(r.eq18_ms).c_str(),
              r.label.empty() ? "" : ("  [" + r.label + "]").c_str());
}

// The command line: every option's value (defaults as printed by --help).
struct Options {
  bool paper = false, paper_scene = false, force_search = false;
  std::string delays_text, delays_file, summary_file, graphs_text, gains_file, json_out, png_out;
  int users = 0;
  std::uint64_t seed = 1;
  double period_ms = 2.0;
  int links = 0, degree_cap = 0, max_evaluations = 500, top = 20;
  int robustness = 0;  // feasible graphs are r-robust (0, 1: no constraint)
  std::uint64_t max_enumerate = 200000;
  double gain_a = 500.0, gain_b = 500.0;
  std::vector<double> mode_values;
  // eq. (18) defaults: the paper's impairment (net/impairment.hpp) over the paper-best run's 20 s, the
  // simulator's delay model and passivity budget (firmware/model/passivity_budget.hpp).
  double self_weight = 0.0, jitter_factor = 1.0 + haptic::net::kPaperJitterFraction;
  double loss_probability = haptic::net::kPaperLossProbability, run_s = 20.0;
  int loss_allowance = -1;
  std::string method = "auto";
  topo::SyntheticMap map;
  topo::SearchOptions search_opt;
  topo::EigenMethod eigen_method = topo::EigenMethod::Auto;
  double period_s() const { return period_ms * 1e-3; }
};

void add_delay_options(CLI::App& app, Options& o) {
  app.add_flag("--paper", o.paper, "the paper's Section V delay matrix (default links 3)");
  app.add_option("--delays", o.delays_text, "mean one-way delay matrix, ms: \"0,4;8,0\" (row i receives from j; inf = no link)");
  app.add_option("--delays-file", o.delays_file, "JSON N x N array or {\"mean_delay_ms\": [[..]]} (null = no link)");
  app.add_option("--users", o.users, "synthetic delays for N users on a seeded map (N >= 2)")->check(CLI::Range(2, 100000));
  app.add_option("--seed", o.seed, "seed of the synthetic map")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--map-width-km", o.map.width_km, "synthetic map width")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--map-height-km", o.map.height_km, "synthetic map height")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--base-ms", o.map.base_ms, "synthetic delay = (base + distance / speed) x asymmetry")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--speed-km-per-ms", o.map.speed_km_per_ms, "synthetic propagation speed")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--from-summary", o.summary_file,
                 "rank with the measured link_stats of a run (run/summary.json); nominal delays, if given, fill unmeasured pairs");
  app.add_option("--period-ms", o.period_ms, "integration step T, ms (> 0)")->capture_default_str();
}

void add_graph_options(CLI::App& app, Options& o) {
  app.add_option("--links", o.links, "undirected links in every feasible graph (default N-1; paper: 3)")->check(haptic::platform::kNonNegative);
  app.add_option("--degree-cap", o.degree_cap, "max links per user (0 = none)")->capture_default_str();
  app.add_option("--graphs", o.graphs_text, "listed feasible set: \"1-2,1-3,1-4;1-2,2-4,3-4\"");
  app.add_flag("--search", o.force_search, "heuristic search even if enumeration is possible");
  app.add_option("--robustness", o.robustness,
                 "feasible graphs are r-robust (resilient consensus with F liars, rt/resilient.hpp: r = 2F+1); "
                 "enumeration or --graphs only, N <= 20; the cost against the best without it is printed")
      ->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--max-enumerate", o.max_enumerate, "enumerate when C(pairs, links) <= this, else search")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--max-evaluations", o.max_evaluations, "search budget of eq. (27) evaluations")->capture_default_str()->check(haptic::platform::kPositive);
  topo::SearchOptions& so = o.search_opt;
  app.add_option("--hub-seeds", so.hub_seeds, "search: shortest-path-tree seeds from the most central users")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--remove-candidates", so.remove_candidates, "search: links tried for removal per pass")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--add-candidates", so.add_candidates, "search: reconnecting links tried per removal")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--kicks", so.kicks, "search: iterated-local-search restarts from the best")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--kick-swaps", so.kick_swaps, "search: random swaps per kick")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--search-seed", so.seed, "search: seed of the kicks")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
}

void add_model_options(CLI::App& app, Options& o) {
  app.add_option("--gain-a", o.gain_a, "uniform P_ij = a I + b K_hat: a")->capture_default_str();
  app.add_option("--gain-b", o.gain_b, "uniform P_ij = a I + b K_hat: b")->capture_default_str();
  app.add_option("--mode-values", o.mode_values, "eigenvalues of K_hat (e.g. K_int / lambda_max)")->delimiter(',');
  app.add_flag("--paper-scene", o.paper_scene,
               "mode values = eigenvalues of K_int / lambda_max(K_int) of the paper's 33-node ball (rt/scene.hpp), n = 99");
  app.add_option("--gains-file", o.gains_file, "per-edge gains JSON (polynomial a, b, mode_values; or dense blocks)");
  app.add_option("--self-weight", o.self_weight, "s in [0,1): p_i(k+1) = s p_i(k) + (1-s) mix; 0 = paper")->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--method", o.method, "eigenvalue method: auto|dense|power|arnoldi")->capture_default_str();
  app.add_option("--jitter-factor", o.jitter_factor, "eq. (18): Nbar_ij = ceil(factor mean / T) + loss allowance")->capture_default_str();
  app.add_option("--loss-allowance", o.loss_allowance,
                 "eq. (18): extra steps per direction for lost packets; -1: from the loss model (--loss, --run-s), as the simulator")
      ->capture_default_str();
  app.add_option("--loss", o.loss_probability, "eq. (18), --loss-allowance -1: loss probability per packet (the paper's 5 %)")->capture_default_str()->check(CLI::Range(0.0, 0.999));
  app.add_option("--run-s", o.run_s, "eq. (18), --loss-allowance -1: run length the allowance covers (s; paper-best's 20 s)")->capture_default_str()->check(haptic::platform::kPositive);
}

// Throws std::invalid_argument naming the option.
void validate(Options& o) {
  if (!(o.period_ms > 0)) throw std::invalid_argument("--period-ms: must be > 0");
  if (!(o.jitter_factor >= 1.0)) throw std::invalid_argument("--jitter-factor: must be >= 1");
  if (o.loss_allowance < -1) throw std::invalid_argument("--loss-allowance: must be >= 0 (-1: from the loss model)");
  if (!(o.loss_probability >= 0 && o.loss_probability < 1)) throw std::invalid_argument("--loss: must be in [0, 1)");
  if (!(o.run_s > 0)) throw std::invalid_argument("--run-s: must be > 0");
  if (o.degree_cap < 0) throw std::invalid_argument("--degree-cap: must be >= 0");
  if (o.robustness > 1 && o.force_search) throw std::invalid_argument("--robustness: needs enumeration or --graphs; the search does not keep it (drop --search)");
  if (o.method == "dense") o.eigen_method = topo::EigenMethod::Dense;
  else if (o.method == "power") o.eigen_method = topo::EigenMethod::Power;
  else if (o.method == "arnoldi") o.eigen_method = topo::EigenMethod::Arnoldi;
  else if (o.method != "auto") throw std::invalid_argument("--method: one of auto, dense, power, arnoldi");
}

// The delays the ranking (means, for N_ij) and eq. (18) use, and where they came from.
struct Delays {
  Eigen::MatrixXd rank_delay, eq18_delay, positions;
  double eq18_factor = 1.0;
  std::string source;
};

Eigen::MatrixXd nominal_delays(Options& o, Delays& d) {
  Eigen::MatrixXd nominal;
  if (o.paper) {
    nominal = topo::paper_delay_matrix_ms();
    d.source = "paper Section V";
    if (o.links == 0) o.links = 3;
  } else if (!o.delays_text.empty()) {
    nominal = haptic::model::parse_delay_matrix(o.delays_text, "--delays");
    d.source = "--delays";
  } else if (!o.delays_file.empty()) {
    nominal = tio::read_delay_file(o.delays_file);
    d.source = o.delays_file;
  } else if (o.users > 0) {
    o.map.seed = o.seed;
    nominal = topo::synthetic_delays_ms(o.users, o.map, &d.positions);
    d.source = "synthetic map seed " + std::to_string(o.seed);
  }
  return nominal;
}

Delays load_delays(Options& o) {
  Delays d;
  const Eigen::MatrixXd nominal = nominal_delays(o, d);
  d.rank_delay = nominal;  // means for N_ij
  d.eq18_delay = nominal;  // delays entering eq. (18) with eq18_factor
  d.eq18_factor = o.jitter_factor;
  if (!o.summary_file.empty()) {
    const tio::MeasuredLinks m = tio::read_summary(o.summary_file, static_cast<int>(nominal.rows()));
    const int n = static_cast<int>(m.mean_delay_ms.rows());
    if (nominal.size() > 0 && nominal.rows() != n) throw std::invalid_argument("--from-summary: user count differs from the nominal matrix");
    d.rank_delay = tio::effective_mean_delay_ms(m, o.period_s());
    d.eq18_delay = m.max_delay_ms;
    d.eq18_factor = 1.0;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        if (!std::isfinite(d.rank_delay(i, j)) && nominal.size() > 0) {
          d.rank_delay(i, j) = nominal(i, j);
          d.eq18_delay(i, j) = o.jitter_factor * nominal(i, j);
        }
      }
    }
    d.source = "measured link_stats of " + o.summary_file + " (" + std::to_string(m.entries) + " directed links)" +
               (nominal.size() > 0 ? ", nominal " + d.source + " for unmeasured pairs" : "");
  }
  if (d.rank_delay.size() == 0) {
    throw std::invalid_argument("delays: give one of --paper, --delays, --delays-file, --users or --from-summary");
  }
  if (d.rank_delay.rows() < 2) throw std::invalid_argument("delays: need N >= 2 users");
  return d;
}

// The consensus gains P_ij the spectrum is computed with, and how a graph is scored (eq. 27).
struct Scorer {
  topo::PolynomialGains poly;
  tio::GainFile gf;
  bool dense_gains = false;
  topo::SpectrumOptions so;
  topo::GraphScore operator()(const topo::Graph& g, const Eigen::MatrixXd& rank_delay, double period_s) const {
    return dense_gains ? topo::score_graph_dense(g, rank_delay, period_s, gf.blocks, so)
                       : topo::score_graph(g, rank_delay, period_s, poly, so);
  }
};

Scorer make_scorer(const Options& o, int n, std::string& source) {
  Scorer sc;
  if (!o.gains_file.empty()) {
    sc.gf = tio::read_gain_file(o.gains_file, n);
    sc.dense_gains = sc.gf.dense;
    sc.poly = sc.gf.poly;
  } else {
    sc.poly = topo::uniform_gains(n, o.gain_a, o.gain_b,
                                  Eigen::Map<const Eigen::VectorXd>(o.mode_values.data(), static_cast<Eigen::Index>(o.mode_values.size())));
  }
  if (o.paper_scene) {
    const haptic::rt::Scene scene = haptic::rt::build_scene(haptic::rt::make_paper_ball(), haptic::rt::SceneParams{});
    const Eigen::MatrixXd k = Eigen::MatrixXd(scene.K_int.S);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(k, Eigen::EigenvaluesOnly);
    const Eigen::VectorXd ev = es.eigenvalues() / es.eigenvalues().maxCoeff();
    const int rep = scene.K_int.is_isotropic() ? 3 : 1;  // S (x) I3: each node-level mode 3 times
    Eigen::VectorXd modes(ev.size() * rep);
    for (Eigen::Index i = 0; i < ev.size(); ++i) modes.segment(i * rep, rep).setConstant(ev(i));
    if (!sc.dense_gains && sc.poly.mode_values.size() == 0) sc.poly.mode_values = modes;
    source += ", K_hat modes of the paper's " + std::to_string(scene.nodes) + "-node ball (n = " +
              std::to_string(modes.size()) + ")";
  }
  sc.so.method = o.eigen_method;
  sc.so.self_weight = o.self_weight;
  return sc;
}

// The feasible set: listed graphs, every connected graph, or a heuristic search's best and seed.
struct Ranking {
  std::vector<Row> rows;
  std::string feasible, mode;
  topo::SearchResult sr;
  bool searched = false;
  Row unconstrained_best;   // --robustness: the best of the feasible set without the constraint
  std::size_t unconstrained_count = 0;
};

void search_rows(Options& o, const Delays& d, const Scorer& sc, int available_pairs, double combos, Ranking& rk) {
  topo::SearchOptions opt = o.search_opt;
  opt.links = o.links;
  opt.degree_cap = o.degree_cap;
  opt.max_evaluations = o.max_evaluations;
  rk.sr = topo::search_topology(d.rank_delay, o.period_s(), sc.poly, sc.so, opt);
  rk.searched = true;
  rk.rows.push_back({rk.sr.best, rk.sr.best_score, {}, "best after local search", 0});
  rk.rows.push_back({rk.sr.seed, rk.sr.seed_score, {}, "greedy seed", 0});
  rk.feasible = "connected graphs with " + std::to_string(o.links) + " links" +
                (o.degree_cap > 0 ? ", degree <= " + std::to_string(o.degree_cap) : "") +
                " (C(" + std::to_string(available_pairs) + "," + std::to_string(o.links) + ") ~ " +
                [&] { std::ostringstream os; os.precision(3); os << combos; return os.str(); }() + " link subsets)";
  rk.mode = "search: capped MST / shortest-path-tree seeds + edge-swap local search + " +
            std::to_string(opt.kicks) + " kicks (" +
            std::to_string(rk.sr.evaluations) + " evaluations, " + std::to_string(rk.sr.improvements) + " improvements)";
}

Ranking feasible_rows(Options& o, const Delays& d, const Scorer& sc) {
  const int n = static_cast<int>(d.rank_delay.rows());
  Eigen::MatrixXi allowed = Eigen::MatrixXi::Ones(n, n);
  int available_pairs = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      if (i != j && !(std::isfinite(d.rank_delay(i, j)) && std::isfinite(d.rank_delay(j, i)))) allowed(i, j) = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) available_pairs += allowed(i, j);
  if (o.links == 0) o.links = n - 1;
  Ranking rk;
  if (!o.graphs_text.empty()) {
    std::istringstream gs(o.graphs_text);
    std::string one;
    while (std::getline(gs, one, ';')) {
      if (one.find_first_not_of(" \t") == std::string::npos) continue;
      rk.rows.push_back({topo::parse_graph_1based(one, n), {}, {}, "", 0});
    }
    rk.feasible = "listed set of " + std::to_string(rk.rows.size()) + " graphs";
    rk.mode = "evaluate listed";
    return rk;
  }
  double combos = 1.0;  // C(available_pairs, links), capped
  for (int k = 1; k <= o.links && combos <= 1e18; ++k) combos = combos * (available_pairs - o.links + k) / k;
  if (!o.force_search && sc.dense_gains == false && combos > static_cast<double>(o.max_enumerate)) o.force_search = true;
  if (o.force_search && !sc.dense_gains) {
    if (o.robustness > 1)
      throw std::invalid_argument("--robustness: C(" + std::to_string(available_pairs) + "," + std::to_string(o.links) +
                                  ") link subsets exceed --max-enumerate, and the search does not keep the constraint");
    search_rows(o, d, sc, available_pairs, combos, rk);
    return rk;
  }
  for (auto& g : topo::enumerate_connected_graphs(n, o.links, o.degree_cap, o.max_enumerate, allowed)) rk.rows.push_back({g, {}, {}, "", 0});
  rk.feasible = "all connected graphs with " + std::to_string(o.links) + " links" +
                (o.degree_cap > 0 ? ", degree <= " + std::to_string(o.degree_cap) : "") + " (" + std::to_string(rk.rows.size()) + ")";
  rk.mode = "enumeration";
  return rk;
}

// Each row's robustness (N <= 20); with --robustness r > 1, the ranked rows keep the r-robust graphs
// only and the best of all is kept for the cost line. Throws when none is r-robust.
void apply_robustness(const Options& o, int n, Ranking& rk) {
  if (n > haptic::model::kMaxRobustnessUsers) return;
  for (auto& r : rk.rows) r.robustness = haptic::model::robustness(r.graph, n, "--robustness");
  if (o.robustness <= 1) return;
  rk.unconstrained_best = rk.rows.front();
  rk.unconstrained_count = rk.rows.size();
  std::erase_if(rk.rows, [&](const Row& r) { return r.robustness < o.robustness; });
  if (rk.rows.empty())
    throw std::invalid_argument("--robustness " + std::to_string(o.robustness) + ": none of the " + std::to_string(rk.unconstrained_count) +
                                " feasible graphs is " + std::to_string(o.robustness) + "-robust (" + std::to_string(n) + " users: at least " +
                                std::to_string((o.robustness * n + 1) / 2) + " links, every degree >= " + std::to_string(o.robustness) +
                                ((n + 1) / 2 < o.robustness ? "; even K_" + std::to_string(n) + " is only " + std::to_string((n + 1) / 2) + "-robust" : "") + ")");
}

// Scores (eq. 27) and eq. (18) sums of every row, then the ranking.
void score_and_rank(const Options& o, const Delays& d, const Scorer& sc, Ranking& rk) {
  if (rk.rows.empty()) throw std::invalid_argument("feasible set is empty (check --links, --degree-cap, --graphs)");
  if (!rk.searched) {
    for (auto& r : rk.rows) r.score = sc(r.graph, d.rank_delay, o.period_s());
  }
  // eq. (18) sums with the simulator's and the station's delay model (firmware/model).
  // The loss allowance covers each graph's own directed links (model::delay_model_allowances).
  for (auto& r : rk.rows) {
    r.loss_allowance = haptic::model::delay_model_allowances(o.loss_allowance, haptic::model::LossModel{o.loss_probability}, o.run_s, o.period_s(),
                                                             2 * static_cast<int>(r.graph.size()), {}, {}).loss_ticks;
    const Eigen::MatrixXi nbar = haptic::model::index_delay_bounds_ticks(d.eq18_delay, d.eq18_factor - 1.0, o.period_s(), r.loss_allowance);
    r.eq18_ms = haptic::model::round_trip_half_sums_ms(r.graph, nbar, o.period_s());
  }
  // rank: |lambda_{n+1}| ascending; ties (periodic graphs all at 1) by the largest eq. (18) sum
  if (!rk.searched) {
    std::stable_sort(rk.rows.begin(), rk.rows.end(), [](const Row& x, const Row& y) {
      if (std::abs(x.score.lambda_next_abs - y.score.lambda_next_abs) > 1e-9) return x.score.lambda_next_abs < y.score.lambda_next_abs;
      if (x.eq18_ms.maxCoeff() != y.eq18_ms.maxCoeff()) return x.eq18_ms.maxCoeff() < y.eq18_ms.maxCoeff();
      return x.eq18_ms.sum() < y.eq18_ms.sum();
    });
    apply_robustness(o, static_cast<int>(d.rank_delay.rows()), rk);
    rk.rows.front().label = "best";
    if (rk.rows.size() > 1) rk.rows.back().label = "worst";
  }
}

void print_header(const Options& o, const Delays& d, const Scorer& sc, const Ranking& rk, double elapsed) {
  const int n = static_cast<int>(d.rank_delay.rows());
  const auto& s0 = rk.rows.front().score;
  std::printf("haptic-topology: %d users, T = %g ms, delays: %s\n", n, o.period_ms, d.source.c_str());
  std::printf("feasible set: %s; %s\n", rk.feasible.c_str(), rk.mode.c_str());
  int n_single = 0, n_split = 0, n_dense = 0, max_modes = 0;
  for (const auto& r : rk.rows) {
    n_single += r.score.path == topo::StructurePath::SingleMode;
    n_split += r.score.path == topo::StructurePath::ModeSplit;
    n_dense += r.score.path == topo::StructurePath::GeneralDense;
    max_modes = std::max(max_modes, r.score.modes_evaluated);
  }
  std::printf("structure: %s for the best; over the table: %d single-mode, %d mode-split (up to %d modes), %d general dense\n",
              topo::to_string(s0.path), n_single, n_split, max_modes, n_dense);
  std::printf("eigenvalue method: %s for the best (lifted size %d, Nbar %d); auto = dense up to size %d, power above\n",
              topo::to_string(s0.method), s0.lifted_size, s0.nbar, sc.so.dense_max_size);
  std::printf("mixing model: self weight s = %g%s\n", o.self_weight,
              o.self_weight == 0.0 ? " (paper-literal; graphs whose delay cycles share a common factor are periodic, |lambda| = 1)" : "");
  std::printf("tau = -T / ln|lambda_n+1|: time constant of the non-consensus residual of the mixing model\n");
  std::printf("eq. (18) sums: sum_j (Nbar_ij + Nbar_ji) T/2 per user, Nbar = ceil(%g x %s / T) + %d (the best's loss allowance, ",
              d.eq18_factor, o.summary_file.empty() ? "mean" : "measured max", rk.rows.front().loss_allowance);
  if (o.loss_allowance >= 0) std::printf("given)\n");
  else std::printf("from %g loss over %g s)\n", o.loss_probability, o.run_s);
  if (o.robustness > 1) {
    const auto& u = rk.unconstrained_best;
    const auto& b = rk.rows.front();
    std::printf("robustness constraint: %d-robust (resilient consensus with F = %d liars): %zu of %zu graphs; best |lambda_n+1| %.9f "
                "(tau %.1f ms) against %.9f (tau %.1f ms, %s, %d-robust) without it\n",
                o.robustness, (o.robustness - 1) / 2, rk.rows.size(), rk.unconstrained_count, b.score.lambda_next_abs,
                time_constant_ms(b.score.lambda_next_abs, o.period_ms), u.score.lambda_next_abs,
                time_constant_ms(u.score.lambda_next_abs, o.period_ms), topo::to_string_1based(u.graph).c_str(), u.robustness);
  }
  const std::size_t scored = rk.searched ? static_cast<std::size_t>(rk.sr.evaluations) : std::max(rk.rows.size(), rk.unconstrained_count);
  std::printf("time: %.3f s (%zu graphs scored%s)\n\n", elapsed, scored,
              rk.searched ? " in the search" : "");
}

void print_table(const Options& o, const Ranking& rk) {
  std::printf("rank  links (1-based)               |lambda_n+1|  tau (ms)   method  eq.(18) round-trip sum per user, ms\n");
  const int nrows = static_cast<int>(rk.rows.size());
  for (int i = 0; i < nrows; ++i) {
    if (nrows > 2 * o.top && i == o.top) std::printf("   ... (%d rows)\n", nrows - 2 * o.top);
    if (nrows > 2 * o.top && i >= o.top && i < nrows - o.top) continue;
    print_row(rk.rows[i], i + 1, o.period_ms);
  }
  bool all_conv = true;
  for (const auto& r : rk.rows) all_conv = all_conv && r.score.converged;
  if (!all_conv) std::printf("WARNING: some eigenvalue iterations did not converge (column 'converged' in the JSON)\n");
}

json ranking_json(const Options& o, const Delays& d, const Ranking& rk, double elapsed) {
  json out;
  out["tool"] = "haptic-topology";
  out["users"] = static_cast<int>(d.rank_delay.rows());
  out["period_ms"] = o.period_ms;
  out["delay_source"] = d.source;
  out["mean_delay_ms"] = matrix_json(d.rank_delay);
  out["eq18_delay_ms"] = matrix_json(d.eq18_delay);
  out["eq18_factor"] = d.eq18_factor;
  out["loss_allowance_steps"] = rk.rows.front().loss_allowance;  // the best's (each row: its own)
  out["self_weight"] = o.self_weight;
  out["feasible_set"] = rk.feasible;
  if (o.robustness > 1) {
    out["robustness_required"] = o.robustness;
    out["unconstrained_count"] = rk.unconstrained_count;
    out["unconstrained_best"] = row_json(rk.unconstrained_best, 1, o.period_ms);
  }
  out["mode"] = rk.mode;
  out["structure_path"] = topo::to_string(rk.rows.front().score.path);
  out["time_s"] = elapsed;
  if (d.positions.size() > 0) {
    json p = json::array();
    for (Eigen::Index i = 0; i < d.positions.rows(); ++i) p.push_back({d.positions(i, 0), d.positions(i, 1)});
    out["positions_km"] = p;
  }
  json ranked = json::array();
  for (int i = 0; i < static_cast<int>(rk.rows.size()); ++i) ranked.push_back(row_json(rk.rows[i], i + 1, o.period_ms));
  out["ranked"] = ranked;
  if (rk.searched) {
    out["search"] = {{"evaluations", rk.sr.evaluations}, {"improvements", rk.sr.improvements}, {"history", rk.sr.history}};
  }
  return out;
}

// --json and --png; returns the exit code (3: plotting failed).
int write_outputs(const Options& o, const Delays& d, const Ranking& rk, double elapsed) {
  if (o.json_out.empty() && o.png_out.empty()) return 0;
  const json out = ranking_json(o, d, rk, elapsed);
  const std::string jpath = o.json_out.empty() ? o.png_out + ".json" : o.json_out;
  std::ofstream f(jpath);
  if (!f) throw std::invalid_argument("--json: cannot write '" + jpath + "'");
  f << (d.rank_delay.rows() <= 8 ? out.dump(1) : out.dump()) << '\n';  // compact for large N
  f.close();
  if (!o.json_out.empty()) std::printf("\nwrote %s\n", o.json_out.c_str());
  if (o.png_out.empty()) return 0;
  const std::string script = haptic::platform::tools_dir() + "/topology/plot_topology.py";
  const std::string cmd = "/usr/bin/python3 '" + script + "' '" + jpath + "' '" + o.png_out + "'";
  const int rc = std::system(cmd.c_str());
  if (rc != 0) {
    std::fprintf(stderr, "haptic-topology: plotting failed (%s exited %d); needs Debian python3-matplotlib\n", script.c_str(), rc);
    return 3;
  }
  std::printf("wrote %s\n", o.png_out.c_str());
  if (o.json_out.empty()) std::remove(jpath.c_str());
  return 0;
}

int run(Options& o) {
  const auto t_start = std::chrono::steady_clock::now();
  validate(o);
  Delays d = load_delays(o);
  const Scorer sc = make_scorer(o, static_cast<int>(d.rank_delay.rows()), d.source);
  Ranking rk = feasible_rows(o, d, sc);
  score_and_rank(o, d, sc, rk);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  print_header(o, d, sc, rk, elapsed);
  print_table(o, rk);
  return write_outputs(o, d, rk, elapsed);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "haptic-topology: rank network topologies by |lambda_{n+1}(J)| (Huang & Lee eq. 27) from a\n"
      "delay matrix (ms, row i receives from column j), and give each user's eq. (18) round-trip sum."};
  Options o;
  add_delay_options(app, o);
  add_graph_options(app, o);
  add_model_options(app, o);
  app.add_option("--top", o.top, "rows printed at each end of the ranked table")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--json", o.json_out, "write the ranked table as JSON");
  app.add_option("--png", o.png_out, "draw the best and worst graphs (runs /usr/bin/python3 plot_topology.py)");
  haptic::platform::add_version_flag(app, "haptic-topology");
  // --help/--version: 0; a usage error (an unknown option with "did you mean"): 2, like a bad value below.
  if (const int rc = haptic::platform::parse_command_line(app, argc, argv, 2); rc >= 0) return rc;
  try {
    return run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-topology: %s\n", e.what());
    return 2;
  }
}
