#pragma once
// Scenes from files: tetrahedral meshes from Gmsh .msh (ASCII v2.2 and v4.1),
// TetGen .node/.ele and legacy VTK unstructured grids (ASCII), surface meshes (.obj, .stl ASCII
// or binary, .off) tetrahedralized by TetGen (Debian package `tetgen`, run as a program). Every
// mesh is checked (mesh_check.hpp) before it becomes an rt::TetMesh. Start-up only: reads files,
// allocates, may run a subprocess; never called from the tick. Not RT-safe.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "rt/mesh.hpp"

namespace haptic::scene {

// A bad mesh file: what() is "FILE:LINE: message" (line 0 when the place is not a line, e.g.
// "FILE: element 17 (line 42): ...").
struct MeshError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

struct MeshLimits {
  std::int64_t max_file_bytes = 256ll << 20;  // any input file larger than this is refused unread
  int max_nodes = 200000;
  int max_elements = 1000000;                 // tetrahedra (after TetGen for surfaces)
};

struct MeshReadOptions {
  double unit_m = 1.0;              // metres per file unit (mm files: 0.001)
  MeshLimits limits{};
  double tetgen_max_volume = 0;     // surfaces: TetGen's -a bound in file units^3; 0 = none
  double tetgen_timeout_s = 60;     // TetGen is killed after this long
};

// A volume mesh as read, before checks: nodes in file units, tetrahedra as 0-based node indices,
// and where each came from (1-based lines of `file`, 0 if unknown).
struct RawTetMesh {
  std::string node_file, element_file;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<int> node_id;          // the id written in the file, per node
  std::vector<int> node_line;
  std::vector<std::array<int, 4>> tets;
  std::vector<int> tet_id;           // the element id written in the file
  std::vector<int> tet_line;
};

// A triangle surface as read.
struct RawSurface {
  std::string file;
  std::vector<Eigen::Vector3d> nodes;
  std::vector<std::array<int, 3>> triangles;
  std::vector<int> triangle_line;  // 1-based line (ASCII) or 1-based facet number (binary STL)
  bool lines_are_facets = false;
};

// By extension: .msh, .node/.ele (either path; the other is beside it), .vtk, .obj, .stl, .off.
// Scales by unit_m, checks (check_tet_mesh), returns the finished mesh. Throws MeshError.
rt::TetMesh read_scene_mesh(const std::string& path, const MeshReadOptions& options = {});

RawTetMesh read_gmsh(const std::string& path, const MeshLimits& limits);
RawTetMesh read_tetgen(const std::string& path, const MeshLimits& limits);
RawTetMesh read_vtk(const std::string& path, const MeshLimits& limits);
RawSurface read_obj(const std::string& path, const MeshLimits& limits);
RawSurface read_stl(const std::string& path, const MeshLimits& limits);
RawSurface read_off(const std::string& path, const MeshLimits& limits);

// Runs `tetgen -pq1.414[aV]Q` on the surface (written as a .smesh in a private temporary folder)
// and reads its .node/.ele back. Throws MeshError when TetGen is missing, fails or times out.
RawTetMesh tetrahedralize(const RawSurface& surface, const MeshReadOptions& options);

// The whole file, refusing files above limits.max_file_bytes ("FILE: 300 MB is above the limit").
std::string read_limited(const std::string& path, const MeshLimits& limits);

}  // namespace haptic::scene
