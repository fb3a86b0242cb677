// Topology optimization, eq. (27): the mechanics of the lifted matrix and of the solvers.
// Eigen before CppUTest: CppUTest's leak-detector macros redefine operator new.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "tools/topology/topology.hpp"

#include <CppUTest/TestHarness.h>

using namespace haptic::topology;

namespace {

int count_near_one(const Eigen::VectorXcd& ev, double tol) {
  int c = 0;
  for (Eigen::Index i = 0; i < ev.size(); ++i) c += std::abs(ev(i) - 1.0) < tol ? 1 : 0;
  return c;
}

// Normalized Laplacian of a path of `n` nodes (a small stand-in for K_int / lambda_max).
Eigen::MatrixXd path_k_hat(int n) {
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i + 1 < n; ++i) {
    k(i, i) += 1;
    k(i + 1, i + 1) += 1;
    k(i, i + 1) -= 1;
    k(i + 1, i) -= 1;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(k);
  return k / es.eigenvalues().maxCoeff();
}

Eigen::MatrixXd small_delays() {
  Eigen::MatrixXd d(4, 4);
  d << 0, 4, 7, 3, 5, 0, 9, 6, 2, 11, 0, 4, 6, 3, 8, 0;
  return d;
}

}  // namespace

TEST_GROUP(LiftedMatrix){};

TEST(LiftedMatrix, ConnectedGraphHasOneEigenvalueAtOneAndTheRestStrictlyInside) {
  const Eigen::MatrixXd d = small_delays();
  const Eigen::MatrixXi steps = haptic::model::mean_delay_steps(d, 0.002);
  for (const Graph& g : enumerate_connected_graphs(4, 4, 0, 1000)) {
    const Eigen::MatrixXd w = mixing_weights(g, 4, Eigen::MatrixXd::Ones(4, 4));
    const Eigen::VectorXcd ev = eigenvalues_by_modulus(lifted_scalar_matrix(g, w, steps, 0.3));
    LONGS_EQUAL(1, count_near_one(ev, 1e-8));
    CHECK(std::abs(ev(1)) < 1.0 - 1e-6);
  }
}

TEST(LiftedMatrix, MatrixStateHasNEigenvaluesAtOneWithConsensusEigenvectors) {
  const int n = 3;
  const Eigen::MatrixXd kh = path_k_hat(n);
  DenseGains dg;
  dg.n = n;
  dg.blocks.assign(16, Eigen::MatrixXd::Identity(n, n));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      dg.blocks[i * 4 + j] = (1.0 + 0.3 * i + 0.1 * j) * Eigen::MatrixXd::Identity(n, n) + (0.5 + 0.2 * j) * kh;
  const Graph g = parse_graph_1based("1-2,1-3,1-4,2-3", 4);
  const Eigen::MatrixXi steps = haptic::model::mean_delay_steps(small_delays(), 0.002);
  const Eigen::MatrixXd J = lifted_dense_matrix(g, 4, dg, steps, 0.0);
  const Eigen::VectorXcd ev = eigenvalues_by_modulus(J);
  LONGS_EQUAL(n, count_near_one(ev, 1e-7));
  CHECK(std::abs(ev(n)) < 1.0 - 1e-6);
  // 1_{Nbar+1} (x) 1_N (x) a is a fixed point for any a
  const Eigen::Vector3d a(0.3, -1.2, 2.0);
  Eigen::VectorXd x(J.rows());
  for (Eigen::Index b = 0; b < J.rows() / n; ++b) x.segment(b * n, n) = a;
  DOUBLES_EQUAL(0.0, (J * x - x).norm(), 1e-12);
}

