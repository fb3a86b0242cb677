#include "rt/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>

namespace haptic::rt {

Eigen::Vector3d TetMesh::centroid() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : nodes) c += p;
  return nodes.empty() ? c : Eigen::Vector3d(c / static_cast<double>(nodes.size()));
}

Eigen::Vector3d TetMesh::face_normal(int f) const {
  const auto& t = surface.at(static_cast<std::size_t>(f));
  const Eigen::Vector3d n = (nodes[t[1]] - nodes[t[0]]).cross(nodes[t[2]] - nodes[t[0]]);
  return n.normalized();
}

Eigen::Vector3d TetMesh::face_center(int f) const {
  const auto& t = surface.at(static_cast<std::size_t>(f));
  return (nodes[t[0]] + nodes[t[1]] + nodes[t[2]]) / 3.0;
}

int TetMesh::face_towards(const Eigen::Vector3d& direction) const {
  const Eigen::Vector3d d = direction.normalized();
  int best = -1;
  double best_dot = -2;
  const Eigen::Vector3d c = centroid();
  for (int f = 0; f < static_cast<int>(surface.size()); ++f) {
    // Prefer the face the ray from the centre actually exits through: score by the face centre's
    // direction, tie-broken by the normal.
    const double s = (face_center(f) - c).normalized().dot(d) + 1e-3 * face_normal(f).dot(d);
    if (s > best_dot) {
      best_dot = s;
      best = f;
    }
  }
  if (best < 0) throw std::runtime_error("mesh has no surface");
  return best;
}

int TetMesh::surface_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, Eigen::Vector3d* point) const {
  const Eigen::Vector3d d = direction.normalized();
  int best = -1;
  double best_t = std::numeric_limits<double>::infinity();
  for (int f = 0; f < static_cast<int>(surface.size()); ++f) {
    const auto& t = surface[static_cast<std::size_t>(f)];
    const Eigen::Vector3d& a = nodes[t[0]];
    const Eigen::Vector3d e1 = nodes[t[1]] - a, e2 = nodes[t[2]] - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) continue;
    const Eigen::Vector3d s = origin - a;
    const double u = s.dot(p) / det;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) / det;
    const double tol = 1e-12;
    if (u < -tol || v < -tol || u + v > 1 + tol) continue;
    const double dist = e2.dot(q) / det;
    if (dist >= 0 && dist < best_t) {
      best_t = dist;
      best = f;
    }
  }
  if (best >= 0 && point) *point = origin + best_t * d;
  return best;
}

int TetMesh::face_touched_from(const Eigen::Vector3d& direction, Eigen::Vector3d* touch) const {
  const Eigen::Vector3d d = direction.normalized();
  return surface_hit(centroid() + 2.0 * bounding_radius() * d, -d, touch);
}

double TetMesh::bounding_radius() const {
  const Eigen::Vector3d c = centroid();
  double r = 0;
  for (const auto& p : nodes) r = std::max(r, (p - c).norm());
  return r;
}

double TetMesh::tet_volume(int t) const {
  const auto& q = tets.at(static_cast<std::size_t>(t));
  return (nodes[q[1]] - nodes[q[0]]).cross(nodes[q[2]] - nodes[q[0]]).dot(nodes[q[3]] - nodes[q[0]]) / 6.0;
}

