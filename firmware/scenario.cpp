#include "firmware/scenario.hpp"

#include <algorithm>

#include "firmware/model/step_bounds.hpp"
#include "firmware/scene/mesh_io.hpp"
#include "net/impairment.hpp"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace haptic::firmware {

namespace {
[[noreturn]] void bad(const std::string& msg) { throw std::invalid_argument(msg); }
std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  const auto b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}
double to_double(const std::string& tok, const std::string& what) {
  try {
    std::size_t used = 0;
    const double v = std::stod(trim(tok), &used);
    if (used != trim(tok).size()) throw std::invalid_argument("trailing");
    if (!std::isfinite(v)) throw std::invalid_argument("not finite");
    return v;
  } catch (const std::exception&) {
    bad(what + ": '" + tok + "' is not a number");
  }
}

// Unit push directions (outward, from the object's centre towards the user) for N users whose
// sum is zero by construction: the 4-user tetrahedral pattern of the paper's scene (the face
// towards (1,1,1) and its images under the three half-turns about the axes); for other N,
// antipodal pairs on a golden-angle spiral of the upper hemisphere, plus a planar triangle
// (120 degrees apart, about z) when N is odd. Start-up only.
std::vector<Eigen::Vector3d> spread_directions(int N, const Eigen::Vector3d& c0) {
  std::vector<Eigen::Vector3d> d;
  if (N == 4) {
    const std::array<Eigen::Vector3d, 4> flips = {Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(1, -1, -1), Eigen::Vector3d(-1, 1, -1),
                                                  Eigen::Vector3d(-1, -1, 1)};
    for (const auto& f : flips) d.push_back(f.cwiseProduct(c0).normalized());
    return d;
  }
  const int pairs = (N % 2 == 0) ? N / 2 : (N - 3) / 2;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < pairs; ++k) {
    const double z = 1.0 - (k + 0.5) / pairs;  // (0, 1): upper hemisphere, never the equator
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::Vector3d u(r * std::cos(golden * k + 0.3), r * std::sin(golden * k + 0.3), z);
    d.push_back(u);
    d.push_back(-u);
  }
  if (N % 2 == 1)
    for (int k = 0; k < 3; ++k) {
      const double a = 0.2 + 2.0 * std::numbers::pi * k / 3.0;
      d.push_back(Eigen::Vector3d(std::cos(a), std::sin(a), 0.0));
    }
  return d;
}
void assign_pushes(BuiltScenario& b);

// T_i^min, T_i^max and the clock rate per user from the spec's clock model or its explicit bounds
// (ScenarioSpec). Start-up only.
void set_step_bounds(BuiltScenario& b) {
  const ScenarioSpec& s = b.spec;
  const int N = s.users;
  const double T = s.period_s;
  for (int i = 0; i < N; ++i) {
    const double c = N > 1 ? s.clock_drift_ppm * (2.0 * i / (N - 1) - 1.0) : 0.0;
    const double rate = 1.0 + c * 1e-6;
    b.clock_rate.push_back(rate);
    // wake-to-wake: one grid interval T rate (1 +- F) plus the difference of two wake delays in [0, J]
    const model::StepBounds m = model::step_bounds(T, rate, s.step_jitter, s.timer_jitter_s);
    b.t_min_s.push_back(s.period_min_s > 0 ? s.period_min_s : m.t_min_s);
    b.t_max_s.push_back(s.period_max_s > 0 ? s.period_max_s : m.t_max_s);
  }
}

}  // namespace

std::vector<std::string> scenario_names() { return {"paper-best", "paper-worst", "paper-unstable", "eq18-binds"}; }

