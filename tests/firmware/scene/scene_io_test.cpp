// Scenes from files: every reader gives the same box; bad meshes fail with the
// file and the element/line named; the material keeps the object at any resolution.
#include <CppUTest/TestHarness.h>

#include <Eigen/Eigenvalues>
#include <filesystem>
#include <string>

#include "firmware/scene/mesh_check.hpp"
#include "firmware/scene/mesh_io.hpp"
#include "rt/scene.hpp"
#include "tests/firmware/scene/fixtures.hpp"
#include "tests/support/error_of.hpp"

using namespace haptic;
using haptic::test::error_of;

namespace {

double volume(const rt::TetMesh& m) {
  double v = 0;
  for (int t = 0; t < static_cast<int>(m.tets.size()); ++t) v += m.tet_volume(t);
  return v;
}

bool tetgen_available() { return std::system("command -v tetgen > /dev/null 2>&1") == 0; }

}  // namespace

// A scratch folder and a Kuhn box of n^3 cubes, side 1.
struct BoxFolder : Utest {
  std::string dir;
  test::BoxMesh box;
  void make(const char* name, int n) {
    dir = test::scratch_dir(name);
    box = test::kuhn_box(n, 1.0);
  }
  void teardown() override { std::filesystem::remove_all(dir); }
};

TEST_GROUP_BASE(SceneReaders, BoxFolder) {
  void setup() override { make("readers", 2); }
};

TEST(SceneReaders, every_volume_format_reads_the_same_box_scaled_by_the_unit) {
  test::write_text(dir + "/box2.msh", test::msh2(box));
  test::write_text(dir + "/box4.msh", test::msh41(box));
  test::write_tetgen(box, dir + "/box");
  test::write_text(dir + "/box.vtk", test::vtk(box));
  scene::MeshReadOptions o;
  o.unit_m = 0.01;  // a box of 1 cm
  for (const std::string f : {"/box2.msh", "/box4.msh", "/box.node", "/box.ele", "/box.vtk"}) {
    const rt::TetMesh m = scene::read_scene_mesh(dir + f, o);
    CHECK_EQUAL(27, m.node_count());
    CHECK_EQUAL(48u, m.tets.size());
    CHECK_EQUAL(48u, m.surface.size());  // 6 sides x 4 squares x 2 triangles
    DOUBLES_EQUAL(1e-6, volume(m), 1e-15);
    DOUBLES_EQUAL(0.01, m.nodes[26][0], 1e-12);
  }
}

TEST(SceneReaders, every_surface_format_is_tetrahedralized_by_tetgen) {
  if (!tetgen_available()) {
    TEST_EXIT;  // reported by the separate CTest skip test scene_tetgen_present
  }
  const test::BoxMesh surface = test::surface_only(box);
  test::write_text(dir + "/box.obj", test::obj(surface));
  test::write_text(dir + "/box.off", test::off(surface));
  test::write_text(dir + "/box.stl", test::stl_ascii(surface));
  test::write_stl_binary(surface, dir + "/boxb.stl");
  for (const std::string f : {"/box.obj", "/box.off", "/box.stl", "/boxb.stl"}) {
    const rt::TetMesh m = scene::read_scene_mesh(dir + f);
    CHECK_TRUE(m.node_count() >= 26);
    DOUBLES_EQUAL(1.0, volume(m), 1e-9);  // the closed surface's volume, whatever TetGen adds inside
    CHECK_TRUE(m.tets.size() >= 6);
  }
}

