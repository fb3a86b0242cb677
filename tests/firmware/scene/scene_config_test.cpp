// A scene file in the scenario, the station file and the fingerprint: contact
// faces where each proxy touches the surface, keys named as written, and two stations whose
// scenes differ tell which part differs.
#include <CppUTest/TestHarness.h>

#include <filesystem>
#include <string>

#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "firmware/station/plan.hpp"
#include "net/wire.hpp"
#include "tests/firmware/scene/fixtures.hpp"
#include "tests/support/error_of.hpp"

using namespace haptic;
using namespace haptic::firmware;
using haptic::test::error_of;

namespace {

// A box of side 6 cm (4^3 Kuhn cubes), centred on the origin, as a Gmsh 2.2 file in `dir`.
std::string write_box(const std::string& dir, const std::string& name, int n = 4) {
  test::BoxMesh b = test::kuhn_box(n, 6.0);  // in cm
  for (auto& p : b.nodes) p -= Eigen::Vector3d(3, 3, 3);
  const std::string path = dir + "/" + name;
  test::write_text(path, test::msh2(b));
  return path;
}

ScenarioSpec box_spec(const std::string& path) {
  ScenarioSpec s = make_scenario("paper-best");
  s.scene_file.path = path;
  s.scene_file.unit_m = 0.01;
  return s;
}

std::string station_text(const std::string& scene) {
  return "[station]\nid = 1\nout_dir = \"/tmp\"\n" + scene +
         "[device]\nkind = \"simulated\"\n[net]\ntransport = \"udp\"\nbind = \"127.0.0.1:0\"\n"
         "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n"
         "[[net.peers]]\nid = 2\naddress = \"127.0.0.1:9\"\n[[net.peers]]\nid = 3\naddress = \"127.0.0.1:9\"\n"
         "[[net.peers]]\nid = 4\naddress = \"127.0.0.1:9\"\n";
}

std::string plan_error(const std::string& text, const std::string& path = "") {
  StationFile f = parse_station_file(text);
  f.path = path;
  const PlanResult r = plan_station(f, RunOverrides{}, read_clocks());
  return r.status == PhaseStatus::kOk ? "" : r.error;
}

}  // namespace

TEST_GROUP(SceneScenario) {
  std::string dir;
  void setup() override { dir = test::scratch_dir("scenario"); }
  void teardown() override { std::filesystem::remove_all(dir); }
};

TEST(SceneScenario, each_users_contact_face_is_where_its_proxy_touches_the_surface) {
  const BuiltScenario b = build_scenario(box_spec(write_box(dir, "box.msh")));
  CHECK_EQUAL(125, b.scene.nodes);
  const auto& m = b.scene.mesh;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d start = b.vp_start[static_cast<std::size_t>(i)];
    // The proxy starts on the box's surface (one coordinate at +-3 cm) ...
    CHECK_EQUAL(1, (start.cwiseAbs().array() > 0.03 - 1e-12).count());
    // ... and its contact nodes are the corners of the boundary triangle under it.
    const auto& c = b.contact_nodes[static_cast<std::size_t>(i)];
    CHECK_EQUAL(3u, c.size());
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int v : c) sum += m.nodes[static_cast<std::size_t>(v)];
    int face = -1;
    for (int f = 0; f < static_cast<int>(m.surface.size()); ++f) {
      auto s = m.surface[static_cast<std::size_t>(f)];
      auto t = std::array<int, 3>{c[0], c[1], c[2]};
      std::sort(s.begin(), s.end());
      std::sort(t.begin(), t.end());
      if (s == t) face = f;
    }
    CHECK_TRUE(face >= 0);
    // The touch point lies in that triangle's plane, and the push goes into the object.
    DOUBLES_EQUAL(0.0, m.face_normal(face).dot(start - m.face_center(face)), 1e-12);
    CHECK_TRUE(b.push_direction[static_cast<std::size_t>(i)].dot(start - m.centroid()) < 0);
  }
  // Different users touch different faces.
  CHECK_TRUE(b.contact_nodes[0] != b.contact_nodes[1]);
}

TEST(SceneScenario, the_material_sets_mass_and_the_unit_scales_the_object) {
  ScenarioSpec s = box_spec(write_box(dir, "box.msh"));
  s.scene_file.density_kg_per_m3 = 1000;
  const BuiltScenario b = build_scenario(s);
  double mass = 0;
  for (int i = 0; i < b.scene.nodes; ++i) mass += b.scene.M.S.coeff(i, i);
  DOUBLES_EQUAL(1000 * 0.06 * 0.06 * 0.06, mass, 1e-12);
  DOUBLES_EQUAL(0.06, b.scene.mesh.bounding_radius() * 2 / std::sqrt(3.0), 1e-12);
}