TEST(LiftedMatrix, PaperLiteralModelIsPeriodicWhenEveryCycleLengthSharesAFactor) {
  // Without self weight, two users exchanging over one link just copy each other:
  // p1(k+1) = p2(k - N12): every eigenvalue is a root of unity, |lambda_2| = 1.
  Eigen::MatrixXd d(2, 2);
  d << 0, 6, 10, 0;
  const Graph g = parse_graph_1based("1-2", 2);
  SpectrumOptions opt;
  opt.method = EigenMethod::Dense;
  DOUBLES_EQUAL(1.0, score_graph(g, d, 0.002, uniform_gains(2, 1, 0, {}), opt).lambda_next_abs, 1e-9);
  opt.self_weight = 0.5;  // a lazy (self-including) mixing is aperiodic
  CHECK(score_graph(g, d, 0.002, uniform_gains(2, 1, 0, {}), opt).lambda_next_abs < 0.99);
}

TEST(LiftedMatrix, RankingIsInvariantUnderRelabellingTheUsers) {
  const Eigen::MatrixXd d = paper_delay_matrix_ms();
  const int perm[4] = {2, 0, 3, 1};  // new label of old user i
  Eigen::MatrixXd dp(4, 4);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) dp(perm[i], perm[j]) = d(i, j);
  SpectrumOptions opt;
  opt.self_weight = 0.25;
  for (const Graph& g : enumerate_connected_graphs(4, 3, 0, 100)) {
    Graph gp;
    for (const Edge& e : g) gp.push_back({perm[e.a], perm[e.b]});
    gp = normalized(gp);
    const double a = score_graph(g, d, 0.002, paper_gains(4, {}), opt).lambda_next_abs;
    const double b = score_graph(gp, dp, 0.002, paper_gains(4, {}), opt).lambda_next_abs;
    DOUBLES_EQUAL(a, b, 1e-7);
  }
}

TEST_GROUP(Structure){};

TEST(Structure, ModeSplitEqualsTheGeneralDenseComputation) {
  const int n = 3, users = 4;
  const Eigen::MatrixXd kh = path_k_hat(n);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(kh);
  PolynomialGains pg;
  pg.a.resize(users, users);
  pg.b.resize(users, users);
  for (int i = 0; i < users; ++i)
    for (int j = 0; j < users; ++j) {
      pg.a(i, j) = 1.0 + 0.4 * ((i + 2 * j) % 3);
      pg.b(i, j) = 0.2 + 1.5 * ((2 * i + j) % 4);
    }
  pg.mode_values = es.eigenvalues();
  DenseGains dg;
  dg.n = n;
  for (int i = 0; i < users; ++i)
    for (int j = 0; j < users; ++j)
      dg.blocks.push_back(pg.a(i, j) * Eigen::MatrixXd::Identity(n, n) + pg.b(i, j) * kh);
  SpectrumOptions opt;
  opt.method = EigenMethod::Dense;
  for (double s : {0.0, 0.4}) {
    opt.self_weight = s;
    for (const char* gs : {"1-2,1-3,1-4", "1-2,2-3,3-4,1-4", "1-3,2-3,2-4"}) {
      const Graph g = parse_graph_1based(gs, users);
      const GraphScore split = score_graph(g, small_delays(), 0.002, pg, opt);
      const GraphScore dense = score_graph_dense(g, small_delays(), 0.002, dg, opt);
      CHECK(split.path == StructurePath::ModeSplit);
      LONGS_EQUAL(n, split.modes_evaluated);
      CHECK(dense.path == StructurePath::GeneralDense);
      DOUBLES_EQUAL(dense.lambda_next_abs, split.lambda_next_abs, 1e-8);
    }
  }
}

