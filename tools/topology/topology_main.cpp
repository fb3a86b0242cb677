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
              {"converged", r.score.converged}};
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "haptic-topology: rank network topologies by |lambda_{n+1}(J)| (Huang & Lee eq. 27) from a\n"
      "delay matrix (ms, row i receives from column j), and give each user's eq. (18) round-trip sum."};
  bool paper = false;
  std::string delays_text, delays_file, summary_file, graphs_text, gains_file, json_out, png_out;
  int users = 0;
  std::uint64_t seed = 1;
  double period_ms = 2.0;
  int links = 0, degree_cap = 0, max_evaluations = 500, top = 20;
  std::uint64_t max_enumerate = 200000;
  bool force_search = false;
  double gain_a = 500.0, gain_b = 500.0;
  std::vector<double> mode_values;
  // eq. (18) defaults: the simulator's (firmware/model/delay_model.hpp).
  // eq. (18) defaults: the paper's impairment (net/impairment.hpp) over the paper-best run's 20 s, the
  // simulator's delay model and passivity budget (firmware/model/passivity_budget.hpp).
  double self_weight = 0.0, jitter_factor = 1.0 + haptic::net::kPaperJitterFraction;
  double loss_probability = haptic::net::kPaperLossProbability, run_s = 20.0;
  int loss_allowance = -1;
  std::string method = "auto";
  topo::SyntheticMap map;

  app.add_flag("--paper", paper, "the paper's Section V delay matrix (default links 3)");
  app.add_option("--delays", delays_text, "mean one-way delay matrix, ms: \"0,4;8,0\" (row i receives from j; inf = no link)");
  app.add_option("--delays-file", delays_file, "JSON N x N array or {\"mean_delay_ms\": [[..]]} (null = no link)");
  app.add_option("--users", users, "synthetic delays for N users on a seeded map (N >= 2)")->check(CLI::Range(2, 100000));
  app.add_option("--seed", seed, "seed of the synthetic map")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--map-width-km", map.width_km, "synthetic map width")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--map-height-km", map.height_km, "synthetic map height")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--base-ms", map.base_ms, "synthetic delay = (base + distance / speed) x asymmetry")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--speed-km-per-ms", map.speed_km_per_ms, "synthetic propagation speed")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--from-summary", summary_file,
                 "rank with the measured link_stats of a run (run/summary.json); nominal delays, if given, fill unmeasured pairs");
  app.add_option("--period-ms", period_ms, "integration step T, ms (> 0)")->capture_default_str();
  app.add_option("--links", links, "undirected links in every feasible graph (default N-1; paper: 3)")->check(haptic::platform::kNonNegative);
  app.add_option("--degree-cap", degree_cap, "max links per user (0 = none)")->capture_default_str();
  app.add_option("--graphs", graphs_text, "listed feasible set: \"1-2,1-3,1-4;1-2,2-4,3-4\"");
  app.add_flag("--search", force_search, "heuristic search even if enumeration is possible");
  app.add_option("--max-enumerate", max_enumerate, "enumerate when C(pairs, links) <= this, else search")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--max-evaluations", max_evaluations, "search budget of eq. (27) evaluations")->capture_default_str()->check(haptic::platform::kPositive);
  topo::SearchOptions search_opt;
  app.add_option("--hub-seeds", search_opt.hub_seeds, "search: shortest-path-tree seeds from the most central users")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--remove-candidates", search_opt.remove_candidates, "search: links tried for removal per pass")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--add-candidates", search_opt.add_candidates, "search: reconnecting links tried per removal")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--kicks", search_opt.kicks, "search: iterated-local-search restarts from the best")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--kick-swaps", search_opt.kick_swaps, "search: random swaps per kick")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--search-seed", search_opt.seed, "search: seed of the kicks")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--gain-a", gain_a, "uniform P_ij = a I + b K_hat: a")->capture_default_str();
  app.add_option("--gain-b", gain_b, "uniform P_ij = a I + b K_hat: b")->capture_default_str();
  app.add_option("--mode-values", mode_values, "eigenvalues of K_hat (e.g. K_int / lambda_max)")->delimiter(',');
  bool paper_scene = false;
  app.add_flag("--paper-scene", paper_scene,
               "mode values = eigenvalues of K_int / lambda_max(K_int) of the paper's 33-node ball (rt/scene.hpp), n = 99");
  app.add_option("--gains-file", gains_file, "per-edge gains JSON (polynomial a, b, mode_values; or dense blocks)");
  app.add_option("--self-weight", self_weight, "s in [0,1): p_i(k+1) = s p_i(k) + (1-s) mix; 0 = paper")->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--method", method, "eigenvalue method: auto|dense|power|arnoldi")->capture_default_str();
  app.add_option("--jitter-factor", jitter_factor, "eq. (18): Nbar_ij = ceil(factor mean / T) + loss allowance")->capture_default_str();
  app.add_option("--loss-allowance", loss_allowance,
                 "eq. (18): extra steps per direction for lost packets; -1: from the loss model (--loss, --run-s), as the simulator")
      ->capture_default_str();
  app.add_option("--loss", loss_probability, "eq. (18), --loss-allowance -1: loss probability per packet (the paper's 5 %)")->capture_default_str()->check(CLI::Range(0.0, 0.999));
  app.add_option("--run-s", run_s, "eq. (18), --loss-allowance -1: run length the allowance covers (s; paper-best's 20 s)")->capture_default_str()->check(haptic::platform::kPositive);
  app.add_option("--top", top, "rows printed at each end of the ranked table")->capture_default_str()->check(haptic::platform::kNonNegative);
  app.add_option("--json", json_out, "write the ranked table as JSON");
  app.add_option("--png", png_out, "draw the best and worst graphs (runs /usr/bin/python3 plot_topology.py)");
  haptic::platform::add_version_flag(app, "haptic-topology");
  // --help/--version: 0; a usage error (an unknown option with "did you mean"): 2, like a bad value below.
  if (const int rc = haptic::platform::parse_command_line(app, argc, argv, 2); rc >= 0) return rc;

  try {
    const auto t_start = std::chrono::steady_clock::now();
    if (!(period_ms > 0)) throw std::invalid_argument("--period-ms: must be > 0");
    const double period_s = period_ms * 1e-3;
    if (!(jitter_factor >= 1.0)) throw std::invalid_argument("--jitter-factor: must be >= 1");
    if (loss_allowance < -1) throw std::invalid_argument("--loss-allowance: must be >= 0 (-1: from the loss model)");
    if (!(loss_probability >= 0 && loss_probability < 1)) throw std::invalid_argument("--loss: must be in [0, 1)");
    if (!(run_s > 0)) throw std::invalid_argument("--run-s: must be > 0");
    if (degree_cap < 0) throw std::invalid_argument("--degree-cap: must be >= 0");
    topo::EigenMethod em = topo::EigenMethod::Auto;
    if (method == "dense") em = topo::EigenMethod::Dense;
    else if (method == "power") em = topo::EigenMethod::Power;
    else if (method == "arnoldi") em = topo::EigenMethod::Arnoldi;
    else if (method != "auto") throw std::invalid_argument("--method: one of auto, dense, power, arnoldi");

    // delays
    Eigen::MatrixXd nominal, positions;
    std::string source;
    if (paper) {
      nominal = topo::paper_delay_matrix_ms();
      source = "paper Section V";
      if (links == 0) links = 3;
    } else if (!delays_text.empty()) {
      nominal = haptic::model::parse_delay_matrix(delays_text, "--delays");
      source = "--delays";
    } else if (!delays_file.empty()) {
      nominal = tio::read_delay_file(delays_file);
      source = delays_file;
    } else if (users > 0) {
      map.seed = seed;
      nominal = topo::synthetic_delays_ms(users, map, &positions);
      source = "synthetic map seed " + std::to_string(seed);
    }
    Eigen::MatrixXd rank_delay = nominal;         // means for N_ij
    Eigen::MatrixXd eq18_delay = nominal;         // delays entering eq. (18) with eq18_factor
    double eq18_factor = jitter_factor;
    if (!summary_file.empty()) {
      const tio::MeasuredLinks m = tio::read_summary(summary_file, static_cast<int>(nominal.rows()));
      const int n = static_cast<int>(m.mean_delay_ms.rows());
      if (nominal.size() > 0 && nominal.rows() != n) throw std::invalid_argument("--from-summary: user count differs from the nominal matrix");
      rank_delay = tio::effective_mean_delay_ms(m, period_s);
      eq18_delay = m.max_delay_ms;
      eq18_factor = 1.0;
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          if (!std::isfinite(rank_delay(i, j)) && nominal.size() > 0) {
            rank_delay(i, j) = nominal(i, j);
            eq18_delay(i, j) = jitter_factor * nominal(i, j);
          }
        }
      }
      source = "measured link_stats of " + summary_file + " (" + std::to_string(m.entries) + " directed links)" +
               (nominal.size() > 0 ? ", nominal " + source + " for unmeasured pairs" : "");
    }
    if (rank_delay.size() == 0) {
      throw std::invalid_argument("delays: give one of --paper, --delays, --delays-file, --users or --from-summary");
    }
    const int n = static_cast<int>(rank_delay.rows());
    if (n < 2) throw std::invalid_argument("delays: need N >= 2 users");

    // gains
    topo::PolynomialGains poly;
    tio::GainFile gf;
    bool dense_gains = false;
    if (!gains_file.empty()) {
      gf = tio::read_gain_file(gains_file, n);
      dense_gains = gf.dense;
      poly = gf.poly;
    } else {
      poly = topo::uniform_gains(n, gain_a, gain_b,
                                 Eigen::Map<const Eigen::VectorXd>(mode_values.data(), static_cast<Eigen::Index>(mode_values.size())));
    }
    if (paper_scene) {
      const haptic::rt::Scene scene = haptic::rt::build_scene(haptic::rt::make_paper_ball(), haptic::rt::SceneParams{});
      const Eigen::MatrixXd k = Eigen::MatrixXd(scene.K_int.S);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(k, Eigen::EigenvaluesOnly);
      const Eigen::VectorXd ev = es.eigenvalues() / es.eigenvalues().maxCoeff();
      const int rep = scene.K_int.is_isotropic() ? 3 : 1;  // S (x) I3: each node-level mode 3 times
      Eigen::VectorXd modes(ev.size() * rep);
      for (Eigen::Index i = 0; i < ev.size(); ++i) modes.segment(i * rep, rep).setConstant(ev(i));
      if (!dense_gains && poly.mode_values.size() == 0) poly.mode_values = modes;
      source += ", K_hat modes of the paper's " + std::to_string(scene.nodes) + "-node ball (n = " +
                std::to_string(modes.size()) + ")";
    }
    topo::SpectrumOptions so;
    so.method = em;
    so.self_weight = self_weight;
    auto score = [&](const topo::Graph& g) {
      return dense_gains ? topo::score_graph_dense(g, rank_delay, period_s, gf.blocks, so)
                         : topo::score_graph(g, rank_delay, period_s, poly, so);
    };

    // feasible set
    Eigen::MatrixXi allowed = Eigen::MatrixXi::Ones(n, n);
    int available_pairs = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        if (i != j && !(std::isfinite(rank_delay(i, j)) && std::isfinite(rank_delay(j, i)))) allowed(i, j) = 0;
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) available_pairs += allowed(i, j);
    if (links == 0) links = n - 1;
    std::vector<Row> rows;
    std::string feasible, mode;
    topo::SearchResult sr;
    bool searched = false;
    if (!graphs_text.empty()) {
      std::istringstream gs(graphs_text);
      std::string one;
      while (std::getline(gs, one, ';')) {
        if (one.find_first_not_of(" \t") == std::string::npos) continue;
        rows.push_back({topo::parse_graph_1based(one, n), {}, {}, "", 0});
      }
      feasible = "listed set of " + std::to_string(rows.size()) + " graphs";
      mode = "evaluate listed";
    } else {
      double combos = 1.0;  // C(available_pairs, links), capped
      for (int k = 1; k <= links && combos <= 1e18; ++k) combos = combos * (available_pairs - links + k) / k;
      if (!force_search && dense_gains == false && combos > static_cast<double>(max_enumerate)) force_search = true;
      if (!force_search || dense_gains) {
        for (auto& g : topo::enumerate_connected_graphs(n, links, degree_cap, max_enumerate, allowed)) rows.push_back({g, {}, {}, "", 0});
        feasible = "all connected graphs with " + std::to_string(links) + " links" +
                   (degree_cap > 0 ? ", degree <= " + std::to_string(degree_cap) : "") + " (" + std::to_string(rows.size()) + ")";
        mode = "enumeration";
      } else {
        topo::SearchOptions opt = search_opt;
        opt.links = links;
        opt.degree_cap = degree_cap;
        opt.max_evaluations = max_evaluations;
        sr = topo::search_topology(rank_delay, period_s, poly, so, opt);
        searched = true;
        rows.push_back({sr.best, sr.best_score, {}, "best after local search", 0});
        rows.push_back({sr.seed, sr.seed_score, {}, "greedy seed", 0});
        feasible = "connected graphs with " + std::to_string(links) + " links" +
                   (degree_cap > 0 ? ", degree <= " + std::to_string(degree_cap) : "") +
                   " (C(" + std::to_string(available_pairs) + "," + std::to_string(links) + ") ~ " +
                   [&] { std::ostringstream o; o.precision(3); o << combos; return o.str(); }() + " link subsets)";
        mode = "search: capped MST / shortest-path-tree seeds + edge-swap local search + " +
               std::to_string(opt.kicks) + " kicks (" +
               std::to_string(sr.evaluations) + " evaluations, " + std::to_string(sr.improvements) + " improvements)";
      }
    }
    if (rows.empty()) throw std::invalid_argument("feasible set is empty (check --links, --degree-cap, --graphs)");
    if (!searched) {
      for (auto& r : rows) r.score = score(r.graph);
    }
    // eq. (18) sums with the simulator's and the station's delay model (firmware/model).
    // The loss allowance covers each graph's own directed links (model::delay_model_allowances).
    for (auto& r : rows) {
      r.loss_allowance = haptic::model::delay_model_allowances(loss_allowance, loss_probability, run_s, period_s,
                                                               2 * static_cast<int>(r.graph.size()), 0, {}).loss_ticks;
      const Eigen::MatrixXi nbar = haptic::model::index_delay_bounds_ticks(eq18_delay, eq18_factor - 1.0, period_s, r.loss_allowance);
      r.eq18_ms = haptic::model::round_trip_half_sums_ms(r.graph, nbar, period_s);
    }
    // rank: |lambda_{n+1}| ascending; ties (periodic graphs all at 1) by the largest eq. (18) sum
    if (!searched) {
      std::stable_sort(rows.begin(), rows.end(), [](const Row& x, const Row& y) {
        if (std::abs(x.score.lambda_next_abs - y.score.lambda_next_abs) > 1e-9) return x.score.lambda_next_abs < y.score.lambda_next_abs;
        if (x.eq18_ms.maxCoeff() != y.eq18_ms.maxCoeff()) return x.eq18_ms.maxCoeff() < y.eq18_ms.maxCoeff();
        return x.eq18_ms.sum() < y.eq18_ms.sum();
      });
      rows.front().label = "best";
      if (rows.size() > 1) rows.back().label = "worst";
    }
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();

    // report
    const auto& s0 = rows.front().score;
    std::printf("haptic-topology: %d users, T = %g ms, delays: %s\n", n, period_ms, source.c_str());
    std::printf("feasible set: %s; %s\n", feasible.c_str(), mode.c_str());
    int n_single = 0, n_split = 0, n_dense = 0, max_modes = 0;
    for (const auto& r : rows) {
      n_single += r.score.path == topo::StructurePath::SingleMode;
      n_split += r.score.path == topo::StructurePath::ModeSplit;
      n_dense += r.score.path == topo::StructurePath::GeneralDense;
      max_modes = std::max(max_modes, r.score.modes_evaluated);
    }
    std::printf("structure: %s for the best; over the table: %d single-mode, %d mode-split (up to %d modes), %d general dense\n",
                topo::to_string(s0.path), n_single, n_split, max_modes, n_dense);
    std::printf("eigenvalue method: %s for the best (lifted size %d, Nbar %d); auto = dense up to size %d, power above\n",
                topo::to_string(s0.method), s0.lifted_size, s0.nbar, so.dense_max_size);
    std::printf("mixing model: self weight s = %g%s\n", self_weight,
                self_weight == 0.0 ? " (paper-literal; graphs whose delay cycles share a common factor are periodic, |lambda| = 1)" : "");
    std::printf("tau = -T / ln|lambda_n+1|: time constant of the non-consensus residual of the mixing model\n");
    std::printf("eq. (18) sums: sum_j (Nbar_ij + Nbar_ji) T/2 per user, Nbar = ceil(%g x %s / T) + %d (the best's loss allowance, ",
                eq18_factor, summary_file.empty() ? "mean" : "measured max", rows.front().loss_allowance);
    if (loss_allowance >= 0) std::printf("given)\n");
    else std::printf("from %g loss over %g s)\n", loss_probability, run_s);
    std::printf("time: %.3f s (%zu graphs scored%s)\n\n", elapsed, searched ? static_cast<std::size_t>(sr.evaluations) : rows.size(),
                searched ? " in the search" : "");
    std::printf("rank  links (1-based)               |lambda_n+1|  tau (ms)   method  eq.(18) round-trip sum per user, ms\n");
    const int nrows = static_cast<int>(rows.size());
    for (int i = 0; i < nrows; ++i) {
      if (nrows > 2 * top && i == top) std::printf("   ... (%d rows)\n", nrows - 2 * top);
      if (nrows > 2 * top && i >= top && i < nrows - top) continue;
      print_row(rows[i], i + 1, period_ms);
    }
    bool all_conv = true;
    for (const auto& r : rows) all_conv = all_conv && r.score.converged;
    if (!all_conv) std::printf("WARNING: some eigenvalue iterations did not converge (column 'converged' in the JSON)\n");

    if (!json_out.empty() || !png_out.empty()) {
      json out;
      out["tool"] = "haptic-topology";
      out["users"] = n;
      out["period_ms"] = period_ms;
      out["delay_source"] = source;
      out["mean_delay_ms"] = matrix_json(rank_delay);
      out["eq18_delay_ms"] = matrix_json(eq18_delay);
      out["eq18_factor"] = eq18_factor;
      out["loss_allowance_steps"] = rows.front().loss_allowance;  // the best's (each row: its own)
      out["self_weight"] = self_weight;
      out["feasible_set"] = feasible;
      out["mode"] = mode;
      out["structure_path"] = topo::to_string(s0.path);
      out["time_s"] = elapsed;
      if (positions.size() > 0) {
        json p = json::array();
        for (Eigen::Index i = 0; i < positions.rows(); ++i) p.push_back({positions(i, 0), positions(i, 1)});
        out["positions_km"] = p;
      }
      json ranked = json::array();
      for (int i = 0; i < nrows; ++i) ranked.push_back(row_json(rows[i], i + 1, period_ms));
      out["ranked"] = ranked;
      if (searched) {
        out["search"] = {{"evaluations", sr.evaluations}, {"improvements", sr.improvements}, {"history", sr.history}};
      }
      std::string jpath = json_out.empty() ? png_out + ".json" : json_out;
      std::ofstream f(jpath);
      if (!f) throw std::invalid_argument("--json: cannot write '" + jpath + "'");
      f << (n <= 8 ? out.dump(1) : out.dump()) << '\n';  // compact for large N
      f.close();
      if (!json_out.empty()) std::printf("\nwrote %s\n", json_out.c_str());
      if (!png_out.empty()) {
        const std::string script = haptic::platform::tools_dir() + "/topology/plot_topology.py";
        const std::string cmd = "/usr/bin/python3 '" + script + "' '" + jpath + "' '" + png_out + "'";
        const int rc = std::system(cmd.c_str());
        if (rc != 0) {
          std::fprintf(stderr, "haptic-topology: plotting failed (%s exited %d); needs Debian python3-matplotlib\n", script.c_str(), rc);
          return 3;
        }
        std::printf("wrote %s\n", png_out.c_str());
        if (json_out.empty()) std::remove(jpath.c_str());
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-topology: %s\n", e.what());
    return 2;
  }
  return 0;
}
