#include "tests/support/graph.hpp"

#include "firmware/model/graph.hpp"

#include <stdexcept>

namespace haptic::test {

bool UndirectedGraph::connected() const {
  if (vertices <= 1) return true;
  model::Graph g;
  for (const auto& e : edges) g.push_back({e[0], e[1]});
  return model::is_connected(g, vertices);
}

Eigen::MatrixXd incidence_matrix(const UndirectedGraph& g) {
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(g.vertices, 2 * static_cast<Eigen::Index>(g.edges.size()));
  for (std::size_t l = 0; l < g.edges.size(); ++l) {
    const auto& e = g.edges[l];
    D(e[0], 2 * l) = 1;   // e_ij: head i, tail j
    D(e[1], 2 * l) = -1;
    D(e[1], 2 * l + 1) = 1;  // e_ji
    D(e[0], 2 * l + 1) = -1;
  }
  return D;
}

Eigen::MatrixXd laplacian(const UndirectedGraph& g) {
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(g.vertices, g.vertices);
  for (const auto& e : g.edges) {
    L(e[0], e[0]) += 1;
    L(e[1], e[1]) += 1;
    L(e[0], e[1]) = -1;
    L(e[1], e[0]) = -1;
  }
  return L;
}

Eigen::MatrixXd stiffness_matrix(const UndirectedGraph& g, const std::vector<Eigen::MatrixXd>& gains) {
  if (gains.size() != g.edges.size()) throw std::invalid_argument("stiffness_matrix: one gain per edge");
  const Eigen::Index n = gains.empty() ? 0 : gains[0].rows();
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(g.vertices * n, g.vertices * n);
  for (std::size_t l = 0; l < g.edges.size(); ++l) {
    const auto i = g.edges[l][0], j = g.edges[l][1];
    P.block(i * n, i * n, n, n) += gains[l];
    P.block(j * n, j * n, n, n) += gains[l];
    P.block(i * n, j * n, n, n) -= gains[l];
    P.block(j * n, i * n, n, n) -= gains[l];
  }
  return P;
}

Eigen::MatrixXd stiffness_matrix_lemma1(const UndirectedGraph& g, const std::vector<Eigen::MatrixXd>& gains) {
  const Eigen::Index n = gains.empty() ? 0 : gains[0].rows();
  const Eigen::MatrixXd D = incidence_matrix(g);
  const Eigen::Index Ne = D.cols();
  Eigen::MatrixXd DI = Eigen::MatrixXd::Zero(g.vertices * n, Ne * n);  // D (x) I_n
  for (Eigen::Index i = 0; i < D.rows(); ++i)
    for (Eigen::Index l = 0; l < Ne; ++l)
      if (D(i, l) != 0) DI.block(i * n, l * n, n, n) = D(i, l) * Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd Pd = Eigen::MatrixXd::Zero(Ne * n, Ne * n);
  for (Eigen::Index l = 0; l < Ne; ++l) Pd.block(l * n, l * n, n, n) = gains[static_cast<std::size_t>(l / 2)];
  return 0.5 * DI * Pd * DI.transpose();
}

}  // namespace haptic::test
