// Dispatch by extension, the file-size limit, and TetGen (the Debian `tetgen` program) for
// surface meshes. Start-up only (allocates, reads files, runs a subprocess). Not RT-safe.
#include "firmware/scene/mesh_io.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <thread>

#include "firmware/scene/mesh_check.hpp"

extern char** environ;

namespace haptic::scene {

namespace fs = std::filesystem;

std::string read_limited(const std::string& path, const MeshLimits& limits) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) throw MeshError(path + ":0: cannot read the mesh file (" + ec.message() + ")");
  if (static_cast<std::int64_t>(size) > limits.max_file_bytes)
    throw MeshError(path + ":0: " + std::to_string(size) + " bytes: above the limit of " + std::to_string(limits.max_file_bytes) + " bytes (a huge file?)");
  std::ifstream in(path, std::ios::binary);
  std::string text(size, '\0');
  if (!in.read(text.data(), static_cast<std::streamsize>(size))) throw MeshError(path + ":0: cannot read the mesh file");
  return text;
}

namespace {

std::string extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return e;
}

void write_smesh(const RawSurface& s, const std::string& file) {
  std::ofstream out(file);
  out << std::setprecision(17);
  out << s.nodes.size() << " 3 0 0\n";
  for (std::size_t i = 0; i < s.nodes.size(); ++i) out << i << ' ' << s.nodes[i][0] << ' ' << s.nodes[i][1] << ' ' << s.nodes[i][2] << '\n';
  out << s.triangles.size() << " 0\n";
  for (const auto& t : s.triangles) out << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  out << "0\n0\n";
  if (!out) throw MeshError(s.file + ":0: cannot write TetGen's input " + file);
}

// Runs argv with stdout/stderr to `log`, killed after timeout_s. Returns the exit status (-1: killed).
int run_bounded(const std::vector<std::string>& args, const std::string& log, double timeout_s, const std::string& surface) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc == ENOENT) throw MeshError(surface + ":0: surface meshes need TetGen, which is not installed (Debian package tetgen)");
  if (rc != 0) throw MeshError(surface + ":0: cannot start TetGen: " + std::strerror(rc));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string last_lines(const std::string& file, int n) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) lines.push_back(l);
  std::string out;
  for (std::size_t i = lines.size() > static_cast<std::size_t>(n) ? lines.size() - n : 0; i < lines.size(); ++i) out += (out.empty() ? "" : " | ") + lines[i];
  return out;
}

}  // namespace

RawTetMesh tetrahedralize(const RawSurface& surface, const MeshReadOptions& options) {
  std::string tmpl = (fs::temp_directory_path() / "haptic-tetgen-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw MeshError(surface.file + ":0: cannot create a temporary folder for TetGen");
  const fs::path dir(tmpl);
  struct Cleanup {
    fs::path d;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(d, ec);
    }
  } cleanup{dir};
  const std::string input = (dir / "surface.smesh").string();
  write_smesh(surface, input);
  std::ostringstream sw;
  sw << "-pq1.414";
  if (options.tetgen_max_volume > 0) sw << 'a' << std::setprecision(17) << options.tetgen_max_volume;
  sw << "Q";
  const std::string log = (dir / "tetgen.log").string();
  const int status = run_bounded({"tetgen", sw.str(), input}, log, options.tetgen_timeout_s, surface.file);
  if (status == -1) throw MeshError(surface.file + ":0: TetGen did not finish within " + std::to_string(options.tetgen_timeout_s) + " s");
  const fs::path node = dir / "surface.1.node", ele = dir / "surface.1.ele";
  if (status != 0 || !fs::exists(node) || !fs::exists(ele))
    throw MeshError(surface.file + ":0: TetGen could not tetrahedralize the surface (self-intersecting?): " + last_lines(log, 3));
  RawTetMesh m = read_tetgen(node.string(), options.limits);
  m.node_file = m.element_file = surface.file + " (tetrahedralized by TetGen " + sw.str() + ")";
  return m;
}

rt::TetMesh read_scene_mesh(const std::string& path, const MeshReadOptions& options) {
  const std::string ext = extension(path);
  RawTetMesh raw;
  if (ext == ".msh") {
    raw = read_gmsh(path, options.limits);
  } else if (ext == ".node" || ext == ".ele") {
    raw = read_tetgen(path, options.limits);
  } else if (ext == ".vtk") {
    raw = read_vtk(path, options.limits);
  } else if (ext == ".obj" || ext == ".stl" || ext == ".off") {
    const RawSurface s = ext == ".obj" ? read_obj(path, options.limits) : ext == ".stl" ? read_stl(path, options.limits) : read_off(path, options.limits);
    check_surface(s);
    raw = tetrahedralize(s, options);
  } else {
    throw MeshError(path + ":0: unknown mesh format '" + ext + "' (.msh, .node/.ele, .vtk, .obj, .stl, .off)");
  }
  rt::TetMesh m = check_tet_mesh(raw, options.unit_m, options.limits);
  m.description = "scene file " + fs::path(path).filename().string() + " (" + std::to_string(m.node_count()) + " nodes, " +
                  std::to_string(m.tets.size()) + " tetrahedra)";
  return m;
}

}  // namespace haptic::scene
