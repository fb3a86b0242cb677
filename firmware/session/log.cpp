#include "firmware/session/log.hpp"

#include <elf.h>
#include <link.h>
#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <stdexcept>

namespace haptic::firmware {

namespace {

using h5::Type;

// A whole dataset (h5::write) with its units and description.
void write_ds(hid_t loc, const std::string& name, Type type, const void* data, std::uint64_t rows, std::uint64_t cols, const std::string& units,
              const std::string& description) {
  h5::write(loc, name, type, data, rows, cols);
  set_units(h5::open_dataset(loc, name).get(), units, description);
}

// A SpatialMatrix as its CSR arrays (exact: same structure, same order of summation); `units` and
// `what` describe its values.
void write_matrix(hid_t loc, const std::string& name, const rt::SpatialMatrix& m, const std::string& units, const std::string& what) {
  h5::Id g = h5::create_group(loc, name);
  h5::attr(g.get(), "width", static_cast<std::int64_t>(m.width));
  h5::attr(g.get(), "rows", static_cast<std::int64_t>(m.S.rows()));
  h5::attr(g.get(), "cols", static_cast<std::int64_t>(m.S.cols()));
  const auto nnz = static_cast<std::uint64_t>(m.S.nonZeros());
  std::vector<std::int64_t> outer(m.S.outerIndexPtr(), m.S.outerIndexPtr() + m.S.outerSize() + 1), inner(m.S.innerIndexPtr(), m.S.innerIndexPtr() + nnz);
  write_ds(g.get(), "outer", Type::kI64, outer.data(), outer.size(), 0, "1", what + ": CSR row starts");
  write_ds(g.get(), "inner", Type::kI64, inner.data(), inner.size(), 0, "1", what + ": CSR column indices");
  write_ds(g.get(), "values", Type::kF64, m.S.valuePtr(), nnz, 0, units, what + ": CSR values");
}

rt::SpatialMatrix read_matrix(hid_t loc, const std::string& name) {
  h5::Id g = h5::open_group(loc, name);
  const auto rows = h5::attr_i64(g.get(), "rows"), cols = h5::attr_i64(g.get(), "cols");
  const auto outer64 = h5::read_i64(g.get(), "outer"), inner64 = h5::read_i64(g.get(), "inner");
  const auto values = h5::read_f64(g.get(), "values");
  if (static_cast<std::int64_t>(outer64.size()) != rows + 1 || inner64.size() != values.size()) throw std::runtime_error("log: matrix " + name + " is inconsistent");
  std::vector<int> outer(outer64.begin(), outer64.end()), inner(inner64.begin(), inner64.end());
  rt::SpatialMatrix m;
  m.width = static_cast<int>(h5::attr_i64(g.get(), "width"));
  m.S = Eigen::Map<const rt::SparseRowMajor>(rows, cols, static_cast<Eigen::Index>(values.size()), outer.data(), inner.data(), values.data());
  return m;
}

template <std::size_t W, class T>
void write_arrays(hid_t loc, const std::string& name, const std::vector<std::array<T, W>>& a, const std::string& description) {
  std::vector<std::int64_t> flat;
  for (const auto& r : a)
    for (auto v : r) flat.push_back(v);
  write_ds(loc, name, Type::kI64, flat.data(), a.size(), W, "1", description);
}

template <std::size_t W>
std::vector<std::array<int, W>> read_arrays(hid_t loc, const std::string& name) {
  const auto flat = h5::read_i64(loc, name);
  std::vector<std::array<int, W>> a(flat.size() / W);
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t c = 0; c < W; ++c) a[i][c] = static_cast<int>(flat[i * W + c]);
  return a;
}

void write_scene(hid_t loc, const rt::Scene& s) {
  h5::Id g = h5::create_group(loc, "scene");
  h5::attr(g.get(), "nodes", static_cast<std::int64_t>(s.nodes));
  h5::attr(g.get(), "dofs", static_cast<std::int64_t>(s.dofs));
  h5::attr(g.get(), "node_mass_kg", s.params.node_mass_kg);
  h5::attr(g.get(), "damping_Ns_per_m", s.params.damping_Ns_per_m);
  h5::attr(g.get(), "edge_stiffness_N_per_m", s.params.edge_stiffness_N_per_m);
  h5::attr(g.get(), "ground_stiffness_N_per_m", s.params.ground_stiffness_N_per_m);
  h5::attr(g.get(), "lambda_max_K_int", s.lambda_max_K_int);
  h5::attr(g.get(), "description", s.mesh.description);
  std::vector<double> nodes;
  for (const auto& p : s.mesh.nodes) nodes.insert(nodes.end(), {p[0], p[1], p[2]});
  write_ds(g.get(), "mesh_nodes", Type::kF64, nodes.data(), s.mesh.nodes.size(), 3, "m", "rest positions of the mesh nodes");
  write_arrays(g.get(), "tets", s.mesh.tets, "tetrahedra (node indices)");
  write_arrays(g.get(), "edges", s.mesh.edges, "edges (node indices)");
  write_arrays(g.get(), "surface", s.mesh.surface, "surface triangles (node indices)");
  write_ds(g.get(), "x_d", Type::kF64, s.x_d.data(), static_cast<std::uint64_t>(s.x_d.size()), 0, "m", "rest (desired) node positions x_d");
  write_matrix(g.get(), "M", s.M, "kg", "mass matrix M");
  write_matrix(g.get(), "B", s.B, "N s/m", "damping matrix B");
  write_matrix(g.get(), "K_int", s.K_int, "N/m", "internal stiffness K_int");
  write_matrix(g.get(), "K", s.K, "N/m", "stiffness K");
}

void read_scene(hid_t loc, rt::Scene& s) {
  h5::Id g = h5::open_group(loc, "scene");
  s.nodes = static_cast<int>(h5::attr_i64(g.get(), "nodes"));
  s.dofs = static_cast<int>(h5::attr_i64(g.get(), "dofs"));
  s.params.node_mass_kg = h5::attr_f64(g.get(), "node_mass_kg");
  s.params.damping_Ns_per_m = h5::attr_f64(g.get(), "damping_Ns_per_m");
  s.params.edge_stiffness_N_per_m = h5::attr_f64(g.get(), "edge_stiffness_N_per_m");
  s.params.ground_stiffness_N_per_m = h5::attr_f64(g.get(), "ground_stiffness_N_per_m");
  s.lambda_max_K_int = h5::attr_f64(g.get(), "lambda_max_K_int");
  s.mesh.description = h5::attr_str(g.get(), "description");
  const auto nodes = h5::read_f64(g.get(), "mesh_nodes");
  for (std::size_t i = 0; i + 2 < nodes.size(); i += 3) s.mesh.nodes.emplace_back(nodes[i], nodes[i + 1], nodes[i + 2]);
  s.mesh.tets = read_arrays<4>(g.get(), "tets");
  s.mesh.edges = read_arrays<2>(g.get(), "edges");
  s.mesh.surface = read_arrays<3>(g.get(), "surface");
  const auto xd = h5::read_f64(g.get(), "x_d");
  s.x_d = Eigen::Map<const Eigen::VectorXd>(xd.data(), static_cast<Eigen::Index>(xd.size()));
  s.M = read_matrix(g.get(), "M");
  s.B = read_matrix(g.get(), "B");
  s.K_int = read_matrix(g.get(), "K_int");
  s.K = read_matrix(g.get(), "K");
  if (s.dofs != 3 * s.nodes || s.x_d.size() != s.dofs) throw std::runtime_error("log: /core/scene sizes disagree");
}

// Distinct gain objects of the neighbours, in first-use order; gain_of[n] indexes them.
std::vector<const rt::EdgeGains*> distinct_gains(const rt::StationConfig& c, std::vector<std::int64_t>& gain_of) {
  std::vector<const rt::EdgeGains*> g;
  for (const auto& n : c.neighbors) {
    auto it = std::find(g.begin(), g.end(), n.gains);
    if (it == g.end()) it = g.insert(g.end(), n.gains);
    gain_of.push_back(it - g.begin());
  }
  return g;
}

void write_core_attrs(hid_t g, const rt::StationConfig& c) {
  h5::attr(g, "station_index", static_cast<std::int64_t>(c.station_id));
  h5::attr(g, "users", static_cast<std::int64_t>(c.users));
  h5::attr(g, "period_s", c.period_s);
  h5::attr(g, "period_min_s", c.period_min_s);  // the step levels (version 2; the steps T_k are /ticks/step_s)
  h5::attr(g, "period_max_s", c.period_max_s);
  h5::attr(g, "step_resolution_s", c.step_resolution_s);
  h5::attr(g, "damping_Ns_per_m", c.damping_Ns_per_m);
  h5::attr(g, "device_damping_Ns_per_m", c.device_damping_Ns_per_m);
  h5::attr(g, "max_device_force_N", c.max_device_force_N);
  h5::attr(g, "divergence_speed_m_per_s", c.divergence_speed_m_per_s);
  h5::attr(g, "vp_mass_kg", c.vp.mass_kg);
  h5::attr(g, "contact_damping_Ns_per_m", c.vp.contact_damping_Ns_per_m);
  h5::attr(g, "contact_stiffness_N_per_m", c.vp.contact_stiffness_N_per_m);
  h5::attr(g, "b_v_Ns_per_m", c.vp.coupling.b_v_Ns_per_m);
  h5::attr(g, "B_vc_Ns_per_m", c.vp.coupling.B_vc_Ns_per_m);
  h5::attr(g, "K_vc_N_per_m", c.vp.coupling.K_vc_N_per_m);
  h5::attr(g, "rx_rule", static_cast<std::int64_t>(c.rx_rule));
  h5::attr(g, "consensus_passivity", static_cast<std::int64_t>(c.consensus_passivity));
  h5::attr(g, "pspm_reservoir0_J", c.pspm_reservoir0_J);
  h5::attr(g, "predict_held_state", static_cast<std::int64_t>(c.predict_held_state));
  h5::attr(g, "predict_held_limit_m", c.predict_held_limit_m);
  h5::attr(g, "return_ramp_s", c.return_ramp_s);
  h5::attr(g, "return_ramp_after_s", c.return_ramp_after_s);
  h5::attr(g, "drop_fade_s", c.drop_fade_s);
  h5::attr(g, "solver_kind", static_cast<std::int64_t>(c.solver.kind));
  h5::attr(g, "solver_iterative_from_rows", static_cast<std::int64_t>(c.solver.iterative_from_rows));
  h5::attr(g, "solver_relative_tolerance", c.solver.relative_tolerance);
  h5::attr(g, "solver_max_iterations_cap", static_cast<std::int64_t>(c.solver.max_iterations_cap));
}

void read_core_attrs(hid_t g, rt::StationConfig& c) {
  c.station_id = static_cast<int>(h5::attr_i64(g, "station_index"));
  c.users = static_cast<int>(h5::attr_i64(g, "users"));
  c.period_s = h5::attr_f64(g, "period_s");
  if (h5::has_attr(g, "period_min_s")) {  // version 1: fixed steps
    c.period_min_s = h5::attr_f64(g, "period_min_s");
    c.period_max_s = h5::attr_f64(g, "period_max_s");
    c.step_resolution_s = h5::attr_f64(g, "step_resolution_s");
  }
  c.damping_Ns_per_m = h5::attr_f64(g, "damping_Ns_per_m");
  c.device_damping_Ns_per_m = h5::attr_f64(g, "device_damping_Ns_per_m");
  c.max_device_force_N = h5::attr_f64(g, "max_device_force_N");
  c.divergence_speed_m_per_s = h5::attr_f64(g, "divergence_speed_m_per_s");
  c.vp.mass_kg = h5::attr_f64(g, "vp_mass_kg");
  c.vp.contact_damping_Ns_per_m = h5::attr_f64(g, "contact_damping_Ns_per_m");
  c.vp.contact_stiffness_N_per_m = h5::attr_f64(g, "contact_stiffness_N_per_m");
  c.vp.coupling.b_v_Ns_per_m = h5::attr_f64(g, "b_v_Ns_per_m");
  c.vp.coupling.B_vc_Ns_per_m = h5::attr_f64(g, "B_vc_Ns_per_m");
  c.vp.coupling.K_vc_N_per_m = h5::attr_f64(g, "K_vc_N_per_m");
  c.rx_rule = static_cast<rt::RxRule>(h5::attr_i64(g, "rx_rule"));
  if (h5::has_attr(g, "consensus_passivity")) {  // logs from before set-position modulation: eq. (18)
    c.consensus_passivity = static_cast<rt::ConsensusPassivity>(h5::attr_i64(g, "consensus_passivity"));
    c.pspm_reservoir0_J = h5::attr_f64(g, "pspm_reservoir0_J");
  }
  if (h5::has_attr(g, "predict_held_state")) c.predict_held_state = h5::attr_i64(g, "predict_held_state") != 0;  // older logs: off
  if (h5::has_attr(g, "predict_held_limit_m")) c.predict_held_limit_m = h5::attr_f64(g, "predict_held_limit_m");
  if (h5::has_attr(g, "return_ramp_s")) {  // older logs: no ramp
    c.return_ramp_s = h5::attr_f64(g, "return_ramp_s");
    c.return_ramp_after_s = h5::attr_f64(g, "return_ramp_after_s");
  }
  if (h5::has_attr(g, "drop_fade_s")) c.drop_fade_s = h5::attr_f64(g, "drop_fade_s");  // older logs: the immediate drop
  c.solver.kind = static_cast<rt::StepSolverKind>(h5::attr_i64(g, "solver_kind"));
  c.solver.iterative_from_rows = static_cast<int>(h5::attr_i64(g, "solver_iterative_from_rows"));
  c.solver.relative_tolerance = h5::attr_f64(g, "solver_relative_tolerance");
  c.solver.max_iterations_cap = static_cast<int>(h5::attr_i64(g, "solver_max_iterations_cap"));
}

}  // namespace

