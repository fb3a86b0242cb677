#include "firmware/scene/mesh_check.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>

namespace haptic::scene {

namespace {

[[noreturn]] void fail(const std::string& file, int line, const std::string& msg) {
  throw MeshError(file + ":" + std::to_string(line) + ": " + msg);
}

std::string num(double v) {
  std::ostringstream os;
  os.precision(3);
  os << v;
  return os.str();
}

int find_root(std::vector<int>& parent, int a) {
  while (parent[static_cast<std::size_t>(a)] != a) a = parent[static_cast<std::size_t>(a)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
  return a;
}

void check_tetrahedra(const RawTetMesh& raw, double unit_m) {
  const auto& f = raw.element_file;
  const int n = static_cast<int>(raw.nodes.size());
  for (std::size_t t = 0; t < raw.tets.size(); ++t) {
    const auto& q = raw.tets[t];
    const std::string el = "element " + std::to_string(raw.tet_id[t]) + ": ";
    for (int v : q)
      if (v < 0 || v >= n) fail(f, raw.tet_line[t], el + "refers to a node that does not exist");
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        if (q[a] == q[b]) fail(f, raw.tet_line[t], el + "degenerate tetrahedron (node " + std::to_string(raw.node_id[static_cast<std::size_t>(q[a])]) + " twice)");
    const auto& P = raw.nodes;
    double longest = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) longest = std::max(longest, (P[q[a]] - P[q[b]]).norm());
    const double six_v = (P[q[1]] - P[q[0]]).cross(P[q[2]] - P[q[0]]).dot(P[q[3]] - P[q[0]]);
    if (!std::isfinite(six_v)) fail(f, raw.tet_line[t], el + "non-finite node coordinates");
    if (std::abs(six_v) <= kDegenerateRelativeVolume * longest * longest * longest)
      fail(f, raw.tet_line[t], el + "degenerate tetrahedron (volume " + num(six_v / 6 * unit_m * unit_m * unit_m) + " m^3, flat or collapsed)");
    if (six_v < 0)
      fail(f, raw.tet_line[t], el + "inverted tetrahedron (volume " + num(six_v / 6 * unit_m * unit_m * unit_m) +
                                   " m^3; corners must be ordered so that (b-a) x (c-a) . (d-a) > 0)");
  }
}

void check_nodes_used_and_connected(const RawTetMesh& raw) {
  const auto n = raw.nodes.size();
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<char> used(n, 0);
  for (const auto& q : raw.tets)
    for (int a = 0; a < 4; ++a) {
      used[static_cast<std::size_t>(q[a])] = 1;
      parent[static_cast<std::size_t>(find_root(parent, q[a]))] = find_root(parent, q[0]);
    }
  for (std::size_t i = 0; i < n; ++i)
    if (!used[i])
      fail(raw.node_file, raw.node_line[i], "node " + std::to_string(raw.node_id[i]) + ": unreferenced node (in no tetrahedron)");
  const int root = find_root(parent, raw.tets[0][0]);
  for (std::size_t t = 0; t < raw.tets.size(); ++t)
    if (find_root(parent, raw.tets[t][0]) != root)
      fail(raw.element_file, raw.tet_line[t], "element " + std::to_string(raw.tet_id[t]) +
                                                  ": the mesh has several disconnected pieces (this element is not connected to element " +
                                                  std::to_string(raw.tet_id[0]) + ")");
}

// Every boundary node's boundary triangles form one fan (joined through edges at the node); two fans
// mean two parts of the surface touch at that node only (e.g. two balls meshed touching at a point),
// which the edge and face checks do not see.
// `boundary`: the faces on one tetrahedron (sorted corners, that tetrahedron), ascending.
void check_boundary_vertices(const RawTetMesh& raw, const std::vector<std::pair<std::array<int, 3>, std::size_t>>& boundary) {
  std::map<int, std::vector<std::pair<std::array<int, 3>, std::size_t>>> around;  // node -> its boundary faces (with their tet)
  for (const auto& [k, t] : boundary)
    for (int v : k) around[v].push_back({k, t});
  for (const auto& [v, fs] : around) {
    std::vector<int> parent(fs.size());
    for (std::size_t i = 0; i < fs.size(); ++i) parent[i] = static_cast<int>(i);
    std::map<int, std::size_t> by_other;  // the other end of an edge at v -> a face on that edge
    for (std::size_t i = 0; i < fs.size(); ++i)
      for (int w : fs[i].first) {
        if (w == v) continue;
        const auto [it, fresh] = by_other.emplace(w, i);
        if (!fresh) parent[static_cast<std::size_t>(find_root(parent, static_cast<int>(i)))] = find_root(parent, static_cast<int>(it->second));
      }
    for (std::size_t i = 1; i < fs.size(); ++i)
      if (find_root(parent, static_cast<int>(i)) != find_root(parent, 0))
        fail(raw.element_file, raw.tet_line[fs[i].second],
             "element " + std::to_string(raw.tet_id[fs[i].second]) + ": non-manifold surface at node " + std::to_string(raw.node_id[static_cast<std::size_t>(v)]) +
                 ": the boundary touches itself there (its boundary triangles form separate fans, e.g. elements " +
                 std::to_string(raw.tet_id[fs[0].second]) + " and " + std::to_string(raw.tet_id[fs[i].second]) + ")");
  }
}

// Faces on more than two tetrahedra; boundary edges not on exactly two boundary faces.
void check_manifold(const RawTetMesh& raw) {
  // Every face (sorted corners) with the tetrahedra that have it, ascending by face, then tetrahedron.
  std::vector<std::pair<std::array<int, 3>, std::size_t>> uses;
  uses.reserve(raw.tets.size() * 4);
  for (std::size_t t = 0; t < raw.tets.size(); ++t) {
    const auto& q = raw.tets[t];
    const std::array<std::array<int, 3>, 4> fs = {{{q[0], q[1], q[2]}, {q[0], q[1], q[3]}, {q[0], q[2], q[3]}, {q[1], q[2], q[3]}}};
    for (auto k : fs) {
      std::sort(k.begin(), k.end());
      uses.push_back({k, t});
    }
  }
  std::sort(uses.begin(), uses.end());
  std::vector<std::pair<std::array<int, 3>, std::size_t>> boundary;  // faces on one tetrahedron
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].first == uses[i].first) ++j;
    if (j - i > 2)
      fail(raw.element_file, raw.tet_line[uses[i + 2].second], "element " + std::to_string(raw.tet_id[uses[i + 2].second]) + ": non-manifold mesh: a face is shared by " +
                                                                   std::to_string(j - i) + " tetrahedra (elements " + std::to_string(raw.tet_id[uses[i].second]) + ", " +
                                                                   std::to_string(raw.tet_id[uses[i + 1].second]) + ", ...)");
    if (j - i == 1) boundary.push_back(uses[i]);
    i = j;
  }
  std::map<std::array<int, 2>, std::vector<std::size_t>> boundary_edges;  // edge -> tets of its boundary faces
  for (const auto& [k, t] : boundary)
    for (auto e : {std::array<int, 2>{k[0], k[1]}, std::array<int, 2>{k[0], k[2]}, std::array<int, 2>{k[1], k[2]}}) boundary_edges[e].push_back(t);
  for (const auto& [e, ts] : boundary_edges)
    if (ts.size() != 2)
      fail(raw.element_file, raw.tet_line[ts[0]], "element " + std::to_string(raw.tet_id[ts[0]]) + ": non-manifold surface: the boundary edge between nodes " +
                                                      std::to_string(raw.node_id[static_cast<std::size_t>(e[0])]) + " and " +
                                                      std::to_string(raw.node_id[static_cast<std::size_t>(e[1])]) + " is on " + std::to_string(ts.size()) +
                                                      " boundary triangles (2 expected)");
  check_boundary_vertices(raw, boundary);
}

}  // namespace