TEST(SceneScenario, a_bad_scene_file_is_named_by_the_option) {
  const std::string bad = dir + "/flat.msh";
  test::BoxMesh b = test::kuhn_box(1, 1.0);
  std::swap(b.tets[0][1], b.tets[0][2]);
  test::write_text(bad, test::msh2(b));
  STRCMP_CONTAINS("--scene: ", error_of([&] { build_scenario(box_spec(bad)); }).c_str());
  STRCMP_CONTAINS("flat.msh:18: element 2: inverted tetrahedron", error_of([&] { build_scenario(box_spec(bad)); }).c_str());
  ScenarioSpec s = box_spec(bad);
  s.scene_file.unit_m = -1;
  STRCMP_CONTAINS("--scene-unit-m must be > 0", error_of([&] { build_scenario(s); }).c_str());
}

TEST(SceneScenario, the_station_file_takes_the_scene_and_names_its_keys) {
  const std::string box = write_box(dir, "box.msh");
  CHECK_EQUAL(std::string(""), plan_error(station_text("[scene]\nfile = \"box.msh\"\nunit_m = 0.01\n"), dir + "/station-1.toml"));
  STRCMP_CONTAINS("scene.colour", error_of([&] { parse_station_file(station_text("[scene]\nfile = \"box.msh\"\ncolour = 1\n")); }).c_str());
  STRCMP_CONTAINS("scene.unit_m", error_of([&] { parse_station_file(station_text("[scene]\nfile = \"box.msh\"\nunit_m = -2\n")); }).c_str());
  STRCMP_CONTAINS("scene.file", error_of([&] { parse_station_file(station_text("[scene]\nunit_m = 0.01\n")); }).c_str());
  STRCMP_CONTAINS("station.nodes must be absent when scene.file is set",
                  error_of([&] { parse_station_file("[station]\nnodes = 100\n" + station_text("[scene]\nfile = \"box.msh\"\n").substr(10)); }).c_str());
  const std::string e = plan_error(station_text("[scene]\nfile = \"missing.msh\"\n"), dir + "/station-1.toml");
  STRCMP_CONTAINS("scene.file: ", e.c_str());
  STRCMP_CONTAINS("missing.msh:0: cannot read the mesh file", e.c_str());
}

TEST(SceneScenario, fingerprints_tell_geometry_from_material) {
  const std::string box = write_box(dir, "box.msh"), fine = write_box(dir, "fine.msh", 5);
  const auto fp = [](const ScenarioSpec& s) { return scene_fingerprint(build_scenario(s), 2'000'000); };
  const net::Fingerprint a = fp(box_spec(box));
  CHECK_EQUAL(std::string(""), net::fingerprint_difference(a, fp(box_spec(box))));
  ScenarioSpec heavier = box_spec(box);
  heavier.scene_file.density_kg_per_m3 = 5000;
  STRCMP_EQUAL("scene material (hash) differs", net::fingerprint_difference(a, fp(heavier)).c_str());
  ScenarioSpec stiffer = box_spec(box);
  stiffer.scene_file.youngs_modulus_Pa = 1e6;
  // (P_ij = p[I/2 + K_int/(2 lambda_max)] is scale-free but its rounding may differ: gains may too.)
  STRCMP_CONTAINS("scene material (hash) differs", net::fingerprint_difference(a, fp(stiffer)).c_str());
  CHECK_TRUE(net::fingerprint_difference(a, fp(stiffer)).find("geometry") == std::string::npos);
  // The same box, one node moved by 1 mm, the same masses and springs: only the geometry differs.
  const BuiltScenario base = build_scenario(box_spec(box));
  BuiltScenario shifted = base;
  shifted.scene.x_d[0] += 0.001;
  STRCMP_EQUAL("scene geometry (hash) differs",
               net::fingerprint_difference(scene_fingerprint(base, 2'000'000), scene_fingerprint(shifted, 2'000'000)).c_str());
  STRCMP_CONTAINS("scene nodes: 125 here, 216 at the peer; scene data (hash) differs", net::fingerprint_difference(a, fp(box_spec(fine))).c_str());
  STRCMP_CONTAINS("period_ns: 2000000 here, 1000000 at the peer",
                  net::fingerprint_difference(a, scene_fingerprint(build_scenario(box_spec(box)), 1'000'000)).c_str());
}