TEST(Structure, UniformPolynomialGainsUseOneScalarProblemThatMatchesDense) {
  const int n = 3, users = 4;
  const Eigen::MatrixXd kh = path_k_hat(n);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(kh);
  const PolynomialGains pg = paper_gains(users, es.eigenvalues());
  DenseGains dg;
  dg.n = n;
  dg.blocks.assign(users * users, 500.0 * Eigen::MatrixXd::Identity(n, n) + 500.0 * kh);
  SpectrumOptions opt;
  opt.method = EigenMethod::Dense;
  const Graph g = parse_graph_1based("1-2,1-3,1-4", users);
  const GraphScore one = score_graph(g, small_delays(), 0.002, pg, opt);
  CHECK(one.path == StructurePath::SingleMode);
  LONGS_EQUAL(1, one.modes_evaluated);
  DOUBLES_EQUAL(score_graph_dense(g, small_delays(), 0.002, dg, opt).lambda_next_abs, one.lambda_next_abs, 1e-8);
}

TEST(Structure, NonPositiveModeWeightIsRejectedWithTheGainNamed) {
  PolynomialGains pg = uniform_gains(4, 1.0, -2.0, Eigen::Vector2d(0.0, 1.0));
  pg.a(0, 1) = 3.0;  // not proportional: mode split; mu = 1 gives p = -1 on other links
  try {
    score_graph(parse_graph_1based("1-2,1-3,1-4", 4), small_delays(), 0.002, pg, SpectrumOptions{});
    FAIL("expected std::invalid_argument");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("gains") != std::string::npos);
  }
}

TEST(Structure, DisconnectedGraphIsRejected) {
  CHECK_THROWS(std::invalid_argument,
               score_graph(parse_graph_1based("1-2,3-4", 4), small_delays(), 0.002, paper_gains(4, {}), SpectrumOptions{}));
}

TEST_GROUP(Solvers){};

TEST(Solvers, PowerMethodMatchesDenseOnEveryPaperTopology) {
  const Eigen::MatrixXd d = paper_delay_matrix_ms();
  for (double s : {0.0, 0.5}) {
    SpectrumOptions dense, power;
    dense.method = EigenMethod::Dense;
    power.method = EigenMethod::Power;
    dense.self_weight = power.self_weight = s;
    for (const Graph& g : enumerate_connected_graphs(4, 3, 0, 100)) {
      const GraphScore a = score_graph(g, d, 0.002, paper_gains(4, {}), dense);
      const GraphScore b = score_graph(g, d, 0.002, paper_gains(4, {}), power);
      CHECK(b.method == EigenMethod::Power);
      CHECK(b.converged);
      DOUBLES_EQUAL(a.lambda_next_abs, b.lambda_next_abs, 1e-6);
    }
  }
}

TEST(Solvers, ArnoldiMatchesDenseWhenTheOuterSpectrumIsSeparated) {
  const Eigen::MatrixXd d = small_delays();
  SpectrumOptions dense, arn;
  dense.method = EigenMethod::Dense;
  arn.method = EigenMethod::Arnoldi;
  dense.self_weight = arn.self_weight = 0.5;
  const Graph g = parse_graph_1based("1-2,1-3,1-4,2-3", 4);
  const GraphScore a = score_graph(g, d, 0.002, paper_gains(4, {}), dense);
  const GraphScore b = score_graph(g, d, 0.002, paper_gains(4, {}), arn);
  CHECK(b.converged);
  DOUBLES_EQUAL(a.lambda_next_abs, b.lambda_next_abs, 1e-7);
}

TEST_GROUP(FeasibleSet){};

TEST(FeasibleSet, EnumerationCountsMatchCayleyAndTheDegreeCap) {
  LONGS_EQUAL(16, enumerate_connected_graphs(4, 3, 0, 100).size());   // 4^(4-2) trees
  LONGS_EQUAL(125, enumerate_connected_graphs(5, 4, 0, 1000).size()); // 5^(5-2) trees
  LONGS_EQUAL(12, enumerate_connected_graphs(4, 3, 2, 100).size());   // paths: 4!/2
  CHECK_THROWS(std::invalid_argument, enumerate_connected_graphs(20, 30, 0, 1000));
  CHECK_THROWS(std::invalid_argument, enumerate_connected_graphs(4, 2, 0, 1000));
}

