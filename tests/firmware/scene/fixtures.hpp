#pragma once
// Test meshes written in every supported format: a box split into Kuhn tetrahedra (n^3 cubes, 6
// tetrahedra each, positively oriented), and its boundary as a triangle surface.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>
#include <string>
#include <vector>

namespace haptic::test {

struct BoxMesh {
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<int, 4>> tets;
  std::vector<std::array<int, 3>> surface;  // outward
};

inline BoxMesh kuhn_box(int n, double side) {
  BoxMesh b;
  auto id = [n](int i, int j, int k) { return (i * (n + 1) + j) * (n + 1) + k; };
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      for (int k = 0; k <= n; ++k) b.nodes.emplace_back(side * i / n, side * j / n, side * k / n);
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k)
        for (const auto& p : perms) {
          std::array<int, 3> v = {i, j, k};
          std::array<int, 4> t{id(i, j, k), 0, 0, 0};
          for (int s = 0; s < 3; ++s) {
            v[static_cast<std::size_t>(p[s])] += 1;
            t[static_cast<std::size_t>(s) + 1] = id(v[0], v[1], v[2]);
          }
          const auto& P = b.nodes;
          if ((P[t[1]] - P[t[0]]).cross(P[t[2]] - P[t[0]]).dot(P[t[3]] - P[t[0]]) < 0) std::swap(t[2], t[3]);
          b.tets.push_back(t);
        }
  // Boundary: two triangles per boundary square, outward.
  auto quad = [&](int a, int bb, int c, int d) {
    b.surface.push_back({a, bb, c});
    b.surface.push_back({a, c, d});
  };
  for (int u = 0; u < n; ++u)
    for (int w = 0; w < n; ++w) {
      quad(id(0, u, w), id(0, u, w + 1), id(0, u + 1, w + 1), id(0, u + 1, w));
      quad(id(n, u, w), id(n, u + 1, w), id(n, u + 1, w + 1), id(n, u, w + 1));
      quad(id(u, 0, w), id(u + 1, 0, w), id(u + 1, 0, w + 1), id(u, 0, w + 1));
      quad(id(u, n, w), id(u, n, w + 1), id(u + 1, n, w + 1), id(u + 1, n, w));
      quad(id(u, w, 0), id(u, w + 1, 0), id(u + 1, w + 1, 0), id(u + 1, w, 0));
      quad(id(u, w, n), id(u + 1, w, n), id(u + 1, w + 1, n), id(u, w + 1, n));
    }
  return b;
}

// The boundary alone (surface files list only the vertices their triangles use).
inline BoxMesh surface_only(const BoxMesh& b) {
  BoxMesh s;
  std::vector<int> map(b.nodes.size(), -1);
  for (auto f : b.surface) {
    for (int& v : f) {
      if (map[static_cast<std::size_t>(v)] < 0) {
        map[static_cast<std::size_t>(v)] = static_cast<int>(s.nodes.size());
        s.nodes.push_back(b.nodes[static_cast<std::size_t>(v)]);
      }
      v = map[static_cast<std::size_t>(v)];
    }
    s.surface.push_back(f);
  }
  return s;
}

inline std::string scratch_dir(const std::string& name) {
  std::ostringstream leaf;
  leaf << "haptic-scene-test-" << ::getpid() << '-' << name;
  const auto d = std::filesystem::temp_directory_path() / leaf.str();
  std::filesystem::create_directories(d);
  return d.string();
}

inline void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Writers: one stream per file (std::ostringstream: no string concatenation at -O3, GCC 105329).
inline void xyz(std::ostringstream& os, const Eigen::Vector3d& p) { os << p[0] << ' ' << p[1] << ' ' << p[2]; }

inline std::string msh2(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  os << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" << b.nodes.size() << '\n';
  for (std::size_t i = 0; i < b.nodes.size(); ++i) {
    os << i + 1 << ' ';
    xyz(os, b.nodes[i]);
    os << '\n';
  }
  os << "$EndNodes\n$Elements\n" << b.tets.size() + 1 << "\n1 15 2 0 1 1\n";  // a point element: skipped
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    os << t + 2 << " 4 2 0 1";
    for (int v : b.tets[t]) os << ' ' << v + 1;
    os << '\n';
  }
  os << "$EndElements\n";
  return os.str();
}