ScenarioSpec make_scenario(const std::string& name, const std::string& key) {
  ScenarioSpec s;
  s.name = name;
  s.delay_ms = model::paper_delay_matrix_ms();
  if (name == "paper-best") {
    // Fig. 7 best: the star on user 1 (our optimizer's ranking agrees; see tools/topology).
    s.topology = {{0, 1}, {0, 2}, {0, 3}};
    s.duration_s = 20.0;
    s.script.release_s = 12.0;
  } else if (name == "paper-worst") {
    // Fig. 7 worst: the path 1-2-4-3 through the two slowest links.
    s.topology = {{0, 1}, {1, 3}, {2, 3}};
    s.duration_s = 80.0;
    s.script.release_s = 64.0;
  } else if (name == "paper-unstable") {
    // Fig. 10: best topology with B_i = (14, 5, 4, 5) N s/m, below eq. (18); users hold light
    // contact and user 1 gives a small perturbation at 2.5 s.
    s.topology = {{0, 1}, {0, 2}, {0, 3}};
    s.damping_Ns_per_m = std::vector<double>{14.0, 5.0, 4.0, 5.0};
    s.duration_s = 10.0;
    s.script.kind = UserScriptSpec::Kind::kPerturb;
  } else if (name == "eq18-binds") {
    // The closed loop in which eq. (18) binds (rt/README.md "Where eq. (18) binds"): two users on one
    // link, a heavy object (1 kg nodes: 33 kg) so that the consensus loop is slow against the delay,
    // constant 9.9 ms one-way delays (Nbar = 5 ticks each way), no loss, D_ij = 0 and no energy gate;
    // user 1 perturbs at 2.5 s. Measured: passive and converging at eq. (18), diverging at 0.8x of it.
    s.users = 2;
    s.topology = {{0, 1}};
    s.delay_ms = Eigen::MatrixXd::Constant(2, 2, 9.9);
    s.delay_ms.diagonal().setZero();
    s.jitter_fraction = 0;
    s.loss_probability = 0;
    s.duplicate_probability = 0;
    s.loss_allowance_ticks = 0;
    s.d_gain_Ns_per_m = 0;
    s.edge_energy_bound_J = 0;
    s.scene.node_mass_kg = 1.0;
    s.duration_s = 30.0;
    s.script.kind = UserScriptSpec::Kind::kPerturb;
  } else {
    std::string list;
    for (const auto& n : scenario_names()) list += (list.empty() ? "" : ", ") + n;
    bad((key.empty() ? std::string() : key + " = \"" + name + "\": ") + "unknown scenario '" + name + "' (valid: " + list + ")");
  }
  return s;
}

std::pair<double, double> ScenarioSpec::delay_trace_range_ms() const {
  const auto [lo, hi] = std::minmax_element(delay_trace->begin(), delay_trace->end());
  return {*lo * 1e3, *hi * 1e3};
}