std::uint64_t state_hash(const rt::StationCore& core, const rt::StationCore::TickOutput& out) {
  const auto n = static_cast<std::size_t>(core.x().size()) * sizeof(double);
  std::uint64_t h = XXH3_64bits(core.x().data(), n);
  h = XXH3_64bits_withSeed(core.v().data(), n, h);
  const auto& e = core.energy();
  const auto& y = core.vp_position_m();
  const double tail[12] = {y[0], y[1], y[2], out.device_force_N[0], out.device_force_N[1], out.device_force_N[2],
                           e.port_J, e.controller_J, e.vo_J, e.device_port_J, e.solver_residual_J, static_cast<double>(out.flags)};
  return XXH3_64bits_withSeed(tail, sizeof tail, h);
}

TickRecord make_tick_record(const rt::StationCore& core, std::int64_t kr, const rt::Vec3& q, const rt::StationCore::TickOutput& out,
                            double step_s) {
  TickRecord r;
  r.k = kr;
  r.step_s = step_s;
  const auto& y = core.vp_position_m();
  for (int a = 0; a < 3; ++a) {
    r.q[a] = q[a];
    r.force[a] = out.device_force_N[a];
    r.vp[a] = y[a];
  }
  const auto& e = core.energy();
  r.port_J = e.port_J;
  r.controller_J = e.controller_J;
  r.vo_J = e.vo_J;
  r.hash = state_hash(core, out);
  r.flags = out.flags;
  r.contact = core.in_contact() ? 1 : 0;
  return r;
}

