#pragma once
// Scenarios: the paper's experiment (Section V) and its variants, as data. Shared by the
// deterministic simulator and the real-time station so both run the same scene and gains.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "firmware/model/delay_model.hpp"
#include "firmware/model/graph.hpp"
#include "firmware/model/passivity_budget.hpp"
#include "net/impairment.hpp"
#include "rt/gains.hpp"
#include "rt/scene.hpp"
#include "rt/station.hpp"
#include "rt/tx_deadband.hpp"
#include "rt/user_model.hpp"

namespace haptic::firmware {

struct UserScriptSpec {
  enum class Kind { kPushHoldRelease, kPerturb, kHold, kRandom } kind = Kind::kPushHoldRelease;
  double push_start_s = 0.5;
  double push_end_s = 3.0;
  double release_s = 12.0;       // the hands retract from here
  double retract_s = 0.5;        // duration of the retraction
  double push_depth_m = 0.03;    // hand goal travel into the object
  double retract_depth_m = 0.03; // hand goal travel out past the start point
  int perturb_user = 0;          // kPerturb: which user (0-based) perturbs
  double perturb_at_s = 2.5;
  double perturb_depth_m = 0.005;
  double perturb_duration_s = 0.2;
  std::uint64_t random_seed = 1;  // kRandom: every user's goal wanders through random keyframes
  double random_amplitude_m = 0.02;
  // Users (0-based) whose hands hold still at their start point whatever the kind: stations that only
  // receive (their copy moves only because the others push), e.g. for the per-edge energy account.
  std::vector<int> idle_users;
  // Where the users push (build_scenario). kSpread: directions whose sum is zero by construction
  // (N = 4: the paper's tetrahedral pattern; other N: antipodal pairs, plus one planar triangle
  // when N is odd), all at push_depth_m. kAsymmetric: each direction tilted by up to
  // asymmetry_tilt_deg about a seeded random axis and each depth scaled by a seeded factor in
  // [1 - asymmetry_depth, 1 + asymmetry_depth], so the users' intended pushes do not cancel and
  // the hold-force balance (eq. 20) is a measurement, not a symmetry.
  enum class PushPattern { kSpread, kAsymmetric } push_pattern = PushPattern::kSpread;
  std::uint64_t push_seed = 1;
  double asymmetry_tilt_deg = 30.0;
  double asymmetry_depth = 0.5;
};

// A scene read from a file (firmware/scene/mesh_io.hpp) instead of the built-in ball: the mesh,
// the unit of its coordinates and the material (rt::Material: lumped masses, van Gelder springs).
struct SceneFileSpec {
  std::string path;                   // "" = the built-in ball of ScenarioSpec::scene_nodes
  bool from_station_file = false;     // errors name scene.* keys (else the sim options --scene ...)
  double unit_m = 1.0;                // metres per file unit
  double density_kg_per_m3 = 0;       // 0 = rt::paper_ball_material()'s
  double youngs_modulus_Pa = 0;       // 0 = rt::paper_ball_material()'s
  int max_nodes = 20000;
  int max_elements = 200000;
  // The key naming `field` ("file", "unit_m", "density_kg_per_m3", "youngs_modulus_Pa") as the user wrote it.
  std::string key(const std::string& field) const;
};

// Sizes of the built-in lattice ball (ScenarioSpec::scene_nodes): the smallest that makes a ball (for 7,
// rt::make_lattice_ball finds no lattice spacing), the largest the simulator builds (a real-time
// station's own bound is station.nodes's, firmware/station/options.cpp).
inline constexpr int kMinSceneNodes = 8;
inline constexpr int kMaxSceneNodes = 20000;

struct ScenarioSpec {
  std::string name = "paper-best";
  int users = 4;
  double period_s = 0.002;
  double duration_s = 20.0;
  std::uint64_t seed = 1;
  model::Graph topology;                     // undirected links, 0-based (firmware/model/graph.hpp)
  Eigen::MatrixXd delay_ms;                  // mean one-way delay, row i receives from column j
  double jitter_fraction = net::kPaperJitterFraction;      // the paper's impairment (net/impairment.hpp)
  double delay_correlation = 0;              // --delay-correlation: AR(1) per packet of the delay (net::LinkImpairment), 0 = i.i.d.
  double loss_probability = net::kPaperLossProbability;
  // --delay-trace: recorded one-way delays (s) every link replays in place of the uniform draw
  // (net::LinkImpairment::delay_trace; Nbar then from the trace's range); empty: the delay model.
  std::shared_ptr<const std::vector<double>> delay_trace;
  std::pair<double, double> delay_trace_range_ms() const;  // its smallest and largest delay (a trace is given)
  // Gilbert-Elliott burst loss on every link (net::LinkImpairment; off when burst_enter_probability = 0):
  // --burst-enter (good -> bad per packet), --burst-length (mean packets in the bad state), --burst-loss.
  double burst_enter_probability = 0;
  double burst_mean_packets = 5;
  double burst_loss_probability = 1;
  model::LossModel loss_model() const {
    return {loss_probability, burst_enter_probability, 1.0 / burst_mean_packets, burst_loss_probability};
  }
  double duplicate_probability = net::kPaperDuplicateProbability;
  int scene_nodes = 33;                      // 33: the paper's ball; otherwise a lattice ball, [kMinSceneNodes, kMaxSceneNodes]
  SceneFileSpec scene_file{};                // a mesh file instead (scene_nodes then unused)
  // For a lattice ball, keep the same physical object as the paper's ball: total mass 33 x
  // node_mass_kg shared by the nodes, and edge stiffness scaled by mean edge length (a spring
  // network's modulus goes as k / h), so resolutions differ only in discretization.
  bool same_object_at_every_size = true;
  double ball_radius_m = 0.05;
  rt::SceneParams scene{};
  double p_gain_N_per_m = 1000.0;
  double d_gain_Ns_per_m = 5.0;
  rt::VirtualProxyParams vp{};
  rt::DeviceModelParams device{};
  rt::HandParams hand{};
  std::optional<std::vector<double>> damping_Ns_per_m;  // B_i override (one per user)
  double damping_margin = 0.05;          // B_i = (1 + margin) * eq. (18) minimum
  // Nbar_ij = ceil(max one-way delay / T) + this (firmware/model/delay_model.hpp); -1 (default):
  // from the loss model, model::loss_allowance_from_loss(loss_probability, run ticks, directed links)
  int loss_allowance_ticks = -1;
  rt::TxDeadbandConfig tx_deadband{};    // transmission deadband (off); Nbar_ij adds (L + 1)(interval - 1)
  rt::RxRule receive_rule = rt::RxRule::kNewestBySequence;  // --receive-rule newest|paper (rt/rx_link.hpp)
  rt::StepSolverKind solver = rt::StepSolverKind::kAuto;     // --solver auto|direct|iterative (rt/step_solver.hpp)
  // Variable steps T_k (rt/README.md "Variable steps"). The simulator's station clocks: every wake
  // is late by a uniform draw in [0, timer_jitter_s] after its grid time; step_jitter F makes each
  // grid interval T (1 + F u), u uniform in [-1, 1] (a free-running loop: the station's tick count
  // wanders against the others'); station i's grid interval is T (1 + c_i 1e-6), c_i spread evenly
  // over [-clock_drift_ppm, +clock_drift_ppm]. T_k = the interval between two wakes.
  double timer_jitter_s = 0;   // --timer-jitter-ms
  double step_jitter = 0;      // --step-jitter
  double clock_drift_ppm = 0;  // --clock-drift-ppm
  // Bounds T^min <= T_k <= T^max of every station (eq. 18's D term, eq. 26, the core's steps);
  // 0: from the clock model above (= period_s without one). The real station: station.period_min_s/max_s.
  double period_min_s = 0, period_max_s = 0;
  bool has_clock_model() const { return timer_jitter_s > 0 || step_jitter > 0 || clock_drift_ppm > 0; }
  // Per-edge damage bound (rt/edge_energy.hpp): an edge whose energy account
  // exceeds this acts as the damper until the account has fallen to half of it. 0 = off.
  double edge_energy_bound_J = rt::kDefaultEdgeEnergyBoundJ;
  double edge_energy_leak_W = rt::kDefaultEdgeEnergyLeakW;  // the accounts' leak (rt/edge_energy.hpp)
  // The gate's timed release (rt/edge_energy.hpp): a tripped edge released after this long x 2^(trips - 1).
  // 0 = off (the simulator's default; a station's is station.edge_energy_hold_s).
  double edge_energy_hold_s = 0;
  // An edge returning after an outage ramps in over this long (rt/return_ramp.hpp); 0 = off (the
  // simulator's default; a station's is station.return_ramp_s).
  double return_ramp_s = 0;
  // An edge whose data ages out fades out over this long (rt/drop_fade.hpp); 0 = the paper's
  // immediate drop (the simulator's default, --drop-fade-s; a station's is station.drop_fade_s).
  double drop_fade_s = 0;
  double divergence_speed_m_per_s = 50;  // a node faster than this: diverged, safe state (rt::StationConfig)
  // The neighbour state check of every station (rt/edge_monitor.hpp): off here by default; the real
  // station turns it on (station.state_check_*).
  rt::EdgeMonitorParams state_check{};
  // --consensus-passivity eq18|pspm (rt/set_position_modulation.hpp): with pspm, B_i defaults to 0
  // (eq. 14 holds by construction) and pspm_reservoir0_J is each edge's initial reservoir.
  rt::ConsensusPassivity consensus_passivity = rt::ConsensusPassivity::kEq18Damping;
  double pspm_reservoir0_J = 0.0;
  // Resilient consensus (rt/resilient.hpp, --resilient-f, station.resilient_f): each station leaves out
  // the F neighbours farthest from its copy every tick. 0 = off. With eq. (18) it needs the energy bound.
  int resilient_f = 0;
  UserScriptSpec script{};
  int trace_node = -1;                   // -1: first node of user 2's contact mesh (paper: node 19)