void ScenarioSpec::validate() const {
  if (users < 1 || users > 64) bad("users must be in [1, 64] (1: solo, no links)");
  if (!(period_s >= 1e-4 && period_s <= 0.05)) bad("period_s must be in [0.0001, 0.05]");
  if (!(duration_s > 0 && duration_s <= 3600)) bad("--duration must be in (0, 3600] s");
  if (script.kind == UserScriptSpec::Kind::kPushHoldRelease && !(script.push_start_s < script.push_end_s && script.push_end_s < script.release_s))
    bad("--push-end (" + std::to_string(script.push_end_s) + " s) must lie after the push start (" + std::to_string(script.push_start_s) +
        " s) and before --release (" + std::to_string(script.release_s) + " s)");
  if (delay_ms.rows() != users || delay_ms.cols() != users) bad("--delay-matrix must be users x users");
  for (int i = 0; i < users; ++i)
    for (int j = 0; j < users; ++j)
      if (!(delay_ms(i, j) >= 0 && delay_ms(i, j) <= 10000)) bad("--delay-matrix entries must be in [0, 10000] ms");
  if (users > 1) model::validate_graph(topology, users, "--topology");
  else if (!topology.empty()) bad("--topology: a single user has no links");
  if (damping_Ns_per_m) {
    if (static_cast<int>(damping_Ns_per_m->size()) != users)
      bad("--damping needs one value per user: " + std::to_string(damping_Ns_per_m->size()) + " B_i for " + std::to_string(users) +
          " users (given by --damping, or fixed by the scenario " + name + ": then give --damping with " + std::to_string(users) + " values)");
    for (double b : *damping_Ns_per_m)
      if (!(b >= 0)) bad("--damping values must be >= 0 N s/m");
  }
  if (!(jitter_fraction >= 0 && jitter_fraction <= 1)) bad("--jitter must be in [0, 1] (a fraction of the mean delay)");
  if (!(delay_correlation >= 0 && delay_correlation < 1)) bad("--delay-correlation must be in [0, 1)");
  if (!(scene.node_mass_kg > 0 && std::isfinite(scene.node_mass_kg))) bad("--node-mass-kg must be > 0");
  if (!(loss_probability >= 0 && loss_probability < 1)) bad("loss_probability must be in [0, 1)");
  if (delay_trace && delay_trace->empty()) bad("--delay-trace: the file holds no delay");
  if (!(burst_enter_probability >= 0 && burst_enter_probability <= 1)) bad("--burst-enter must be in [0, 1] (a probability per packet)");
  if (!(burst_mean_packets >= 1 && std::isfinite(burst_mean_packets))) bad("--burst-length must be >= 1 (packets)");
  if (!(burst_loss_probability >= 0 && burst_loss_probability <= 1)) bad("--burst-loss must be in [0, 1]");
  if (!(duplicate_probability >= 0 && duplicate_probability <= 1)) bad("duplicate_probability must be in [0, 1]");
  if (scene_nodes < kMinSceneNodes || scene_nodes > kMaxSceneNodes)
    bad("--nodes must be in [" + std::to_string(kMinSceneNodes) + ", " + std::to_string(kMaxSceneNodes) + "]");
  if (!scene_file.path.empty()) {
    if (!(scene_file.unit_m > 0 && std::isfinite(scene_file.unit_m))) bad(scene_file.key("unit_m") + " must be > 0 (metres per file unit)");
    if (!(scene_file.density_kg_per_m3 >= 0 && std::isfinite(scene_file.density_kg_per_m3))) bad(scene_file.key("density_kg_per_m3") + " must be > 0 kg/m^3");
    if (!(scene_file.youngs_modulus_Pa >= 0 && std::isfinite(scene_file.youngs_modulus_Pa))) bad(scene_file.key("youngs_modulus_Pa") + " must be > 0 Pa");
  }
  if (!(damping_margin >= 0 && damping_margin <= 10)) bad("damping margin must be in [0, 10]");
  if (loss_allowance_ticks < -1 || loss_allowance_ticks > 1000) bad("--loss-allowance must be in [0, 1000] ticks (-1: from the loss model)");
  if (!(edge_energy_bound_J >= 0 && edge_energy_bound_J <= 1e6)) bad("--edge-energy-bound must be in [0, 1e6] J (0 = off)");
  if (!(edge_energy_leak_W >= 0 && edge_energy_leak_W <= 1)) bad("--edge-energy-leak-W must be in [0, 1] W (0 = the account only grows)");
  if (!(edge_energy_hold_s >= 0 && edge_energy_hold_s <= 3600)) bad("--edge-energy-hold-s must be in [0, 3600] s (0 = off)");
  if (!(drop_fade_s >= 0 && drop_fade_s <= 10)) bad("--drop-fade-s must be in [0, 10] s (0 = the immediate drop)");
  if (!(tx_deadband.position_deadband_m >= 0 && tx_deadband.position_deadband_m < 0.1)) bad("--tx-deadband-mm must be in [0, 100)");
  if (tx_deadband.max_interval_ticks < 1 || tx_deadband.max_interval_ticks > 1000) bad("--tx-max-interval must be in [1, 1000]");
  if (resilient_f < 0 || resilient_f > 16) bad("--resilient-f must be in [0, 16] (0 = off)");
  if (state_check.enabled() && consensus_passivity == rt::ConsensusPassivity::kSetPositionModulation)
    bad("--state-check-kinematic-m / --state-check-disagreement-m need --consensus-passivity eq18 (pspm never drops an edge)");
  if (resilient_f > 0 && consensus_passivity == rt::ConsensusPassivity::kEq18Damping && !(edge_energy_bound_J > 0))
    bad("--resilient-f needs --edge-energy-bound > 0 with eq. (18): the energy bound covers an edge left out on one side (rt/README.md)");
  if (tx_deadband.predictive && consensus_passivity != rt::ConsensusPassivity::kSetPositionModulation)
    bad("--tx-predict needs --consensus-passivity pspm (eq. 18 does not cover extrapolated neighbour data)");
  if (!(timer_jitter_s >= 0 && timer_jitter_s < 0.5 * period_s)) bad("--timer-jitter-ms must be in [0, period/2) = [0, " + std::to_string(0.5e3 * period_s) + ") ms");
  if (!(step_jitter >= 0 && step_jitter <= 0.5)) bad("--step-jitter must be in [0, 0.5] (a fraction of the period)");
  if (!(clock_drift_ppm >= 0 && clock_drift_ppm <= 10000)) bad("--clock-drift-ppm must be in [0, 10000]");
  if (!(period_min_s >= 0 && period_min_s <= period_s)) bad("period_min_s must be in [0, period] (0: from the clock model)");
  if (!(period_max_s == 0 || (period_max_s >= period_s && period_max_s < 2 * period_s))) bad("period_max_s must be in [period, 2 period) (0: from the clock model)");
  if (!(script.asymmetry_tilt_deg >= 0 && script.asymmetry_tilt_deg <= 90)) bad("asymmetry tilt must be in [0, 90] degrees");
  if (!(script.asymmetry_depth >= 0 && script.asymmetry_depth <= 0.9)) bad("asymmetry depth must be in [0, 0.9]");
  scene.validate();
}

