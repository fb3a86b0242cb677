#include "firmware/model/graph.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cctype>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace haptic::model {

namespace {
[[noreturn]] void bad(const std::string& msg) { throw std::invalid_argument(msg); }
std::string link_text(const Link& l) { return std::to_string(l.a + 1) + "-" + std::to_string(l.b + 1); }
}  // namespace

Graph normalized(Graph g, const std::string& key) {
  for (Link& l : g) {
    if (l.a == l.b) bad(key + ": link " + link_text(l) + " joins user " + std::to_string(l.a + 1) + " to itself");
    if (l.a > l.b) std::swap(l.a, l.b);
  }
  std::sort(g.begin(), g.end(), [](const Link& x, const Link& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  for (std::size_t i = 1; i < g.size(); ++i)
    if (g[i] == g[i - 1]) bad(key + ": link " + link_text(g[i]) + " is listed twice");
  return g;
}

bool is_connected(const Graph& g, int users) {
  if (users <= 0) return false;
  std::vector<int> parent(static_cast<std::size_t>(users));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int v) {
    while (parent[static_cast<std::size_t>(v)] != v) v = parent[static_cast<std::size_t>(v)];
    return v;
  };
  int components = users;
  for (const Link& l : g) {
    if (l.a < 0 || l.b < 0 || l.a >= users || l.b >= users) return false;
    const int ra = find(l.a), rb = find(l.b);
    if (ra != rb) {
      parent[static_cast<std::size_t>(ra)] = rb;
      --components;
    }
  }
  return components == 1;
}

void validate_graph(const Graph& g, int users, const std::string& key) {
  if (g.empty()) bad(key + " needs at least one link");
  for (const Link& l : g)
    if (l.a < 0 || l.b < 0 || l.a >= users || l.b >= users || l.a == l.b)
      bad(key + ": link " + link_text(l) + " is not between two different users 1.." + std::to_string(users));
  (void)normalized(g, key);  // repeated links
  if (!is_connected(g, users)) {
    // name the users no path reaches from user 1 (the links are in range here)
    std::vector<char> seen(static_cast<std::size_t>(users), 0);
    std::vector<int> todo{0};
    seen[0] = 1;
    while (!todo.empty()) {
      const int v = todo.back();
      todo.pop_back();
      for (const Link& l : g) {
        const int w = l.a == v ? l.b : l.b == v ? l.a : -1;
        if (w >= 0 && !seen[static_cast<std::size_t>(w)]) seen[static_cast<std::size_t>(w)] = 1, todo.push_back(w);
      }
    }
    std::string cut;
    for (int u = 0; u < users; ++u)
      if (!seen[static_cast<std::size_t>(u)]) cut += (cut.empty() ? "" : ", ") + std::to_string(u + 1);
    bad(key + " must connect all users (Theorem 1 needs a connected graph): no link path from user 1 reaches user" +
        (cut.find(',') == std::string::npos ? " " : "s ") + cut);
  }
}

Graph parse_graph_1based(const std::string& text, int users, const std::string& key) {
  Graph g;
  std::istringstream is(text);
  std::string tok;
  while (std::getline(is, tok, ',')) {
    tok.erase(std::remove_if(tok.begin(), tok.end(), [](unsigned char c) { return std::isspace(c) != 0; }), tok.end());
    if (tok.empty()) continue;
    const auto dash = tok.find('-');
    int a = 0, b = 0;
    std::size_t used_a = 0, used_b = 0;
    try {
      if (dash == std::string::npos || dash == 0) throw std::invalid_argument(tok);
      a = std::stoi(tok.substr(0, dash), &used_a);
      b = std::stoi(tok.substr(dash + 1), &used_b);
    } catch (const std::exception&) {
      bad(key + ": '" + tok + "' is not a link like 1-2");
    }
    if (used_a != dash || used_b != tok.size() - dash - 1) bad(key + ": '" + tok + "' is not a link like 1-2");
    if (a < 1 || b < 1 || a > users || b > users) bad(key + ": '" + tok + "' must join users numbered 1.." + std::to_string(users));
    g.push_back({a - 1, b - 1});
  }
  if (g.empty()) bad(key + " is empty (give links like 1-2,1-3)");
  return normalized(std::move(g), key);
}

std::string to_string_1based(const Graph& g) {
  std::ostringstream os;
  for (std::size_t i = 0; i < g.size(); ++i) os << (i ? " " : "") << g[i].a + 1 << '-' << g[i].b + 1;
  return os.str();
}

Adjacency adjacency(const Graph& g, int users) {
  Adjacency a;
  a.neighbours.assign(static_cast<std::size_t>(users), {});
  a.link_of.assign(static_cast<std::size_t>(users), {});
  for (std::size_t e = 0; e < g.size(); ++e) {
    const Link& l = g[e];
    a.neighbours[static_cast<std::size_t>(l.a)].push_back(l.b);
    a.link_of[static_cast<std::size_t>(l.a)].push_back(static_cast<int>(e));
    a.neighbours[static_cast<std::size_t>(l.b)].push_back(l.a);
    a.link_of[static_cast<std::size_t>(l.b)].push_back(static_cast<int>(e));
  }
  return a;
}

namespace {
// reach[S] = max over u in S of |N(u) \ S| (the r for which S is r-reachable), every S.
std::vector<int> reach_of_every_set(const Graph& g, int users) {
  std::vector<std::uint32_t> nb(static_cast<std::size_t>(users), 0);
  for (const Link& l : g) {
    nb[static_cast<std::size_t>(l.a)] |= 1u << l.b;
    nb[static_cast<std::size_t>(l.b)] |= 1u << l.a;
  }
  const std::uint32_t sets = 1u << users;
  std::vector<int> reach(sets, 0);
  for (std::uint32_t s = 1; s < sets; ++s)
    for (int u = 0; u < users; ++u)
      if (s >> u & 1u) reach[s] = std::max(reach[s], std::popcount(nb[static_cast<std::size_t>(u)] & ~s));
  return reach;
}
}  // namespace

int robustness(const Graph& g, int users, const std::string& key) {
  if (users > kMaxRobustnessUsers)
    bad(key + ": robustness is checked exhaustively up to " + std::to_string(kMaxRobustnessUsers) + " users, not " + std::to_string(users));
  if (users < 2 || !is_connected(g, users)) return 0;
  const std::vector<int> reach = reach_of_every_set(g, users);
  const std::uint32_t all = (1u << users) - 1;
  // least[C] = min over non-empty S2 within C of reach[S2] (a sentinel above any reach for C = 0)
  std::vector<int> least(reach.size(), users + 1);
  for (std::uint32_t c = 1; c <= all; ++c) {
    least[c] = reach[c];
    for (int u = 0; u < users; ++u)
      if (c >> u & 1u) least[c] = std::min(least[c], least[c & ~(1u << u)]);
  }
  int r = users;
  for (std::uint32_t s1 = 1; s1 < all; ++s1) r = std::min(r, std::max(reach[s1], least[all & ~s1]));
  return r;
}

}  // namespace haptic::model