TEST(SceneReaders, surface_faces_point_outward_and_the_proxy_ray_finds_the_touched_face) {
  test::write_text(dir + "/box.msh", test::msh2(box));
  const rt::TetMesh m = scene::read_scene_mesh(dir + "/box.msh");
  const Eigen::Vector3d c(0.5, 0.5, 0.5);
  for (int f = 0; f < static_cast<int>(m.surface.size()); ++f) CHECK_TRUE(m.face_normal(f).dot(m.face_center(f) - c) > 0);
  Eigen::Vector3d p;
  const int f = m.surface_hit(Eigen::Vector3d(0.3, 0.6, 5.0), Eigen::Vector3d(0, 0, -1), &p);
  CHECK_TRUE(f >= 0);
  DOUBLES_EQUAL(1.0, p.z(), 1e-12);
  DOUBLES_EQUAL(1.0, m.face_normal(f).z(), 1e-12);
  for (int v : m.surface[static_cast<std::size_t>(f)]) DOUBLES_EQUAL(1.0, m.nodes[static_cast<std::size_t>(v)].z(), 1e-12);
  CHECK_EQUAL(-1, m.surface_hit(Eigen::Vector3d(3, 3, 5), Eigen::Vector3d(0, 0, -1), nullptr));
}

TEST_GROUP_BASE(BadMeshes, BoxFolder) {
  void setup() override { make("bad", 1); }
  std::string read_error(const test::BoxMesh& b, const scene::MeshLimits& limits = {}) {
    test::write_text(dir + "/bad.msh", test::msh2(b));
    scene::MeshReadOptions o;
    o.limits = limits;
    return error_of([&] { scene::read_scene_mesh(dir + "/bad.msh", o); });
  }
};

// msh2 writes node i on line 6 + i and element t (0-based) as id t + 2 on line 7 + nodes + 5 + t.
TEST(BadMeshes, an_inverted_tetrahedron_is_named_with_its_line) {
  std::swap(box.tets[3][0], box.tets[3][1]);
  STRCMP_CONTAINS("bad.msh:21: element 5: inverted tetrahedron", read_error(box).c_str());
}

TEST(BadMeshes, a_degenerate_tetrahedron_is_named_with_its_line) {
  box.nodes.emplace_back(0.5, 0.5, 0.0);  // flat: z = 0 like nodes 0, 2, 4
  box.tets.push_back({0, 2, 4, 8});
  const std::string e = read_error(box);
  STRCMP_CONTAINS("bad.msh:25: element 8: degenerate tetrahedron", e.c_str());
  box.tets.back() = {0, 1, 1, 3};
  STRCMP_CONTAINS("element 8: degenerate tetrahedron (node 2 twice)", read_error(box).c_str());
}

TEST(BadMeshes, an_unreferenced_node_is_named_with_its_line) {
  box.nodes.emplace_back(3.0, 3.0, 3.0);
  STRCMP_CONTAINS("bad.msh:14: node 9: unreferenced node", read_error(box).c_str());
}

namespace {
// `box` and a copy shifted by `shift`, the copy's nodes that coincide with the first box's merged into them.
test::BoxMesh two_boxes_touching(const test::BoxMesh& box, const Eigen::Vector3d& shift) {
  test::BoxMesh two = box;
  const int n0 = static_cast<int>(two.nodes.size());
  for (const auto& p : box.nodes) two.nodes.push_back(p + shift);
  for (auto t : box.tets) {
    for (int& v : t) v += n0;
    two.tets.push_back(t);
  }
  for (auto& t : two.tets)
    for (int& v : t)
      if (v >= n0)
        for (int w = 0; w < n0; ++w)
          if ((two.nodes[w] - two.nodes[v]).norm() < 1e-12) v = w;
  std::vector<int> used(two.nodes.size(), 0);
  for (const auto& t : two.tets)
    for (int v : t) used[v] = 1;
  test::BoxMesh compact;
  std::vector<int> map(two.nodes.size(), -1);
  for (std::size_t i = 0; i < two.nodes.size(); ++i)
    if (used[i]) {
      map[i] = static_cast<int>(compact.nodes.size());
      compact.nodes.push_back(two.nodes[i]);
    }
  for (auto t : two.tets) {
    for (int& v : t) v = map[v];
    compact.tets.push_back(t);
  }
  return compact;
}
}  // namespace

TEST(BadMeshes, a_non_manifold_mesh_is_refused) {
  // A second box touching the first along one edge only: that edge is on 4 boundary triangles.
  const test::BoxMesh compact = two_boxes_touching(box, Eigen::Vector3d(1, 1, 0));
  STRCMP_CONTAINS("non-manifold surface: the boundary edge between nodes", read_error(compact).c_str());
  // A face shared by three tetrahedra.
  box.tets.push_back(box.tets[0]);
  STRCMP_CONTAINS("element 8: non-manifold mesh: a face is shared by 3 tetrahedra", read_error(box).c_str());
}