std::vector<double> parse_list(const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string tok;
  while (std::getline(ss, tok, ',')) out.push_back(to_double(tok, what));
  return out;
}

std::string SceneFileSpec::key(const std::string& field) const {
  if (from_station_file) return "scene." + field;
  if (field == "file") return "--scene";
  if (field == "unit_m") return "--scene-unit-m";
  if (field == "density_kg_per_m3") return "--density";
  if (field == "youngs_modulus_Pa") return "--youngs";
  return "--" + field;
}

namespace {
// The object: a mesh file with its material (rt::lump_material), or the built-in ball (paper
// ball, or a lattice ball scaled to the same object). Start-up only.
rt::Scene make_scene(const ScenarioSpec& spec) {
  const SceneFileSpec& f = spec.scene_file;
  if (!f.path.empty()) {
    scene::MeshReadOptions o;
    o.unit_m = f.unit_m;
    o.limits.max_nodes = f.max_nodes;
    o.limits.max_elements = f.max_elements;
    rt::TetMesh mesh;
    try {
      mesh = scene::read_scene_mesh(f.path, o);
    } catch (const scene::MeshError& e) {
      bad(f.key("file") + ": " + e.what());
    }
    rt::Material material = rt::paper_ball_material();
    if (f.density_kg_per_m3 > 0) material.density_kg_per_m3 = f.density_kg_per_m3;
    if (f.youngs_modulus_Pa > 0) material.youngs_modulus_Pa = f.youngs_modulus_Pa;
    return rt::build_scene(mesh, spec.scene, rt::lump_material(mesh, material));
  }
  const rt::TetMesh mesh = spec.scene_nodes == 33 ? rt::make_paper_ball(spec.ball_radius_m)
                                                  : rt::make_lattice_ball(spec.scene_nodes, spec.ball_radius_m);
  rt::SceneParams sp = spec.scene;
  if (spec.scene_nodes != 33 && spec.same_object_at_every_size) {
    auto mean_edge = [](const rt::TetMesh& m) {
      double s = 0;
      for (const auto& e : m.edges) s += (m.nodes[static_cast<std::size_t>(e[0])] - m.nodes[static_cast<std::size_t>(e[1])]).norm();
      return s / static_cast<double>(m.edges.size());
    };
    const rt::TetMesh paper = rt::make_paper_ball(spec.ball_radius_m);
    sp.node_mass_kg = spec.scene.node_mass_kg * paper.node_count() / mesh.node_count();
    sp.edge_stiffness_N_per_m = spec.scene.edge_stiffness_N_per_m * mean_edge(mesh) / mean_edge(paper);
  }
  return rt::build_scene(mesh, sp);
}
}  // namespace