TEST(FeasibleSet, Eq18SumsForThePaperStar) {
  const Graph star = parse_graph_1based("1-2,1-3,1-4", 4);
  // The delay model of the simulator and the station (firmware/model), as haptic-topology uses it.
  const auto sums = [&](int allowance) {
    return haptic::model::round_trip_half_sums_ms(
        star, haptic::model::index_delay_bounds_ticks(paper_delay_matrix_ms(), 0.5, 0.002, allowance), 0.002);
  };
  const Eigen::VectorXd s = sums(0);
  // Nbar = ceil(1.5 mean / T): 1-2: 3 + 6, 1-3: 3 + 3, 1-4: 3 + 5 (x T/2 = 1 ms)
  DOUBLES_EQUAL(23.0, s(0), 1e-12);
  DOUBLES_EQUAL(9.0, s(1), 1e-12);
  DOUBLES_EQUAL(6.0, s(2), 1e-12);
  DOUBLES_EQUAL(8.0, s(3), 1e-12);
  const Eigen::VectorXd s1 = sums(1);
  DOUBLES_EQUAL(29.0, s1(0), 1e-12);  // + one step each way per link
}

TEST(FeasibleSet, SearchReturnsAFeasibleGraphNoWorseThanItsSeedAndNotBelowTheOptimum) {
  SyntheticMap map;
  map.seed = 7;
  const int n = 6;
  const Eigen::MatrixXd d = synthetic_delays_ms(n, map, nullptr);
  SpectrumOptions opt;
  opt.method = EigenMethod::Power;  // checked against Dense above; keeps the exhaustive check fast
  SearchOptions so;
  so.degree_cap = 3;
  so.max_evaluations = 60;
  const SearchResult r = search_topology(d, 0.002, paper_gains(n, {}), opt, so);
  CHECK(is_connected(r.best, n));
  LONGS_EQUAL(n - 1, r.best.size());
  std::vector<int> deg(n, 0);
  for (const Edge& e : r.best) {
    ++deg[e.a];
    ++deg[e.b];
  }
  CHECK(*std::max_element(deg.begin(), deg.end()) <= 3);
  CHECK(r.best_score.lambda_next_abs <= r.seed_score.lambda_next_abs);
  CHECK(r.evaluations <= 60);
  double optimum = 1.0;
  for (const Graph& g : enumerate_connected_graphs(n, n - 1, 3, 100000)) {
    optimum = std::min(optimum, score_graph(g, d, 0.002, paper_gains(n, {}), opt).lambda_next_abs);
  }
  CHECK(r.best_score.lambda_next_abs >= optimum - 1e-6);
}

TEST(FeasibleSet, SyntheticDelaysAreReproducibleFromTheSeed) {
  SyntheticMap map;
  map.seed = 3;
  const Eigen::MatrixXd a = synthetic_delays_ms(16, map, nullptr);
  const Eigen::MatrixXd b = synthetic_delays_ms(16, map, nullptr);
  DOUBLES_EQUAL(0.0, (a - b).norm(), 0.0);
  map.seed = 4;
  CHECK((a - synthetic_delays_ms(16, map, nullptr)).norm() > 1.0);
  CHECK(a.minCoeff() == 0.0);
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j)
      if (i != j) CHECK(a(i, j) >= map.base_ms * (1 - map.asymmetry));
}

TEST(FeasibleSet, GraphParsingNamesTheBadLink) {
  CHECK_THROWS(std::invalid_argument, parse_graph_1based("1-5", 4));
  CHECK_THROWS(std::invalid_argument, parse_graph_1based("1-2,2-1", 4));
  CHECK_THROWS(std::invalid_argument, parse_graph_1based("12", 4));
  STRCMP_EQUAL("1-2 2-4 3-4", to_string_1based(parse_graph_1based("4-2, 1-2,3-4", 4)).c_str());
}
