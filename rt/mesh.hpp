#pragma once
// Tetrahedral meshes of the ball-like virtual object. Start-up only (allocates).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

namespace haptic::rt {

struct TetMesh {
  std::vector<Eigen::Vector3d> nodes;       // rest positions x_d (m)
  std::vector<std::array<int, 4>> tets;
  std::vector<std::array<int, 2>> edges;    // unique tetrahedron edges (i < j); one spring each
  std::vector<std::array<int, 3>> surface;  // boundary triangles, counter-clockwise seen from outside
  std::string description;

  int node_count() const { return static_cast<int>(nodes.size()); }
  Eigen::Vector3d centroid() const;
  Eigen::Vector3d face_normal(int face) const;  // outward unit normal at rest
  Eigen::Vector3d face_center(int face) const;
  // Index of the boundary face whose outward normal is closest to `direction`.
  int face_towards(const Eigen::Vector3d& direction) const;
  // Where a proxy moving from `origin` along `direction` first touches the surface: the index of
  // the boundary triangle the ray hits first (Moller-Trumbore), -1 if it misses; `*point` gets
  // the touch point. Start-up only.
  int surface_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, Eigen::Vector3d* point) const;
  // The contact face of a user's proxy that starts outside the object, at centroid + 2 x
  // bounding radius x direction, and approaches the centroid: surface_hit of that ray (-1: none).
  int face_touched_from(const Eigen::Vector3d& direction, Eigen::Vector3d* touch) const;
  // Largest distance of a node from the centroid (m).
  double bounding_radius() const;
  // Signed volume of tetrahedron t: (b-a) x (c-a) . (d-a) / 6 (> 0 for the positive orientation).
  double tet_volume(int t) const;
};

// The paper's reference scene (Section V, Fig. 3): a 33-node ball. The paper does not publish
// its mesh (87 tetrahedra); ours is the pentakis dodecahedron (12 icosahedron + 20 dodecahedron
// vertices on the sphere) coned to a centre node: 33 nodes, 60 tetrahedra, 122 edges,
// 60 boundary triangles.
TetMesh make_paper_ball(double radius_m = 0.05);

// A ball of about `target_nodes` nodes from our documented generator: the cubic lattice of
// spacing h inside the sphere, every lattice cube whose 8 corners lie inside split into 6
// tetrahedra (Kuhn/Freudenthal split, conforming across cubes), boundary nodes projected
// radially onto the sphere. h is searched so the node count is as close as possible to the
// target. Deterministic.
TetMesh make_lattice_ball(int target_nodes, double radius_m = 0.05);

// Fills edges and surface from nodes + tets; each boundary triangle is oriented away from its
// tetrahedron's fourth node (outward for any shape, convex or not).
void finish_mesh(TetMesh& mesh);

}  // namespace haptic::rt