BuiltScenario build_scenario(const ScenarioSpec& spec) {
  spec.validate();
  BuiltScenario b;
  b.spec = spec;
  const int N = spec.users;
  const double T = spec.period_s;
  b.scene = make_scene(spec);
  b.gains.reserve(spec.topology.size());
  for (std::size_t e = 0; e < spec.topology.size(); ++e)
    b.gains.push_back(e == 0 ? rt::paper_edge_gains(b.scene, spec.p_gain_N_per_m, spec.d_gain_Ns_per_m) : b.gains[0]);
  const model::Adjacency adj = model::adjacency(spec.topology, N);
  b.neighbors = adj.neighbours;
  b.neighbor_edge = adj.link_of;
  for (int i = 0; i < N; ++i)
    if (static_cast<int>(b.neighbors[static_cast<std::size_t>(i)].size()) > rt::kMaxNeighbors)
      bad("--topology: user " + std::to_string(i + 1) + " has more than " + std::to_string(rt::kMaxNeighbors) + " links");
  set_step_bounds(b);
  // Nbar_ij from the delay model with its allowances, B_i and the condition: the passivity budget
  // (firmware/model/passivity_budget.hpp).
  const model::NbarAllowances allow = model::delay_model_allowances(
      spec.loss_allowance_ticks, spec.loss_model(), spec.duration_s, T, 2 * static_cast<int>(spec.topology.size()),
      spec.tx_deadband, model::ClockModel{spec.timer_jitter_s, spec.step_jitter, spec.clock_drift_ppm});
  b.loss_allowance_ticks = allow.loss_ticks;
  if (spec.delay_trace) {
    const auto [lo_ms, hi_ms] = spec.delay_trace_range_ms();
    b.nbar_ticks = model::index_delay_bounds_ticks_from_range(spec.delay_ms, lo_ms, hi_ms, T, allow.total(), spec.receive_rule);
  } else {
    b.nbar_ticks = model::index_delay_bounds_ticks(spec.delay_ms, spec.jitter_fraction, T, allow.total(), spec.receive_rule);
  }
  const Eigen::VectorXd half_sums = model::round_trip_half_sums_ms(spec.topology, b.nbar_ticks, T);
  b.round_trip_sum_ms.assign(half_sums.data(), half_sums.data() + half_sums.size());
  b.damping_min.assign(static_cast<std::size_t>(N), 0.0);
  b.damping.assign(static_cast<std::size_t>(N), 0.0);
  b.passivity_condition_met = true;
  for (int i = 0; i < N; ++i) {
    std::vector<int> sums;
    for (int j : b.neighbors[static_cast<std::size_t>(i)]) sums.push_back(model::link_bound_from_delay_model(b.nbar_ticks, i, j).assumed_sum_ticks);
    const model::Damping d = b.damping_eq18(i, sums, spec.damping_Ns_per_m ? (*spec.damping_Ns_per_m)[static_cast<std::size_t>(i)] : -1.0,
                                            spec.damping_margin);
    b.damping_min[static_cast<std::size_t>(i)] = d.min_Ns_per_m;
    b.damping[static_cast<std::size_t>(i)] = d.used_Ns_per_m;
    b.passivity_condition_met = b.passivity_condition_met && d.condition_met;
  }
  assign_pushes(b);
  b.trace_node = spec.trace_node >= 0 ? spec.trace_node : b.contact_nodes[std::min(1, N - 1)][0];
  if (b.trace_node >= b.scene.nodes) bad("--trace-node must be below the node count " + std::to_string(b.scene.nodes));
  return b;
}