namespace {
// dl_iterate_phdr callback: the NT_GNU_BUILD_ID note of the main program (the first object).
int find_build_id(dl_phdr_info* info, std::size_t, void* data) {
  auto* out = static_cast<std::string*>(data);
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr)& ph = info->dlpi_phdr[i];
    if (ph.p_type != PT_NOTE) continue;
    const auto* p = reinterpret_cast<const unsigned char*>(info->dlpi_addr + ph.p_vaddr);
    const unsigned char* end = p + ph.p_memsz;
    while (p + sizeof(ElfW(Nhdr)) <= end) {
      const auto* n = reinterpret_cast<const ElfW(Nhdr)*>(p);
      const unsigned char* name = p + sizeof(ElfW(Nhdr));
      const unsigned char* desc = name + ((n->n_namesz + 3) & ~3u);
      if (n->n_type == NT_GNU_BUILD_ID && n->n_namesz == 4 && std::memcmp(name, "GNU", 4) == 0 && desc + n->n_descsz <= end) {
        static const char hex[] = "0123456789abcdef";
        for (unsigned k = 0; k < n->n_descsz; ++k) out->push_back(hex[desc[k] >> 4]), out->push_back(hex[desc[k] & 15]);
        return 1;
      }
      p = desc + ((n->n_descsz + 3) & ~3u);
    }
  }
  return 1;  // only the main program
}
}  // namespace