TEST(BadMeshes, two_pieces_touching_at_one_node_are_refused) {
  // A second box touching the first at the corner (1, 1, 1) only: every edge and face is fine, but the
  // boundary touches itself at that node (two fans of boundary triangles around it).
  const std::string e = read_error(two_boxes_touching(box, Eigen::Vector3d(1, 1, 1)));
  STRCMP_CONTAINS("bad.msh:", e.c_str());
  STRCMP_CONTAINS("non-manifold surface at node ", e.c_str());
  STRCMP_CONTAINS("the boundary touches itself there", e.c_str());
}

TEST(BadMeshes, a_non_manifold_surface_file_is_refused_before_tetgen) {
  test::BoxMesh b = test::kuhn_box(1, 1.0);
  b.surface.pop_back();  // a hole: three edges on one triangle only
  test::write_text(dir + "/hole.obj", test::obj(b));
  const std::string e = error_of([&] { scene::read_scene_mesh(dir + "/hole.obj"); });
  STRCMP_CONTAINS("hole.obj:", e.c_str());
  STRCMP_CONTAINS("non-manifold surface: the edge between vertices", e.c_str());
  STRCMP_CONTAINS("on 1 triangles (a closed surface needs exactly 2)", e.c_str());
}

TEST(BadMeshes, two_closed_shells_touching_at_a_corner_are_named_in_the_users_file) {
  // two unit cubes, each closed and manifold, the second's vertex 1 on the first's vertex 7 (1, 1, 1):
  // refused before TetGen, with the file's own vertex numbers (not TetGen's output elements)
  test::BoxMesh b = test::kuhn_box(1, 1.0);
  std::string text = test::obj(b);
  const std::size_t nv = b.nodes.size();
  for (const auto& x : b.nodes) text += "v " + std::to_string(x.x() + 1) + " " + std::to_string(x.y() + 1) + " " + std::to_string(x.z() + 1) + "\n";
  for (const auto& f : b.surface)
    text += "f " + std::to_string(f[0] + 1 + nv) + " " + std::to_string(f[1] + 1 + nv) + " " + std::to_string(f[2] + 1 + nv) + "\n";
  test::write_text(dir + "/touching.obj", text);
  const std::string e = error_of([&] { scene::read_scene_mesh(dir + "/touching.obj"); });
  STRCMP_CONTAINS("touching.obj:0: vertex ", e.c_str());
  STRCMP_CONTAINS("at the same point as vertex", e.c_str());
  STRCMP_CONTAINS("the surface touches itself there", e.c_str());
}

TEST(BadMeshes, huge_files_and_counts_are_refused_before_reading_them) {
  scene::MeshLimits small;
  small.max_file_bytes = 200;
  STRCMP_CONTAINS("bytes: above the limit of 200 bytes", read_error(box, small).c_str());
  scene::MeshLimits few;
  few.max_nodes = 5;
  STRCMP_CONTAINS("bad.msh:5: 8 nodes: above the limit of 5", read_error(box, few).c_str());
  few = {};
  few.max_elements = 4;
  STRCMP_CONTAINS("more than 4 tetrahedra: above the limit", read_error(box, few).c_str());
}

TEST(BadMeshes, syntax_errors_name_the_file_and_line) {
  test::write_text(dir + "/x.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 zero 0\n$EndNodes\n");
  STRCMP_CONTAINS("x.msh:6: expected a coordinate (a finite number), found 'zero'", error_of([&] { scene::read_gmsh(dir + "/x.msh", {}); }).c_str());
  test::write_text(dir + "/y.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n");
  STRCMP_CONTAINS("y.msh:2: binary .msh not supported", error_of([&] { scene::read_gmsh(dir + "/y.msh", {}); }).c_str());
  test::write_text(dir + "/z.vtk", "# vtk DataFile Version 2.0\nt\nASCII\nDATASET POLYDATA\n");
  STRCMP_CONTAINS("z.vtk:4: the dataset must be UNSTRUCTURED_GRID", error_of([&] { scene::read_vtk(dir + "/z.vtk", {}); }).c_str());
  STRCMP_CONTAINS("unknown mesh format '.ply'", error_of([&] { scene::read_scene_mesh(dir + "/a.ply"); }).c_str());
  STRCMP_CONTAINS("nothere.msh:0: cannot read the mesh file", error_of([&] { scene::read_scene_mesh(dir + "/nothere.msh"); }).c_str());
}