namespace {
// Each user's contact face, push direction, depth and proxy start (ScenarioSpec's push pattern),
// and the imbalance of the intended pushes. Start-up only.
void assign_pushes(BuiltScenario& b) {
  const auto& spec = b.spec;
  const int N = spec.users;
  const auto& mesh = b.scene.mesh;
  const Eigen::Vector3d c0 = mesh.face_center(mesh.face_towards(Eigen::Vector3d(1, 1, 1))) - mesh.centroid();
  std::vector<Eigen::Vector3d> dirs = spread_directions(N, c0);
  std::vector<double> depth(static_cast<std::size_t>(N), spec.script.push_depth_m);
  if (spec.script.push_pattern == UserScriptSpec::PushPattern::kAsymmetric) {
    net::Rng rng(spec.script.push_seed * 104729ULL + 17);
    const double tilt = spec.script.asymmetry_tilt_deg * std::numbers::pi / 180.0;
    for (int i = 0; i < N; ++i) {
      Eigen::Vector3d axis;
      for (int a = 0; a < 3; ++a) axis[a] = 2 * rng.uniform01() - 1;
      axis = axis.cross(dirs[static_cast<std::size_t>(i)]);  // a random axis perpendicular to the direction
      if (axis.norm() < 1e-9) axis = dirs[static_cast<std::size_t>(i)].unitOrthogonal();
      dirs[static_cast<std::size_t>(i)] = Eigen::AngleAxisd(tilt * rng.uniform01(), axis.normalized()) * dirs[static_cast<std::size_t>(i)];
      depth[static_cast<std::size_t>(i)] *= 1.0 + spec.script.asymmetry_depth * (2 * rng.uniform01() - 1);
    }
  }
  Eigen::Vector3d intended = Eigen::Vector3d::Zero();
  double depth_sum = 0;
  for (int i = 0; i < N; ++i) {
    // The user's proxy starts outside the object on its direction and approaches the centroid: its
    // contact face is the boundary triangle it touches first (TetMesh::face_touched_from), for any
    // mesh (the core fixes the contact nodes at start-up: its Schur data are precomputed).
    Eigen::Vector3d touch;
    const int f = mesh.face_touched_from(dirs[static_cast<std::size_t>(i)], &touch);
    if (f < 0)
      bad("scene: user " + std::to_string(i + 1) + "'s proxy, approaching the object's centroid, touches no surface (the centroid is outside the object?)");
    const auto& face = mesh.surface[static_cast<std::size_t>(f)];
    b.contact_nodes.push_back({face[0], face[1], face[2]});
    // N = 4 spread: the paper's pattern pushes along the face normals (cancel by the ball's symmetry);
    // otherwise along -d, so spread pushes cancel exactly whatever faces the mesh offers.
    const bool paper_pattern = N == 4 && spec.script.push_pattern == UserScriptSpec::PushPattern::kSpread;
    b.push_direction.push_back(paper_pattern ? Eigen::Vector3d(-mesh.face_normal(f)) : Eigen::Vector3d(-dirs[static_cast<std::size_t>(i)]));
    b.push_depth_m.push_back(depth[static_cast<std::size_t>(i)]);
    b.vp_start.push_back(touch);
    intended += depth[static_cast<std::size_t>(i)] * b.push_direction.back();
    depth_sum += depth[static_cast<std::size_t>(i)];
  }
  b.push_imbalance_ratio = depth_sum > 0 ? intended.norm() / (depth_sum / N) : 0.0;
}
}  // namespace

model::Graph default_tree(int users) {
  model::Graph g;
  for (int k = 1; k < users; ++k) g.push_back({(k - 1) / 3, k});
  return model::normalized(g);
}

void set_user_count(ScenarioSpec& spec, int users, const std::string& key) {
  if (users < 2 || users > 64) bad(key + " = " + std::to_string(users) + " must be in [2, 64]");
  if (users == spec.users) return;
  spec.users = users;
  spec.delay_ms = Eigen::MatrixXd::Constant(users, users, kDefaultNUserMeanDelayMs);
  spec.delay_ms.diagonal().setZero();
  spec.topology = default_tree(users);
}

void make_solo(ScenarioSpec& spec, double anchor_N_per_m, const std::string& key) {
  if (!(anchor_N_per_m >= 0 && anchor_N_per_m <= 1e4)) bad(key + " = " + std::to_string(anchor_N_per_m) + " must be in [0, 10000] N/m");
  spec.scene.ground_stiffness_N_per_m = anchor_N_per_m;
  spec.name += "-solo";
  spec.users = 1;
  spec.topology.clear();
  spec.delay_ms = Eigen::MatrixXd::Zero(1, 1);
  spec.damping_Ns_per_m.reset();  // a scenario's fixed B_i are per user of its own links
  spec.script.kind = UserScriptSpec::Kind::kRandom;
}