std::string program_build_id() {
  std::string id;
  dl_iterate_phdr(find_build_id, &id);
  return id;
}

void write_session_header(hid_t file, const SessionInfo& info, const rt::StationConfig& c) {
  h5::attr(file, "format", std::string("haptic-session"));
  h5::attr(file, "version", kSessionLogVersion);
  h5::attr(file, "source", info.source);
  if (!info.scenario.empty()) h5::attr(file, "scenario", info.scenario);
  h5::attr(file, kFieldUnitsAttr, static_cast<std::int64_t>(1));
  h5::attr(file, "station_id", static_cast<std::int64_t>(info.station_id));
  h5::attr(file, "users", static_cast<std::int64_t>(c.users));
  h5::attr(file, "nodes", static_cast<std::int64_t>(c.scene->nodes));
  h5::attr(file, "dofs", static_cast<std::int64_t>(c.scene->dofs));
  h5::attr(file, "period_s", c.period_s);
  h5::attr(file, "config_text", info.config_text);
  h5::attr(file, "fingerprint", info.fingerprint);
  h5::attr(file, "packet_values", std::string(info.packets_float32 ? "float32" : "float64"));
  h5::attr(file, "build_id", program_build_id());
  if (info.damping_min_Ns_per_m >= 0) {
    h5::attr(file, "damping_min_Ns_per_m", info.damping_min_Ns_per_m);
    h5::attr(file, "passivity_condition_met", static_cast<std::int64_t>(info.passivity_condition_met ? 1 : 0));
  }
  h5::Id g = h5::create_group(file, "core");
  write_core_attrs(g.get(), c);
  std::vector<std::int64_t> contact(c.contact_nodes.begin(), c.contact_nodes.end()), peer, bound, gain_of;
  std::vector<double> share;
  write_ds(g.get(), "contact_nodes", Type::kI64, contact.data(), contact.size(), 0, "1", "the contact mesh C_i: the scene nodes the virtual proxy can touch");
  write_ds(g.get(), "vp_initial_position_m", Type::kF64, c.vp_initial_position_m.data(), 3, 0, "m", "virtual proxy position before the first tick");
  for (const auto& n : c.neighbors) {
    peer.push_back(n.peer_id);
    bound.push_back(n.index_delay_bound_ticks);
    share.push_back(n.damping_share);
  }
  const auto gains = distinct_gains(c, gain_of);
  write_ds(g.get(), "neighbour_peer", Type::kI64, peer.data(), peer.size(), 0, "1", "each neighbour's station index (0-based)");
  write_ds(g.get(), "neighbour_index_delay_bound_ticks", Type::kI64, bound.data(), bound.size(), 0, "1",
           "each neighbour's index-delay bound, in ticks");
  write_ds(g.get(), "neighbour_gain", Type::kI64, gain_of.data(), gain_of.size(), 0, "1", "each neighbour's gains: a group of /core/gains");
  write_ds(g.get(), "neighbour_damping_share", Type::kF64, share.data(), share.size(), 0, "1", "each neighbour's share of the damping B_i");
  write_scene(g.get(), *c.scene);
  h5::Id gg = h5::create_group(g.get(), "gains");
  for (std::size_t e = 0; e < gains.size(); ++e) {
    h5::Id ge = h5::create_group(gg.get(), std::to_string(e));
    write_matrix(ge.get(), "P", gains[e]->P, "N/m", "consensus stiffness gain P_ij");
    write_matrix(ge.get(), "D", gains[e]->D, "N s/m", "consensus damping gain D_ij");
    h5::attr(ge.get(), "lambda_max_P", gains[e]->lambda_max_P);
    h5::attr(ge.get(), "lambda_max_D", gains[e]->lambda_max_D);
    h5::attr(ge.get(), "description", gains[e]->description);
  }
}

