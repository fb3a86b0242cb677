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

}  // namespace haptic::model
