#pragma once
// Checks of meshes read from files. Every error names the file and the element
// (its id as written and its line): "ball.msh:412: element 77: inverted tetrahedron (volume
// -2.1e-09 m^3; corners must be ordered so that (b-a) x (c-a) . (d-a) > 0)". Start-up only
// (allocates). Not RT-safe.
#include "firmware/scene/mesh_io.hpp"
#include "rt/mesh.hpp"

namespace haptic::scene {

// Relative volume below which a tetrahedron is degenerate: |6V| < this x (longest edge)^3.
inline constexpr double kDegenerateRelativeVolume = 1e-9;

// Node indices in range, limits, every tetrahedron positively oriented and not degenerate,
// every node used by a tetrahedron, no face shared by more than two tetrahedra, a boundary that
// is a 2-manifold (every boundary edge on exactly two boundary triangles), one connected piece.
// Scales by unit_m and finishes the mesh (edges, oriented surface). Throws MeshError.
rt::TetMesh check_tet_mesh(const RawTetMesh& raw, double unit_m, const MeshLimits& limits);

// A closed 2-manifold triangle surface: indices in range, no degenerate or repeated triangle,
// every edge on exactly two triangles, every node used. Throws MeshError.
void check_surface(const RawSurface& surface);

}  // namespace haptic::scene