void finish_mesh(TetMesh& m) {
  // Edges ascending and unique; the boundary faces (used by one tetrahedron) in ascending order of
  // their sorted corners.
  m.edges.clear();
  m.edges.reserve(m.tets.size() * 6);
  struct FaceUse {
    std::array<int, 3> key;   // sorted corners
    std::array<int, 3> face;  // as the tetrahedron lists them
    int opposite;             // the tetrahedron's fourth node
  };
  std::vector<FaceUse> faces;
  faces.reserve(m.tets.size() * 4);
  for (const auto& t : m.tets) {
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) m.edges.push_back({std::min(t[a], t[b]), std::max(t[a], t[b])});
    const std::array<std::array<int, 3>, 4> fs = {{{t[0], t[1], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[3]}, {t[1], t[2], t[3]}}};
    const std::array<int, 4> opposite = {t[3], t[2], t[1], t[0]};
    for (std::size_t i = 0; i < fs.size(); ++i) {
      auto key = fs[i];
      std::sort(key.begin(), key.end());
      faces.push_back({key, fs[i], opposite[i]});
    }
  }
  std::sort(m.edges.begin(), m.edges.end());
  m.edges.erase(std::unique(m.edges.begin(), m.edges.end()), m.edges.end());
  std::sort(faces.begin(), faces.end(), [](const FaceUse& a, const FaceUse& b) { return a.key < b.key; });
  m.surface.clear();
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].key == faces[i].key) ++j;
    if (j == i + 1) {
      auto f = faces[i].face;
      const Eigen::Vector3d n = (m.nodes[f[1]] - m.nodes[f[0]]).cross(m.nodes[f[2]] - m.nodes[f[0]]);
      if (n.dot(m.nodes[f[0]] - m.nodes[faces[i].opposite]) < 0) std::swap(f[1], f[2]);
      m.surface.push_back(f);
    }
    i = j;
  }
}

TetMesh make_paper_ball(double radius_m) {
  if (!(radius_m > 0)) throw std::invalid_argument("ball radius must be > 0");
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> s;
  for (int a : {-1, 1})
    for (int b : {-1, 1}) {
      s.emplace_back(0, a, b * phi);
      s.emplace_back(a, b * phi, 0);
      s.emplace_back(b * phi, 0, a);
    }
  for (int a : {-1, 1})
    for (int b : {-1, 1})
      for (int c : {-1, 1}) s.emplace_back(a, b, c);
  for (int a : {-1, 1})
    for (int b : {-1, 1}) {
      s.emplace_back(0, a / phi, b * phi);
      s.emplace_back(a / phi, b * phi, 0);
      s.emplace_back(b * phi, 0, a / phi);
    }
  TetMesh m;
  m.nodes.push_back(Eigen::Vector3d::Zero());
  for (auto& p : s) m.nodes.push_back(radius_m * p.normalized());
  // Convex hull of the 32 sphere points by brute force (no four of them are coplanar on a hull
  // face), then cone every hull triangle to the centre node 0.
  const int ns = static_cast<int>(m.nodes.size());
  for (int i = 1; i < ns; ++i)
    for (int j = i + 1; j < ns; ++j)
      for (int k = j + 1; k < ns; ++k) {
        const Eigen::Vector3d n = (m.nodes[j] - m.nodes[i]).cross(m.nodes[k] - m.nodes[i]);
        int pos = 0, neg = 0;
        for (int l = 1; l < ns; ++l) {
          if (l == i || l == j || l == k) continue;
          const double d = n.dot(m.nodes[l] - m.nodes[i]);
          if (d > 1e-12 * radius_m * radius_m * radius_m) ++pos;
          else if (d < -1e-12 * radius_m * radius_m * radius_m) ++neg;
        }
        if (pos == 0 || neg == 0) m.tets.push_back({0, i, j, k});
      }
  finish_mesh(m);
  m.description = "paper ball: pentakis dodecahedron coned to its centre (33 nodes)";
  if (m.node_count() != 33 || m.tets.size() != 60 || m.edges.size() != 122)
    throw std::logic_error("make_paper_ball: unexpected mesh size");
  return m;
}