inline std::string msh41(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  const auto n = b.nodes.size(), m = b.tets.size();
  os << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n1 0 0 0 1 1 1 0 0\n$EndEntities\n";
  os << "$Nodes\n1 " << n << " 1 " << n << "\n3 1 0 " << n << '\n';
  for (std::size_t i = 0; i < n; ++i) os << i + 1 << '\n';
  for (const auto& p : b.nodes) {
    xyz(os, p);
    os << '\n';
  }
  os << "$EndNodes\n$Elements\n1 " << m << " 1 " << m << "\n3 1 4 " << m << '\n';
  for (std::size_t t = 0; t < m; ++t) {
    os << t + 1;
    for (int v : b.tets[t]) os << ' ' << v + 1;
    os << '\n';
  }
  os << "$EndElements\n";
  return os.str();
}

inline void write_tetgen(const BoxMesh& b, const std::string& base) {
  std::ostringstream node, ele;
  node.precision(17);
  node << b.nodes.size() << " 3 0 0\n# comment\n";
  for (std::size_t i = 0; i < b.nodes.size(); ++i) {
    node << i << ' ';
    xyz(node, b.nodes[i]);
    node << '\n';
  }
  ele << b.tets.size() << " 4 0\n";
  for (std::size_t t = 0; t < b.tets.size(); ++t) {
    ele << t;
    for (int v : b.tets[t]) ele << ' ' << v;
    ele << '\n';
  }
  write_text(base + ".node", node.str());
  write_text(base + ".ele", ele.str());
}

inline std::string vtk(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  os << "# vtk DataFile Version 2.0\nbox\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS " << b.nodes.size() << " double\n";
  for (const auto& p : b.nodes) {
    xyz(os, p);
    os << '\n';
  }
  os << "CELLS " << b.tets.size() << ' ' << 5 * b.tets.size() << '\n';
  for (const auto& t : b.tets) os << "4 " << t[0] << ' ' << t[1] << ' ' << t[2] << ' ' << t[3] << '\n';
  os << "CELL_TYPES " << b.tets.size() << '\n';
  for (std::size_t t = 0; t < b.tets.size(); ++t) os << "10\n";
  return os.str();
}

inline std::string obj(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  os << "# box\no box\n";
  for (const auto& p : b.nodes) {
    os << "v ";
    xyz(os, p);
    os << '\n';
  }
  for (const auto& f : b.surface) os << "f " << f[0] + 1 << "/1 " << f[1] + 1 << "//2 " << f[2] + 1 << '\n';
  return os.str();
}

inline std::string off(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  os << "OFF\n" << b.nodes.size() << ' ' << b.surface.size() << " 0\n";
  for (const auto& p : b.nodes) {
    xyz(os, p);
    os << '\n';
  }
  for (const auto& f : b.surface) os << "3 " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
  return os.str();
}

inline std::string stl_ascii(const BoxMesh& b) {
  std::ostringstream os;
  os.precision(17);
  os << "solid box\n";
  for (const auto& f : b.surface) {
    os << "facet normal 0 0 0\n outer loop\n";
    for (int v : f) {
      os << "  vertex ";
      xyz(os, b.nodes[static_cast<std::size_t>(v)]);
      os << '\n';
    }
    os << " endloop\nendfacet\n";
  }
  os << "endsolid box\n";
  return os.str();
}

inline void write_stl_binary(const BoxMesh& b, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  const std::string header(80, ' ');
  out.write(header.data(), 80);
  const auto count = static_cast<std::uint32_t>(b.surface.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  for (const auto& f : b.surface) {
    float rec[12] = {};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) rec[3 + 3 * k + d] = static_cast<float>(b.nodes[f[k]][d]);
    out.write(reinterpret_cast<const char*>(rec), 48);
    const std::uint16_t attr = 0;
    out.write(reinterpret_cast<const char*>(&attr), 2);
  }
}

}  // namespace haptic::test