// ---------------------------------------------------------------- material

namespace {
// Lowest non-zero eigenvalue omega^2 of K phi = omega^2 M phi (node level; the 3 translations
// are the zero modes of the isotropic spring network, one per coordinate).
double lowest_frequency_squared(const rt::Scene& s) {
  const Eigen::MatrixXd K = Eigen::MatrixXd(s.K_int.S), M = Eigen::MatrixXd(s.M.S);
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(K, M);
  return es.eigenvalues()[1];
}

rt::Scene box_scene(int n, const rt::Material& mat) {
  const test::BoxMesh b = test::kuhn_box(n, 0.1);
  rt::TetMesh m;
  m.nodes = b.nodes;
  m.tets = b.tets;
  rt::finish_mesh(m);
  return rt::build_scene(m, rt::SceneParams{}, rt::lump_material(m, mat));
}
}  // namespace

TEST_GROUP(Material){};

TEST(Material, the_same_object_at_any_resolution_has_the_same_mass_and_lowest_mode) {
  const rt::Material steelish{2000.0, 5e4};
  const rt::Scene coarse = box_scene(2, steelish), fine = box_scene(6, steelish);
  double mc = 0, mf = 0;
  for (int i = 0; i < coarse.nodes; ++i) mc += coarse.M.S.coeff(i, i);
  for (int i = 0; i < fine.nodes; ++i) mf += fine.M.S.coeff(i, i);
  DOUBLES_EQUAL(2.0, mc, 1e-12);  // rho x (0.1 m)^3
  DOUBLES_EQUAL(2.0, mf, 1e-12);
  const double wc = lowest_frequency_squared(coarse), wf = lowest_frequency_squared(fine);
  // 27 and 343 nodes: the lowest mode (the object's slowest deformation) agrees within 10 %.
  CHECK_TRUE(std::abs(wc / wf - 1) < 0.10);
  // The same springs and masses at every node (the paper's per-node constants) would not:
  const rt::Scene uc = rt::build_scene(coarse.mesh, rt::SceneParams{}), uf = rt::build_scene(fine.mesh, rt::SceneParams{});
  CHECK_TRUE(lowest_frequency_squared(uc) / lowest_frequency_squared(uf) > 3);
}

TEST(Material, stiffness_scales_with_youngs_modulus_and_mass_with_density) {
  const rt::Scene a = box_scene(2, {1000.0, 1e4}), b = box_scene(2, {3000.0, 4e4});
  DOUBLES_EQUAL(3.0, b.M.S.coeff(5, 5) / a.M.S.coeff(5, 5), 1e-12);
  DOUBLES_EQUAL(4.0, b.lambda_max_K_int / a.lambda_max_K_int, 1e-9);
}

TEST(Material, the_default_material_reproduces_the_paper_ball) {
  const rt::Material p = rt::paper_ball_material();
  const rt::TetMesh ball = rt::make_paper_ball(0.05);
  const rt::Scene s = rt::build_scene(ball, rt::SceneParams{}, rt::lump_material(ball, p));
  DOUBLES_EQUAL(0.04, s.params.node_mass_kg, 1e-12);
  DOUBLES_EQUAL(100.0, s.params.edge_stiffness_N_per_m, 1e-9);
  STRCMP_CONTAINS("scene.density_kg_per_m3 must be > 0", error_of([] { rt::Material{0, 1}.validate(); }).c_str());
  STRCMP_CONTAINS("scene.youngs_modulus_Pa must be > 0", error_of([] { rt::Material{1, -1}.validate(); }).c_str());
}