namespace {
// Calls f(i, j, k) for every lattice cube (corner (i, j, k), spacing h) whose 8 corners are inside
// the sphere of radius R; returns the half-width K of the scanned lattice.
template <class F>
int for_each_inside_cube(double h, double R, F&& f) {
  const int K = static_cast<int>(std::ceil(R / h)) + 1;
  auto inside = [&](int i, int j, int k) { return std::sqrt(double(i * i + j * j + k * k)) * h <= R * (1 + 1e-9); };
  for (int i = -K; i < K; ++i)
    for (int j = -K; j < K; ++j)
      for (int k = -K; k < K; ++k) {
        bool all = true;
        for (int c = 0; c < 8 && all; ++c) all = inside(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        if (all) f(i, j, k);
      }
  return K;
}

// Nodes of the lattice ball with spacing h (the corners of the inside cubes, which the mesh below
// uses exactly). Counting needs no mesh: a flag per lattice point.
long lattice_ball_node_count(double h, double R) {
  const int K = static_cast<int>(std::ceil(R / h)) + 1;
  const auto W = static_cast<std::size_t>(2 * K + 1);
  std::vector<unsigned char> used(W * W * W, 0);
  long count = 0;
  for_each_inside_cube(h, R, [&](int i, int j, int k) {
    for (int c = 0; c < 8; ++c) {
      const auto at = (static_cast<std::size_t>(i + (c & 1) + K) * W + static_cast<std::size_t>(j + ((c >> 1) & 1) + K)) * W +
                      static_cast<std::size_t>(k + ((c >> 2) & 1) + K);
      count += used[at] == 0;
      used[at] = 1;
    }
  });
  return count;
}

TetMesh lattice_ball_with_spacing(double h, double R) {
  std::map<std::array<int, 3>, int> index;
  TetMesh m;
  auto node = [&](int i, int j, int k) {
    auto [it, fresh] = index.try_emplace({i, j, k}, static_cast<int>(m.nodes.size()));
    if (fresh) m.nodes.emplace_back(i * h, j * h, k * h);
    return it->second;
  };
  // Kuhn split of the unit cube along the main diagonal 0 -> 7: six tetrahedra, one per
  // permutation of the axes; identical on shared faces of neighbouring cubes.
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for_each_inside_cube(h, R, [&](int i, int j, int k) {
        for (const auto& p : perms) {
          std::array<int, 3> v = {i, j, k};
          std::array<int, 4> t{};
          t[0] = node(v[0], v[1], v[2]);
          for (int s = 0; s < 3; ++s) {
            v[static_cast<std::size_t>(p[s])] += 1;
            t[static_cast<std::size_t>(s) + 1] = node(v[0], v[1], v[2]);
          }
          m.tets.push_back(t);
        }
  });
  finish_mesh(m);
  // Project boundary nodes radially onto the sphere (springs only depend on connectivity and
  // rest offsets, so this changes the shape, not the validity of the model).
  std::set<int> boundary;
  for (const auto& f : m.surface)
    for (int v : f) boundary.insert(v);
  for (int v : boundary)
    if (m.nodes[static_cast<std::size_t>(v)].norm() > 0) m.nodes[static_cast<std::size_t>(v)] = R * m.nodes[static_cast<std::size_t>(v)].normalized();
  finish_mesh(m);  // re-orient faces after projection
  return m;
}
}  // namespace

TetMesh make_lattice_ball(int target_nodes, double radius_m) {
  if (target_nodes < 7 || target_nodes > 200000)
    throw std::invalid_argument("lattice ball: nodes must be in [7, 200000]");
  if (!(radius_m > 0)) throw std::invalid_argument("ball radius must be > 0");
  // Node count grows like (4/3) pi (R/h)^3; scan a bracket of spacings around that estimate.
  const double h0 = radius_m * std::cbrt(4.0 * std::numbers::pi / (3.0 * target_nodes));
  double best_h = 0;
  long best_err = -1;
  for (int s = -12; s <= 12; ++s) {
    const double h = h0 * (1.0 + 0.025 * s);
    const long count = lattice_ball_node_count(h, radius_m);
    if (count == 0) continue;
    const long err = std::labs(count - target_nodes);
    if (best_err < 0 || err < best_err) {
      best_err = err;
      best_h = h;
    }
  }
  if (best_err < 0) throw std::runtime_error("lattice ball: no mesh for that target");
  TetMesh best = lattice_ball_with_spacing(best_h, radius_m);
  best.description = "lattice ball (Kuhn-split cubes, boundary projected), " + std::to_string(best.node_count()) + " nodes";
  return best;
}

}  // namespace haptic::rt