std::string flag_bits_text() {
  std::string t;
  for (const auto& f : rt::kTickFlagNames) {
    t += std::to_string(std::countr_zero(f.bit)) + " " + f.name + " " + f.meaning + "\n";
  }
  return t;
}

void set_units(hid_t dataset, const std::string& units, const std::string& description) {
  h5::attr(dataset, kUnitsAttr, units);
  h5::attr(dataset, kDescriptionAttr, description);
}

h5::Appendable create_field(hid_t group, const LogField& f, std::uint64_t dofs, bool float32, std::uint64_t chunk_rows, int deflate_level,
                            std::uint64_t ring_rows) {
  const bool values = f.cols == FieldCols::kDofs;
  const std::uint64_t cols = f.cols == FieldCols::kScalar ? 0 : f.cols == FieldCols::kXyz ? 3 : dofs;
  h5::Appendable a(group, f.name, values && float32 ? Type::kF32 : f.type, cols, chunk_rows, deflate_level, ring_rows);
  set_units(a.id(), f.units, f.description);
  if (&f == &kTickFields[kTickFlags]) h5::attr(a.id(), kFlagBitsAttr, flag_bits_text());
  return a;
}

void write_initial_state(hid_t file, const double* x, const double* v, std::uint64_t dofs) {
  h5::Id g = h5::create_group(file, "initial_state");
  write_ds(g.get(), "x", Type::kF64, x, dofs, 0, "m", "VO node positions before the first tick");
  write_ds(g.get(), "v", Type::kF64, v, dofs, 0, "m/s", "VO node velocities before the first tick");
}

