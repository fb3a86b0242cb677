#pragma once
// The graph G of the paper (Section II): users 0..N-1 joined by undirected links. The one
// topology type and parser used by scenarios, the station, the simulator and tools/topology.
// Start-up/offline code: allocates, throws std::invalid_argument naming the option; not RT-safe.
#include <string>
#include <vector>

namespace haptic::model {

// Undirected link between users a and b (0-based; normalized(): a < b).
struct Link {
  int a = 0;
  int b = 0;
  bool operator==(const Link&) const = default;
};
using Graph = std::vector<Link>;

// a < b, sorted by (a, b); throws on a self link or a link listed twice (either direction),
// naming `key` (the option or config key the graph came from).
Graph normalized(Graph g, const std::string& key = "graph");
// Every user 0..users-1 reachable; false as well when a link leaves 0..users-1.
bool is_connected(const Graph& g, int users);
// Everything a scenario's graph must satisfy: links between two different users 1..users,
// none listed twice, connected (Theorem 1). Throws naming `key`.
void validate_graph(const Graph& g, int users, const std::string& key);
// "1-2,1-3,1-4" (1-based user numbers, ',' between links, blanks ignored) -> normalized graph.
// Throws naming `key` on a malformed link, a user outside 1..users, a self or repeated link.
Graph parse_graph_1based(const std::string& text, int users, const std::string& key = "graph");
std::string to_string_1based(const Graph& g);  // "1-2 1-3 1-4"
// neighbours[i] = the users linked to i in link order; link_of[i][n] = index in g of that link.
struct Adjacency {
  std::vector<std::vector<int>> neighbours;
  std::vector<std::vector<int>> link_of;
};
Adjacency adjacency(const Graph& g, int users);

// r-robustness (LeBlanc, Zhang, Koutsoukos, Sundaram, IEEE JSAC 31(4), 2013): a set S is
// r-reachable when one of its users has at least r neighbours outside S; the graph is r-robust when
// of every two disjoint non-empty sets of users at least one is r-reachable. With at most F
// misbehaving users, W-MSR lets the others agree on a (2F+1)-robust graph (F-local; F-total needs
// (F+1, F+1)-robust, implied). Exact and exhaustive: reach(S) for all 2^N sets, then the best
// disjoint partner of each S from the least reach over the subsets of its complement, O(2^N N)
// time and 2^N ints; N <= kMaxRobustnessUsers (throws beyond, naming `key`). The complete graph
// K_N is ceil(N/2)-robust, the most any graph on N users is; a tree is 1-robust.
inline constexpr int kMaxRobustnessUsers = 20;
// The largest r for which g is r-robust (0: fewer than 2 users or g not connected).
int robustness(const Graph& g, int users, const std::string& key = "graph");
inline bool is_r_robust(const Graph& g, int users, int r, const std::string& key = "graph") { return robustness(g, users, key) >= r; }

}  // namespace haptic::model