rt::TetMesh check_tet_mesh(const RawTetMesh& raw, double unit_m, const MeshLimits& limits) {
  if (!(unit_m > 0 && std::isfinite(unit_m))) throw MeshError("scene.unit_m must be > 0 (metres per file unit)");
  if (raw.tets.empty()) fail(raw.element_file, 0, "no tetrahedra (4-node tetrahedral elements) in the file");
  if (static_cast<long>(raw.nodes.size()) > limits.max_nodes)
    fail(raw.node_file, 0, std::to_string(raw.nodes.size()) + " nodes: above the limit of " + std::to_string(limits.max_nodes));
  if (static_cast<long>(raw.tets.size()) > limits.max_elements)
    fail(raw.element_file, 0, std::to_string(raw.tets.size()) + " tetrahedra: above the limit of " + std::to_string(limits.max_elements));
  check_tetrahedra(raw, unit_m);
  check_nodes_used_and_connected(raw);
  check_manifold(raw);
  rt::TetMesh m;
  m.nodes.reserve(raw.nodes.size());
  for (const auto& p : raw.nodes) m.nodes.push_back(unit_m * p);
  m.tets = raw.tets;
  rt::finish_mesh(m);
  return m;
}

void check_surface(const RawSurface& s) {
  const auto where = [&](std::size_t t) { return (s.lines_are_facets ? "facet " : "") + std::to_string(s.triangle_line[t]); };
  const auto failt = [&](std::size_t t, const std::string& msg) {
    throw MeshError(s.file + ":" + (s.lines_are_facets ? "0: " + where(t) + ": " : where(t) + ": ") + msg);
  };
  if (s.triangles.empty()) throw MeshError(s.file + ":0: no triangles in the file");
  const int n = static_cast<int>(s.nodes.size());
  std::vector<char> used(s.nodes.size(), 0);
  std::map<std::array<int, 3>, std::size_t> seen;
  std::map<std::array<int, 2>, std::vector<std::size_t>> edges;
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const auto& f = s.triangles[t];
    for (int v : f)
      if (v < 0 || v >= n) failt(t, "triangle refers to a vertex that does not exist");
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) failt(t, "degenerate triangle (a vertex twice)");
    const Eigen::Vector3d a = s.nodes[f[1]] - s.nodes[f[0]], b = s.nodes[f[2]] - s.nodes[f[0]];
    const double longest = std::max({a.norm(), b.norm(), (b - a).norm()});
    if (!(a.cross(b).norm() > 1e-12 * longest * longest)) failt(t, "degenerate triangle (zero area)");
    auto k = f;
    std::sort(k.begin(), k.end());
    if (!seen.emplace(k, t).second) failt(t, "repeated triangle");
    for (int e = 0; e < 3; ++e) {
      used[static_cast<std::size_t>(f[e])] = 1;
      edges[{std::min(f[e], f[(e + 1) % 3]), std::max(f[e], f[(e + 1) % 3])}].push_back(t);
    }
  }
  for (const auto& [e, ts] : edges)
    if (ts.size() != 2)
      failt(ts[0], "non-manifold surface: the edge between vertices " + std::to_string(e[0] + 1) + " and " + std::to_string(e[1] + 1) + " is on " +
                       std::to_string(ts.size()) + " triangles (a closed surface needs exactly 2)");
  for (std::size_t i = 0; i < used.size(); ++i)
    if (!used[i]) throw MeshError(s.file + ":0: vertex " + std::to_string(i + 1) + ": unreferenced vertex (in no triangle)");
  // Two vertices at one point: closed shells that touch (TetGen would weld them into a non-manifold
  // edge or vertex and the error would name its output's elements), or a surface not welded.
  std::map<std::array<double, 3>, std::size_t> at;
  for (std::size_t i = 0; i < s.nodes.size(); ++i) {
    const auto [it, fresh] = at.emplace(std::array<double, 3>{s.nodes[i].x(), s.nodes[i].y(), s.nodes[i].z()}, i);
    if (!fresh)
      throw MeshError(s.file + ":0: vertex " + std::to_string(i + 1) + ": at the same point as vertex " + std::to_string(it->second + 1) +
                      ": the surface touches itself there (two shells, or vertices not welded); one closed manifold surface is needed");
  }
}

}  // namespace haptic::scene