std::vector<double> tick_end_times_s(const std::vector<std::int64_t>& k, const std::vector<double>& step_s, double period_s) {
  std::vector<double> t(k.size());
  double now = k.empty() ? 0.0 : static_cast<double>(k.front()) * period_s;
  for (std::size_t i = 0; i < k.size(); ++i) {
    if (i > 0 && k[i] > k[i - 1] + 1) now += static_cast<double>(k[i] - k[i - 1] - 1) * period_s;
    const double step = i < step_s.size() && step_s[i] > 0 ? step_s[i] : period_s;
    now += step;
    t[i] = now;
  }
  return t;
}

std::unique_ptr<CoreSetup> read_core_setup(hid_t file) {
  if (!h5::has_attr(file, "format") || h5::attr_str(file, "format") != "haptic-session")
    throw std::runtime_error("not a haptic session log (no format = \"haptic-session\" attribute)");
  const std::int64_t version = h5::attr_i64(file, "version");
  if (version < 1 || version > kSessionLogVersion)
    throw std::runtime_error("session log version " + std::to_string(version) + ", this program reads 1 to " + std::to_string(kSessionLogVersion));
  auto s = std::make_unique<CoreSetup>();
  h5::Id g = h5::open_group(file, "core");
  read_core_attrs(g.get(), s->config);
  read_scene(g.get(), s->scene);
  s->config.scene = &s->scene;
  for (auto p : h5::read_i64(g.get(), "contact_nodes")) s->config.contact_nodes.push_back(static_cast<int>(p));
  const auto vp0 = h5::read_f64(g.get(), "vp_initial_position_m");
  s->config.vp_initial_position_m = rt::Vec3(vp0.at(0), vp0.at(1), vp0.at(2));
  const auto peer = h5::read_i64(g.get(), "neighbour_peer"), bound = h5::read_i64(g.get(), "neighbour_index_delay_bound_ticks"),
             gain_of = h5::read_i64(g.get(), "neighbour_gain");
  const auto share = h5::read_f64(g.get(), "neighbour_damping_share");
  h5::Id gg = h5::open_group(g.get(), "gains");
  const std::int64_t ngains = gain_of.empty() ? 0 : *std::max_element(gain_of.begin(), gain_of.end()) + 1;
  s->gains.resize(static_cast<std::size_t>(ngains));
  for (std::int64_t e = 0; e < ngains; ++e) {
    h5::Id ge = h5::open_group(gg.get(), std::to_string(e));
    auto& eg = s->gains[static_cast<std::size_t>(e)];
    eg.P = read_matrix(ge.get(), "P");
    eg.D = read_matrix(ge.get(), "D");
    eg.lambda_max_P = h5::attr_f64(ge.get(), "lambda_max_P");
    eg.lambda_max_D = h5::attr_f64(ge.get(), "lambda_max_D");
    eg.description = h5::attr_str(ge.get(), "description");
  }
  for (std::size_t n = 0; n < peer.size(); ++n) {
    rt::NeighborConfig nc;
    nc.peer_id = static_cast<int>(peer[n]);
    nc.index_delay_bound_ticks = bound.at(n);
    nc.damping_share = share.at(n);
    nc.gains = &s->gains.at(static_cast<std::size_t>(gain_of.at(n)));
    s->config.neighbors.push_back(nc);
  }
  return s;
}

}  // namespace haptic::firmware
