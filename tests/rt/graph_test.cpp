// Lemma 1 and Proposition 1 on random connected graphs with random SPD matrix edge gains.
#include <CppUTest/TestHarness.h>

#include <Eigen/Eigenvalues>
#include <random>

#include "tests/support/graph.hpp"

using namespace haptic::test;

namespace {
UndirectedGraph random_connected_graph(std::mt19937& rng, int N) {
  UndirectedGraph g;
  g.vertices = N;
  // random spanning tree, then extra random edges
  for (int v = 1; v < N; ++v) g.edges.push_back({static_cast<int>(rng() % static_cast<unsigned>(v)), v});
  const int extra = static_cast<int>(rng() % static_cast<unsigned>(N));
  for (int e = 0; e < extra; ++e) {
    int a = static_cast<int>(rng() % static_cast<unsigned>(N)), b = static_cast<int>(rng() % static_cast<unsigned>(N));
    if (a == b) continue;
    bool dup = false;
    for (const auto& x : g.edges) dup = dup || (x[0] == a && x[1] == b) || (x[0] == b && x[1] == a);
    if (!dup) g.edges.push_back({a, b});
  }
  return g;
}
Eigen::MatrixXd random_spd(std::mt19937& rng, int n) {
  std::normal_distribution<double> nd;
  Eigen::MatrixXd A(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A(i, j) = nd(rng);
  return A * A.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
}
}  // namespace

TEST_GROUP(Graph){};

TEST(Graph, lemma1_stiffness_matrix_equals_half_incidence_product) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const int N = 2 + trial % 6, n = 1 + trial % 4;
    const auto g = random_connected_graph(rng, N);
    std::vector<Eigen::MatrixXd> gains;
    for (std::size_t e = 0; e < g.edges.size(); ++e) gains.push_back(random_spd(rng, n));
    const Eigen::MatrixXd P = stiffness_matrix(g, gains);
    const Eigen::MatrixXd P7 = stiffness_matrix_lemma1(g, gains);
    CHECK_TRUE((P - P7).norm() <= 1e-10 * P.norm());
  }
}

TEST(Graph, laplacian_is_incidence_product_eq5) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const auto g = random_connected_graph(rng, 2 + trial % 7);
    const Eigen::MatrixXd D = incidence_matrix(g);
    // with both directions of every edge in D, D D^T = 2 L
    CHECK_TRUE((D * D.transpose() - 2 * laplacian(g)).norm() < 1e-12);
  }
}

TEST(Graph, proposition1_rank_and_kernel_of_stiffness_matrix) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const int N = 2 + trial % 6, n = 1 + trial % 4;
    const auto g = random_connected_graph(rng, N);
    CHECK_TRUE(g.connected());
    std::vector<Eigen::MatrixXd> gains;
    for (std::size_t e = 0; e < g.edges.size(); ++e) gains.push_back(random_spd(rng, n));
    const Eigen::MatrixXd P = stiffness_matrix(g, gains);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P);
    const auto& ev = es.eigenvalues();
    const double tol = 1e-9 * ev.cwiseAbs().maxCoeff();
    int zeros = 0;
    for (Eigen::Index i = 0; i < ev.size(); ++i) {
      CHECK_TRUE(ev[i] > -tol);  // positive semidefinite
      if (std::abs(ev[i]) <= tol) ++zeros;
    }
    CHECK_EQUAL(n, zeros);  // rank = n (N - 1)
    for (int d = 0; d < n; ++d) {  // kernel spanned by 1_N (x) a
      Eigen::VectorXd a = Eigen::VectorXd::Random(n);
      Eigen::VectorXd one_a = Eigen::VectorXd::Zero(N * n);
      for (int i = 0; i < N; ++i) one_a.segment(i * n, n) = a;
      CHECK_TRUE((P * one_a).norm() <= 1e-10 * P.norm() * a.norm());
    }
  }
}

TEST(Graph, disconnected_graph_has_larger_kernel) {
  UndirectedGraph g;
  g.vertices = 4;
  g.edges = {{0, 1}, {2, 3}};
  CHECK_FALSE(g.connected());
  std::vector<Eigen::MatrixXd> gains(2, Eigen::MatrixXd::Identity(2, 2));
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(stiffness_matrix(g, gains));
  int zeros = 0;
  for (Eigen::Index i = 0; i < es.eigenvalues().size(); ++i) zeros += std::abs(es.eigenvalues()[i]) < 1e-9;
  CHECK_EQUAL(4, zeros);
}