  void validate() const;  // throws std::invalid_argument naming the option
};

// Names of the built-in scenarios, and the spec for one (throws std::invalid_argument listing
// the valid names when unknown).
std::vector<std::string> scenario_names();
// key: the option or configuration key that named it, for the error ("": none).
ScenarioSpec make_scenario(const std::string& name, const std::string& key = "");

// N users (2..64) for a scenario made for 4: the delay matrix becomes uniform at
// default_mean_delay_ms and the topology the tree of degree <= 4 user k -> user (k - 2) / 3 + 1
// (1-based), unless the caller sets its own (e.g. apply_topology_file). users == spec.users: no
// change. Throws std::invalid_argument naming `key` when out of range. Not RT-safe.
inline constexpr double kDefaultNUserMeanDelayMs = 10.0;
void set_user_count(ScenarioSpec& spec, int users, const std::string& key = "--users");
model::Graph default_tree(int users);
// `haptic-station solo`: one user and no links (no neighbour, so eq. (18) gives B_i = 0 through
// the budget's own rule), its script kRandom so a simulated user keeps touching the object by
// itself (the station then applies station.script over it, apply_script_kind); anchor_N_per_m > 0: a ground spring K_gnd of that stiffness on every node (rt::SceneParams),
// so one hand cannot push the floating object away (0: the paper's floating object). The rest of the
// spec (scene, gains, period, duration) is kept. Throws std::invalid_argument naming `key`. Not RT-safe.
void make_solo(ScenarioSpec& spec, double anchor_N_per_m = 0, const std::string& key = "--anchor");
// The eq. (27) optimizer's choice: haptic-topology's --json output (users, mean_delay_ms, ranked
// best first). Sets spec.users, spec.delay_ms (no link = null: 0 where the graph has no link) and
// spec.topology = ranked[0].edges. Throws std::invalid_argument naming `key` and the file.
void apply_topology_file(ScenarioSpec& spec, const std::string& path, const std::string& key = "--topology-file");
// "spread" | "asymmetric" (throws std::invalid_argument naming `key`).
UserScriptSpec::PushPattern parse_push_pattern(const std::string& text, const std::string& key);
// The users' script by name: "push-hold-release", "random" (every hand wanders through seeded random
// keyframes over the whole run, so the object never comes to rest), "hold" (hands still); "" keeps the
// scenario's. Throws std::invalid_argument naming `key`.
void apply_script_kind(UserScriptSpec& script, const std::string& text, std::uint64_t seed, const std::string& key);

// "1,2,3" (throws std::invalid_argument naming `what`). Topologies and delay matrices are parsed
// by firmware/model (parse_graph_1based, parse_delay_matrix).
std::vector<double> parse_list(const std::string& text, const std::string& what);

// Everything built from a spec: the scene, one gain set per edge, per-user bounds and dampings.
struct BuiltScenario {
  ScenarioSpec spec;
  rt::Scene scene;
  std::vector<rt::EdgeGains> gains;             // one per link in spec.topology
  std::vector<std::vector<int>> neighbors;      // neighbors[i] = peers of i (0-based)
  std::vector<std::vector<int>> neighbor_edge;  // edge index of neighbors[i][n]
  Eigen::MatrixXi nbar_ticks;                   // Nbar_ij bound used by eq. (18) and the guard (model::index_delay_bounds_ticks)
  int loss_allowance_ticks = 0;                 // the allowance in nbar_ticks (spec's, or from the loss model)
  std::vector<double> round_trip_sum_ms;        // sum_j (Nbar_ij + Nbar_ji) T / 2, per user (model::round_trip_half_sums_ms)
  std::vector<double> t_min_s, t_max_s;         // T_i^min, T_i^max per user (eq. 18, 26)
  std::vector<double> clock_rate;               // grid interval / T = 1 + c_i 1e-6 per user (ScenarioSpec::clock_drift_ppm)
  std::vector<double> damping_min;              // eq. (18), per user
  std::vector<double> damping;                  // B_i used
  std::vector<std::vector<int>> contact_nodes;  // contact mesh per user
  std::vector<Eigen::Vector3d> push_direction;  // inward, per user
  std::vector<double> push_depth_m;             // hand goal travel into the object, per user
  std::vector<Eigen::Vector3d> vp_start;        // light contact point per user
  int trace_node = 0;
  bool passivity_condition_met = false;
  // |sum_i depth_i d_i| / mean_i depth_i of the users' intended pushes (d_i = push_direction):
  // ~0 for kSpread, clearly > 0 for kAsymmetric; the hold-force balance is measured against it.
  double push_imbalance_ratio = 0;

  // eq. (18) for `user` with the given Nbar_ij + Nbar_ji (ticks), one per neighbour in
  // neighbors[user] order (the model's bounds, build_scenario, or measured ones, the station), and
  // B_i by the budget's rule (model::damping_eq18: override >= 0, the pspm rule, the margin).
  model::Damping damping_eq18(int user, const std::vector<int>& round_trip_sum_ticks, double override_Ns_per_m, double margin) const;
  // The same with the user's own T_i^min and its neighbours' T_j^max given (the real station: its
  // measured bounds and the ones its neighbours announced), in place of t_min_s / t_max_s.
  model::Damping damping_eq18(int user, const std::vector<int>& round_trip_sum_ticks, double override_Ns_per_m, double margin, double t_min_i_s,
                              const std::vector<double>& t_max_j_s) const;
  rt::StationConfig station_config(int user) const;
  rt::GoalScript goal_script(int user) const;
};

BuiltScenario build_scenario(const ScenarioSpec& spec);

}  // namespace haptic::firmware