void apply_topology_file(ScenarioSpec& spec, const std::string& path, const std::string& key) {
  const std::string where = key + " = \"" + path + "\"";
  std::ifstream in(path);
  if (!in) bad(where + ": cannot open the file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    bad(where + ": not JSON (" + e.what() + ")");
  }
  if (!j.is_object() || !j.contains("users") || !j.contains("mean_delay_ms") || !j.contains("ranked") || j["ranked"].empty())
    bad(where + ": not a haptic-topology --json file (needs users, mean_delay_ms and a non-empty ranked)");
  try {
    set_user_count(spec, j["users"].get<int>(), where + ": users");
    model::Graph g;
    for (const auto& e : j["ranked"][0]["edges"]) g.push_back({e[0].get<int>() - 1, e[1].get<int>() - 1});
    model::validate_graph(g, spec.users, where + ": ranked[0].edges");
    spec.topology = model::normalized(g);
    const auto& m = j["mean_delay_ms"];
    if (!m.is_array() || static_cast<int>(m.size()) != spec.users) bad(where + ": mean_delay_ms must be users x users");
    for (int r = 0; r < spec.users; ++r) {
      if (!m[r].is_array() || static_cast<int>(m[r].size()) != spec.users) bad(where + ": mean_delay_ms must be users x users");
      for (int c = 0; c < spec.users; ++c) spec.delay_ms(r, c) = m[r][c].is_null() ? 0.0 : m[r][c].get<double>();
    }
    for (const auto& l : spec.topology)
      if (m[l.a][l.b].is_null() || m[l.b][l.a].is_null())
        bad(where + ": link " + std::to_string(l.a + 1) + "-" + std::to_string(l.b + 1) + " has no delay in mean_delay_ms");
  } catch (const nlohmann::json::exception& e) {
    bad(where + ": " + e.what());
  }
}

UserScriptSpec::PushPattern parse_push_pattern(const std::string& text, const std::string& key) {
  if (text == "spread") return UserScriptSpec::PushPattern::kSpread;
  if (text == "asymmetric") return UserScriptSpec::PushPattern::kAsymmetric;
  bad(key + " = \"" + text + "\" must be \"spread\" or \"asymmetric\"");
}

void apply_script_kind(UserScriptSpec& script, const std::string& text, std::uint64_t seed, const std::string& key) {
  if (text.empty()) return;  // the scenario's
  if (text == "push-hold-release") script.kind = UserScriptSpec::Kind::kPushHoldRelease;
  else if (text == "random") script.kind = UserScriptSpec::Kind::kRandom;
  else if (text == "hold") script.kind = UserScriptSpec::Kind::kHold;
  else bad(key + " = \"" + text + "\" must be \"push-hold-release\", \"random\" or \"hold\" (or \"\" for the scenario's)");
  script.random_seed = seed;
}

model::Damping BuiltScenario::damping_eq18(int user, const std::vector<int>& round_trip_sum_ticks, double override_Ns_per_m,
                                           double margin) const {
  std::vector<double> t_max;
  for (const int j : neighbors[static_cast<std::size_t>(user)]) t_max.push_back(t_max_s[static_cast<std::size_t>(j)]);
  return damping_eq18(user, round_trip_sum_ticks, override_Ns_per_m, margin, t_min_s[static_cast<std::size_t>(user)], t_max);
}

model::Damping BuiltScenario::damping_eq18(int user, const std::vector<int>& round_trip_sum_ticks, double override_Ns_per_m, double margin,
                                           double t_min_i_s, const std::vector<double>& t_max_j_s) const {
  const auto& edges = neighbor_edge[static_cast<std::size_t>(user)];
  if (round_trip_sum_ticks.size() != edges.size() || t_max_j_s.size() != edges.size())
    throw std::invalid_argument("damping_eq18: one round trip and one T_j^max per neighbour needed");
  std::vector<const rt::EdgeGains*> g;
  for (const int e : edges) g.push_back(&gains[static_cast<std::size_t>(e)]);
  return model::damping_eq18(t_min_i_s, round_trip_sum_ticks, t_max_j_s, g, margin, override_Ns_per_m, spec.consensus_passivity);
}

