// Tetrahedral mesh readers: Gmsh .msh (ASCII 2.2 and 4.1), TetGen .node/.ele, legacy VTK
// unstructured grid (ASCII). Start-up only (allocates, reads files). Not RT-safe.
#include <string_view>
#include <utility>
#include <unordered_map>

#include "firmware/scene/mesh_io.hpp"
#include "firmware/scene/text_cursor.hpp"

namespace haptic::scene {

namespace {

// Node ids as written -> indices; ids must be unique.
struct NodeTable {
  RawTetMesh& m;
  std::unordered_map<long long, int> index;
  void add(TextCursor& c, long long id, const Eigen::Vector3d& p) {
    if (!index.emplace(id, static_cast<int>(m.nodes.size())).second) c.fail("node " + std::to_string(id) + " defined twice");
    m.nodes.push_back(p);
    m.node_id.push_back(static_cast<int>(id));
    m.node_line.push_back(c.line());
  }
  int at(TextCursor& c, long long id, long long element) const {
    const auto it = index.find(id);
    if (it == index.end()) c.fail("element " + std::to_string(element) + ": refers to node " + std::to_string(id) + ", which is not defined");
    return it->second;
  }
};

void check_count(TextCursor& c, long long n, long long limit, const char* what) {
  if (n < 0) c.fail(std::string("negative number of ") + what);
  if (n > limit) c.fail(std::to_string(n) + " " + what + ": above the limit of " + std::to_string(limit) + " (a huge file?)");
}

Eigen::Vector3d point(TextCursor& c) {
  Eigen::Vector3d p;
  for (int d = 0; d < 3; ++d) p[d] = c.real("a coordinate");
  return p;
}

// Gmsh element types: 4 = 4-node tetrahedron; other 3-D types are refused, lower ones skipped.
bool gmsh_tet_type(TextCursor& c, long long type, long long id) {
  if (type == 4) return true;
  if (type == 11 || type == 29 || type == 30)
    c.fail("element " + std::to_string(id) + ": higher-order tetrahedron (Gmsh type " + std::to_string(type) + ") not supported: mesh with -order 1");
  if (type == 5 || type == 6 || type == 7 || type == 12 || type == 13 || type == 14 || type == 17 || type == 18 || type == 19)
    c.fail("element " + std::to_string(id) + ": volume element of Gmsh type " + std::to_string(type) + " is not a tetrahedron: mesh with tetrahedra only");
  return false;
}

void add_tet(TextCursor& c, RawTetMesh& m, const NodeTable& nodes, long long id, const long long (&v)[4], const MeshLimits& limits) {
  if (static_cast<long long>(m.tets.size()) >= limits.max_elements)
    c.fail("more than " + std::to_string(limits.max_elements) + " tetrahedra: above the limit (a huge file?)");
  m.tets.push_back({nodes.at(c, v[0], id), nodes.at(c, v[1], id), nodes.at(c, v[2], id), nodes.at(c, v[3], id)});
  m.tet_id.push_back(static_cast<int>(id));
  m.tet_line.push_back(c.line());
}

void gmsh_v2_nodes(TextCursor& c, NodeTable& nodes, const MeshLimits& limits) {
  const long long n = c.integer("the number of nodes");
  check_count(c, n, limits.max_nodes, "nodes");
  for (long long i = 0; i < n; ++i) {
    const long long id = c.integer("a node id");
    nodes.add(c, id, point(c));
  }
  c.expect("$EndNodes");
}

void gmsh_v2_elements(TextCursor& c, RawTetMesh& m, const NodeTable& nodes, const MeshLimits& limits) {
  const long long n = c.integer("the number of elements");
  check_count(c, n, 10ll * limits.max_elements, "elements");
  for (long long i = 0; i < n; ++i) {
    const long long id = c.integer("an element id");
    const long long type = c.integer("an element type");
    const long long ntags = c.integer("the number of tags");
    check_count(c, ntags, 64, "tags");
    for (long long t = 0; t < ntags; ++t) c.integer("a tag");
    if (!gmsh_tet_type(c, type, id)) {
      c.line_rest();  // lower-dimensional element: its nodes are on this line
      continue;
    }
    long long v[4];
    for (auto& x : v) x = c.integer("a node id");
    add_tet(c, m, nodes, id, v, limits);
  }
  c.expect("$EndElements");
}

void gmsh_v4_nodes(TextCursor& c, NodeTable& nodes, const MeshLimits& limits) {
  const long long blocks = c.integer("the number of node blocks");
  const long long n = c.integer("the number of nodes");
  check_count(c, n, limits.max_nodes, "nodes");
  c.integer("the smallest node tag");
  c.integer("the largest node tag");
  for (long long b = 0; b < blocks; ++b) {
    const long long dim = c.integer("an entity dimension");
    c.integer("an entity tag");
    const long long parametric = c.integer("the parametric flag");
    const long long count = c.integer("the number of nodes in the block");
    check_count(c, count, limits.max_nodes, "nodes");
    std::vector<long long> tags(static_cast<std::size_t>(count));
    for (auto& t : tags) t = c.integer("a node tag");
    for (const long long t : tags) {
      nodes.add(c, t, point(c));
      for (long long u = 0; parametric != 0 && u < dim; ++u) c.real("a parametric coordinate");
    }
  }
  c.expect("$EndNodes");
}

void gmsh_v4_elements(TextCursor& c, RawTetMesh& m, const NodeTable& nodes, const MeshLimits& limits) {
  const long long blocks = c.integer("the number of element blocks");
  check_count(c, c.integer("the number of elements"), 10ll * limits.max_elements, "elements");
  c.integer("the smallest element tag");
  c.integer("the largest element tag");
  for (long long b = 0; b < blocks; ++b) {
    c.integer("an entity dimension");
    c.integer("an entity tag");
    const long long type = c.integer("an element type");
    const long long count = c.integer("the number of elements in the block");
    check_count(c, count, 10ll * limits.max_elements, "elements");
    for (long long i = 0; i < count; ++i) {
      const long long id = c.integer("an element tag");
      if (!gmsh_tet_type(c, type, id)) {
        c.line_rest();
        continue;
      }
      long long v[4];
      for (auto& x : v) x = c.integer("a node tag");
      add_tet(c, m, nodes, id, v, limits);
    }
  }
  c.expect("$EndElements");
}

void skip_section(TextCursor& c, std::string_view name) {
  const std::string end = "$End" + std::string(name.substr(1));
  while (c.token(end.c_str()) != end) {
  }
}

// One file holding nodes and elements (Gmsh, VTK): its text, the mesh and the cursor over it.
struct SingleFile {
  std::string text;
  RawTetMesh m;
  TextCursor c;
  NodeTable nodes;
  SingleFile(const std::string& path, const MeshLimits& limits) : text(read_limited(path, limits)), c(text, path), nodes{m, {}} {
    m.node_file = m.element_file = path;
  }
};

}  // namespace

RawTetMesh read_gmsh(const std::string& path, const MeshLimits& limits) {
  SingleFile f(path, limits);
  TextCursor& c = f.c;
  RawTetMesh& m = f.m;
  NodeTable& nodes = f.nodes;
  c.expect("$MeshFormat");
  const std::string version(c.token("the format version"));
  const bool v2 = version.rfind("2.", 0) == 0, v41 = version == "4.1";
  if (!v2 && !v41) c.fail("Gmsh format " + version + " not supported (2.2 or 4.1: gmsh -format msh22 or msh41)");
  if (c.integer("the file type") != 0) c.fail("binary .msh not supported: save it as ASCII (gmsh -bin 0 ...)");
  c.integer("the data size");
  c.expect("$EndMeshFormat");
  bool have_nodes = false;
  while (!c.at_end()) {
    const std::string_view section = c.token("a section");
    if (section == "$Nodes") {
      v2 ? gmsh_v2_nodes(c, nodes, limits) : gmsh_v4_nodes(c, nodes, limits);
      have_nodes = true;
    } else if (section == "$Elements") {
      if (!have_nodes) c.fail("$Elements before $Nodes");
      v2 ? gmsh_v2_elements(c, m, nodes, limits) : gmsh_v4_elements(c, m, nodes, limits);
    } else if (!section.empty() && section[0] == '$') {
      skip_section(c, section);
    } else {
      c.fail("expected a section ($Nodes, $Elements, ...), found '" + std::string(section) + "'");
    }
  }
  return std::move(m);
}

RawTetMesh read_tetgen(const std::string& path, const MeshLimits& limits) {
  const auto dot = path.rfind('.');
  const std::string base = path.substr(0, dot);
  RawTetMesh m;
  m.node_file = base + ".node";
  m.element_file = base + ".ele";
  NodeTable nodes{m, {}};
  const std::string node_text = read_limited(m.node_file, limits);
  TextCursor n(node_text, m.node_file, '#');
  const long long count = n.integer("the number of points");
  check_count(n, count, limits.max_nodes, "nodes");
  if (n.integer("the dimension") != 3) n.fail("the dimension must be 3");
  const long long attributes = n.integer("the number of attributes");
  const long long markers = n.integer("the boundary marker flag");
  for (long long i = 0; i < count; ++i) {
    const long long id = n.integer("a point number");
    nodes.add(n, id, point(n));
    for (long long a = 0; a < attributes + (markers != 0 ? 1 : 0); ++a) n.real("an attribute or marker");
  }
  const std::string ele_text = read_limited(m.element_file, limits);
  TextCursor e(ele_text, m.element_file, '#');
  const long long tets = e.integer("the number of tetrahedra");
  check_count(e, tets, limits.max_elements, "tetrahedra");
  const long long corners = e.integer("the nodes per tetrahedron");
  if (corners == 10) e.fail("second-order tetrahedra (10 nodes) not supported: run tetgen without -o2");
  if (corners != 4) e.fail("nodes per tetrahedron must be 4");
  const long long region = e.integer("the region attribute flag");
  for (long long i = 0; i < tets; ++i) {
    const long long id = e.integer("a tetrahedron number");
    long long v[4];
    for (auto& x : v) x = e.integer("a node number");
    add_tet(e, m, nodes, id, v, limits);
    if (region != 0) e.real("a region attribute");
  }
  return m;
}

RawTetMesh read_vtk(const std::string& path, const MeshLimits& limits) {
  SingleFile f(path, limits);
  TextCursor& c = f.c;
  RawTetMesh& m = f.m;
  NodeTable& nodes = f.nodes;
  const std::string_view header = c.line_rest();
  if (header.rfind("# vtk DataFile Version", 0) != 0) c.fail("not a legacy VTK file (first line '# vtk DataFile Version ...')");
  if (header.find("Version 5") != std::string_view::npos) c.fail("VTK legacy 5.x (OFFSETS/CONNECTIVITY) not supported: write version 4.2 or lower");
  c.line_rest();  // title
  if (c.token("ASCII or BINARY") != "ASCII") c.fail("binary VTK not supported: write it as ASCII");
  c.expect("DATASET");
  if (c.token("the dataset type") != "UNSTRUCTURED_GRID") c.fail("the dataset must be UNSTRUCTURED_GRID");
  c.expect("POINTS");
  const long long n = c.integer("the number of points");
  check_count(c, n, limits.max_nodes, "nodes");
  c.token("the point data type");
  for (long long i = 0; i < n; ++i) nodes.add(c, i, point(c));
  c.expect("CELLS");
  const long long cells = c.integer("the number of cells");
  check_count(c, cells, 10ll * limits.max_elements, "cells");
  c.integer("the cell list size");
  std::vector<std::vector<long long>> conn(static_cast<std::size_t>(cells));
  std::vector<int> line(static_cast<std::size_t>(cells));
  for (long long i = 0; i < cells; ++i) {
    const long long k = c.integer("the number of points of a cell");
    check_count(c, k, 64, "points in a cell");
    line[static_cast<std::size_t>(i)] = c.line();
    for (long long j = 0; j < k; ++j) conn[static_cast<std::size_t>(i)].push_back(c.integer("a point index"));
  }
  c.expect("CELL_TYPES");
  if (c.integer("the number of cell types") != cells) c.fail("CELL_TYPES count differs from CELLS");
  for (long long i = 0; i < cells; ++i) {
    const long long type = c.integer("a cell type");
    const auto& v = conn[static_cast<std::size_t>(i)];
    if (type == 24) c.fail("cell " + std::to_string(i) + ": quadratic tetrahedron not supported");
    if (type == 12 || type == 13 || type == 14) c.fail("cell " + std::to_string(i) + ": volume cell type " + std::to_string(type) + " is not a tetrahedron");
    if (type != 10) continue;
    if (v.size() != 4) c.fail_at(line[static_cast<std::size_t>(i)], "cell " + std::to_string(i) + ": a tetrahedron (type 10) needs 4 points");
    const long long q[4] = {v[0], v[1], v[2], v[3]};
    add_tet(c, m, nodes, i, q, limits);
    m.tet_line.back() = line[static_cast<std::size_t>(i)];
  }
  return std::move(m);  // POINT_DATA / CELL_DATA after this are ignored
}

}  // namespace haptic::scene
