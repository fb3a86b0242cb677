#pragma once
// Graph objects of Section II: incidence matrix (3), Laplacian (4) and the multidimensional
// stiffness matrix P (6) with matrix edge gains. Dense, start-up and analysis only.
#include <Eigen/Core>
#include <array>
#include <vector>

namespace haptic::test {

// Undirected simple graph on N vertices (0-based edges {i, j}, i != j).
struct UndirectedGraph {
  int vertices = 0;
  std::vector<std::array<int, 2>> edges;
  bool connected() const;
};

// Incidence matrix D (N x Ne) of (3) over the directed edges e_ij and e_ji of every undirected
// edge (Ne = 2 |edges|): +1 at the head (receiver) i, -1 at the tail j.
Eigen::MatrixXd incidence_matrix(const UndirectedGraph& g);
// Graph Laplacian L (4).
Eigen::MatrixXd laplacian(const UndirectedGraph& g);
// Stiffness matrix P (6) with P_ij = gains[e] (n x n, symmetric positive definite) on edge e.
Eigen::MatrixXd stiffness_matrix(const UndirectedGraph& g, const std::vector<Eigen::MatrixXd>& gains);
// Lemma 1's right-hand side: 1/2 (D (x) I_n) P_d (D (x) I_n)^T with P_d = diag over directed edges.
Eigen::MatrixXd stiffness_matrix_lemma1(const UndirectedGraph& g, const std::vector<Eigen::MatrixXd>& gains);

}  // namespace haptic::test