rt::StationConfig BuiltScenario::station_config(int i) const {
  rt::StationConfig c;
  c.station_id = i;
  c.users = spec.users;
  c.period_s = spec.period_s;
  c.period_min_s = t_min_s[static_cast<std::size_t>(i)];
  c.period_max_s = t_max_s[static_cast<std::size_t>(i)];
  c.scene = &scene;
  c.damping_Ns_per_m = damping[static_cast<std::size_t>(i)];
  for (std::size_t n = 0; n < neighbors[static_cast<std::size_t>(i)].size(); ++n) {
    rt::NeighborConfig nc;
    nc.peer_id = neighbors[static_cast<std::size_t>(i)][n];
    nc.gains = &gains[static_cast<std::size_t>(neighbor_edge[static_cast<std::size_t>(i)][n])];
    nc.index_delay_bound_ticks = nbar_ticks(i, nc.peer_id);
    nc.step_min_s = t_min_s[static_cast<std::size_t>(nc.peer_id)];
    nc.step_max_s = t_max_s[static_cast<std::size_t>(nc.peer_id)];
    if (spec.edge_energy_bound_J > 0) {
      nc.energy_bound_J = spec.edge_energy_bound_J;
      nc.energy_release_J = 0.5 * spec.edge_energy_bound_J;
    }
    nc.energy_leak_W = spec.edge_energy_leak_W;
    nc.energy_hold_s = spec.edge_energy_hold_s;
    c.neighbors.push_back(nc);
  }
  c.rx_rule = spec.receive_rule;
  c.solver.kind = spec.solver;
  c.divergence_speed_m_per_s = spec.divergence_speed_m_per_s;
  c.consensus_passivity = spec.consensus_passivity;
  c.state_check = spec.state_check;
  c.pspm_reservoir0_J = spec.pspm_reservoir0_J;
  c.resilient_f = spec.resilient_f;
  c.predict_held_state = spec.tx_deadband.predictive;
  c.return_ramp_s = spec.return_ramp_s;
  c.drop_fade_s = spec.drop_fade_s;
  if (spec.tx_deadband.enabled()) c.predict_held_limit_m = spec.tx_deadband.prediction_limit_m();
  c.vp = spec.vp;
  c.contact_nodes = contact_nodes[static_cast<std::size_t>(i)];
  c.vp_initial_position_m = vp_start[static_cast<std::size_t>(i)];
  c.device_damping_Ns_per_m = spec.device.damping_Ns_per_m;
  return c;
}

rt::GoalScript BuiltScenario::goal_script(int i) const {
  const auto& s = spec.script;
  const Eigen::Vector3d p0 = vp_start[static_cast<std::size_t>(i)];
  const Eigen::Vector3d in = push_direction[static_cast<std::size_t>(i)];
  const double depth = push_depth_m[static_cast<std::size_t>(i)];
  rt::GoalScript g(p0);
  if (std::find(s.idle_users.begin(), s.idle_users.end(), i) != s.idle_users.end()) return g;  // holds still
  switch (s.kind) {
    case UserScriptSpec::Kind::kPushHoldRelease:
      g.add(s.push_start_s, p0);
      g.add(s.push_end_s, p0 + depth * in);
      g.add(s.release_s, p0 + depth * in);
      g.add(s.release_s + s.retract_s, p0 - s.retract_depth_m * in);
      break;
    case UserScriptSpec::Kind::kPerturb:
      if (i == s.perturb_user) {
        g.add(s.perturb_at_s, p0);
        g.add(s.perturb_at_s + s.perturb_duration_s / 2, p0 + s.perturb_depth_m * in);
        g.add(s.perturb_at_s + s.perturb_duration_s, p0);
      }
      break;
    case UserScriptSpec::Kind::kHold:
      break;
    case UserScriptSpec::Kind::kRandom: {
      // Passive users with arbitrary intent: random keyframes inside +-amplitude of the start.
      net::Rng rng(s.random_seed * 7919ULL + static_cast<std::uint64_t>(i));
      const double dt = spec.duration_s / (rt::GoalScript::kMaxKeys - 1);
      for (std::size_t kf = 1; kf < rt::GoalScript::kMaxKeys; ++kf) {
        Eigen::Vector3d off;
        for (int d = 0; d < 3; ++d) off[d] = s.random_amplitude_m * (2 * rng.uniform01() - 1);
        off += 0.5 * s.random_amplitude_m * in;  // lean into the object so contact happens
        g.add(static_cast<double>(kf) * dt, p0 + off);
      }
      break;
    }
  }
  return g;
}

}  // namespace haptic::firmware
