// Surface mesh readers: Wavefront .obj, STL (ASCII and binary), .off. Start-up only (allocates,
// reads files). Not RT-safe.
#include <cstring>
#include <map>
#include <sstream>

#include "firmware/scene/mesh_io.hpp"
#include "firmware/scene/text_cursor.hpp"

namespace haptic::scene {

namespace {

void check_vertices(const TextCursor& c, std::size_t n, const MeshLimits& limits) {
  if (static_cast<long long>(n) > limits.max_nodes)
    c.fail("more than " + std::to_string(limits.max_nodes) + " vertices: above the limit (a huge file?)");
}

void add_triangle(const TextCursor& c, RawSurface& s, int a, int b, int d, int line, const MeshLimits& limits) {
  if (static_cast<long long>(s.triangles.size()) >= limits.max_elements)
    c.fail_at(line, "more than " + std::to_string(limits.max_elements) + " triangles: above the limit (a huge file?)");
  s.triangles.push_back({a, b, d});
  s.triangle_line.push_back(line);
}

// Polygons are split into a fan of triangles around their first vertex.
void add_polygon(const TextCursor& c, RawSurface& s, const std::vector<int>& v, int line, const MeshLimits& limits) {
  if (v.size() < 3) c.fail_at(line, "a face needs at least 3 vertices");
  for (std::size_t i = 1; i + 1 < v.size(); ++i) add_triangle(c, s, v[0], v[i], v[i + 1], line, limits);
}

// Merges STL's repeated corner coordinates into shared vertices.
struct VertexMerge {
  RawSurface& s;
  std::map<std::array<double, 3>, int> index;
  int at(const Eigen::Vector3d& p) {
    const auto [it, fresh] = index.try_emplace({p[0], p[1], p[2]}, static_cast<int>(s.nodes.size()));
    if (fresh) s.nodes.push_back(p);
    return it->second;
  }
};

RawSurface read_stl_binary(const std::string& path, const std::string& data, const MeshLimits& limits) {
  RawSurface s;
  s.file = path;
  s.lines_are_facets = true;
  std::uint32_t count = 0;
  std::memcpy(&count, data.data() + 80, 4);
  const TextCursor c(data, path);
  if (static_cast<long long>(count) > limits.max_elements)
    c.fail_at(0, std::to_string(count) + " facets: above the limit of " + std::to_string(limits.max_elements) + " (a huge file?)");
  VertexMerge merge{s, {}};
  for (std::uint32_t f = 0; f < count; ++f) {
    const char* rec = data.data() + 84 + 50 * static_cast<std::size_t>(f);
    int v[3];
    for (int k = 0; k < 3; ++k) {
      float xyz[3];
      std::memcpy(xyz, rec + 12 + 12 * k, 12);
      v[k] = merge.at(Eigen::Vector3d(xyz[0], xyz[1], xyz[2]));
    }
    check_vertices(c, s.nodes.size(), limits);
    add_triangle(c, s, v[0], v[1], v[2], static_cast<int>(f) + 1, limits);
  }
  return s;
}

}  // namespace

RawSurface read_obj(const std::string& path, const MeshLimits& limits) {
  const std::string text = read_limited(path, limits);
  TextCursor c(text, path);
  RawSurface s;
  s.file = path;
  while (!c.at_end()) {
    const std::string line(c.line_rest());
    const int at = c.line();
    std::istringstream is(line);
    std::string kind;
    is >> kind;
    if (kind == "v") {
      Eigen::Vector3d p;
      if (!(is >> p[0] >> p[1] >> p[2]) || !p.allFinite()) c.fail_at(at, "a vertex needs three finite coordinates");
      s.nodes.push_back(p);
      check_vertices(c, s.nodes.size(), limits);
    } else if (kind == "f") {
      std::vector<int> v;
      std::string tok;
      while (is >> tok) {
        long long i = 0;
        try {
          i = std::stoll(tok.substr(0, tok.find('/')));
        } catch (const std::exception&) {
          c.fail_at(at, "'" + tok + "' is not a vertex index");
        }
        const long long idx = i < 0 ? static_cast<long long>(s.nodes.size()) + i : i - 1;  // negative: relative
        if (i == 0 || idx < 0 || idx >= static_cast<long long>(s.nodes.size()))
          c.fail_at(at, "face refers to vertex " + std::to_string(i) + ", which is not defined above it");
        v.push_back(static_cast<int>(idx));
      }
      add_polygon(c, s, v, at, limits);
    }  // vn, vt, o, g, s, usemtl, mtllib, comments: not geometry
  }
  return s;
}

RawSurface read_stl(const std::string& path, const MeshLimits& limits) {
  const std::string data = read_limited(path, limits);
  if (data.size() >= 84) {
    std::uint32_t count = 0;
    std::memcpy(&count, data.data() + 80, 4);
    if (data.size() == 84 + 50 * static_cast<std::size_t>(count)) return read_stl_binary(path, data, limits);
  }
  TextCursor c(data, path);
  RawSurface s;
  s.file = path;
  VertexMerge merge{s, {}};
  c.expect("solid");
  c.line_rest();  // the solid's name
  while (true) {
    const std::string_view t = c.token("'facet' or 'endsolid'");
    if (t == "endsolid") break;
    if (t != "facet") c.fail("expected 'facet' or 'endsolid', found '" + std::string(t) + "' (a binary STL whose size does not match its facet count?)");
    const int at = c.line();
    c.expect("normal");
    for (int k = 0; k < 3; ++k) c.real("a normal component");
    c.expect("outer");
    c.expect("loop");
    int v[3];
    for (int& x : v) {
      c.expect("vertex");
      Eigen::Vector3d p;
      for (int d = 0; d < 3; ++d) p[d] = c.real("a coordinate");
      x = merge.at(p);
    }
    check_vertices(c, s.nodes.size(), limits);
    c.expect("endloop");
    c.expect("endfacet");
    add_triangle(c, s, v[0], v[1], v[2], at, limits);
  }
  return s;
}

RawSurface read_off(const std::string& path, const MeshLimits& limits) {
  const std::string text = read_limited(path, limits);
  TextCursor c(text, path, '#');
  RawSurface s;
  s.file = path;
  c.expect("OFF");
  const long long nv = c.integer("the number of vertices");
  const long long nf = c.integer("the number of faces");
  c.integer("the number of edges");
  if (nv < 0 || nv > limits.max_nodes) c.fail(std::to_string(nv) + " vertices: outside [0, " + std::to_string(limits.max_nodes) + "] (a huge file?)");
  if (nf < 0 || nf > limits.max_elements) c.fail(std::to_string(nf) + " faces: outside [0, " + std::to_string(limits.max_elements) + "] (a huge file?)");
  for (long long i = 0; i < nv; ++i) {
    Eigen::Vector3d p;
    for (int d = 0; d < 3; ++d) p[d] = c.real("a coordinate");
    s.nodes.push_back(p);
  }
  for (long long f = 0; f < nf; ++f) {
    const long long k = c.integer("the number of vertices of a face");
    const int at = c.line();
    if (k < 3 || k > 1000) c.fail("a face needs 3..1000 vertices");
    std::vector<int> v;
    for (long long j = 0; j < k; ++j) {
      const long long i = c.integer("a vertex index");
      if (i < 0 || i >= nv) c.fail("face refers to vertex " + std::to_string(i) + ", which does not exist (0.." + std::to_string(nv - 1) + ")");
      v.push_back(static_cast<int>(i));
    }
    c.line_rest();  // optional colour
    add_polygon(c, s, v, at, limits);
  }
  return s;
}

}  // namespace haptic::scene
