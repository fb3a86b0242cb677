#pragma once
// One station's real-time core: its local copy of the virtual object (NPMI, eq. 9), the PD
// consensus law (15) towards its neighbours' copies, the virtual proxy (21) in contact with the
// contact mesh (22) and the virtual coupling to the device (Section III-C), solved together in
// one non-iterative linear step per tick (DESIGN.md, "The linear step"):
//
//   A_S v_hat = b,   A_S = (1/N)(2M/T + B + T/2 K) + B_i + sum_{j in S} (D_ij + T/2 P_ij)
//
// with S all configured neighbours: a neighbour whose packet is older than its bound keeps its
// edge in the matrix and its data are replaced by this station's own state (x_hat_j := x(k),
// delta_ij = 0), which turns the edge into pure damping D_ij + T/2 P_ij (rt/README.md, "One matrix
// at any degree"). A is constant: one solver per station (rt/step_solver: direct LDL^T for small
// scenes, Jacobi-preconditioned CG for large ones). Contact adds c = b_c + k_c T/2 on the contact
// nodes and couples them to the VP's unknown w_hat; that is solved by a Schur complement on top of
// A^{-1} (a small dense system of at most 3*kMaxContactNodes + 3 unknowns) whose data are
// precomputed at start-up, so a change of contact or neighbour set costs nothing extra in the tick.
// Worst-case tick cost: one solve with 3 right-hand sides plus O(n * |C|) work.
//
// tick() never allocates, locks or blocks, and never throws: it returns status flags.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "rt/cpu_avx.hpp"
#include "rt/edge_energy.hpp"
#include "rt/edge_monitor.hpp"
#include "rt/gains.hpp"
#include "rt/multi_term_operator.hpp"
#include "rt/drop_fade.hpp"
#include "rt/return_ramp.hpp"
#include "rt/rx_link.hpp"
#include "rt/scene.hpp"
#include "rt/set_position_modulation.hpp"
#include "rt/step_solver.hpp"

namespace haptic::rt {

using Vec3 = Eigen::Vector3d;

inline constexpr int kMaxContactNodes = 8;
inline constexpr int kMaxNeighbors = 16;
static_assert(kMaxNeighbors <= kMaxEdgeAccounts, "one energy account per neighbour");
static_assert(kMaxNeighbors <= kMaxMonitoredEdges, "one state check per neighbour");

struct VirtualProxyParams {
  double mass_kg = 0.001;                    // m_i (eq. 21)
  double contact_damping_Ns_per_m = 0.0;     // b_c (eq. 22)
  double contact_stiffness_N_per_m = 200.0;  // k_c (eq. 22)
  VirtualCouplingGains coupling{};           // b_v, B_vc, K_vc (Section III-C)
};

struct NeighborConfig {
  int peer_id = -1;
  const EdgeGains* gains = nullptr;
  // Bound on the indexing delay N_ij^k assumed by eq. (18). A packet older than this is acted on
  // passively: the neighbour's data are replaced by this station's own state (x_hat_j := x(k),
  // delta_ij = 0), so the edge acts as the damper D_ij + T/2 P_ij until a packet within the bound
  // arrives (counted as a bound violation).
  std::int64_t index_delay_bound_ticks = 1 << 30;
  // This edge's share of B_i in the per-edge energy account (rt/edge_energy.hpp); shares are
  // normalized over the neighbours, all 0 (default): equal shares.
  double damping_share = 0;
  // Per-edge damage bound (rt/edge_energy.hpp EdgeEnergyGate): when this edge's
  // energy account exceeds energy_bound_J the edge takes the over-bound action above (the damper),
  // latched until the account has fallen to energy_release_J. +inf: off.
  double energy_bound_J = EdgeEnergyGate::kOff;
  double energy_release_J = 0;
  // The timed release (EdgeEnergyGate, rt/README.md "The timed release"): a tripped edge is released
  // after it stayed tripped this long x 2^(trips - 1), the excess of its account forgiven. 0: off
  // (released at energy_release_J only).
  double energy_hold_s = 0;
  // The account's leak (EdgeEnergyAccount::set_leak): energy that left the copy is taken off this
  // edge's account up to this power, W (0: the account only grows).
  double energy_leak_W = 0;
  // The neighbour's step bounds T_j^min <= T_k <= T_j^max, for the state check's step fit
  // (rt/edge_monitor.hpp StepBox; 0: the nominal period, a neighbour with fixed steps).
  double step_min_s = 0, step_max_s = 0;
};

struct StationConfig {
  int station_id = 0;
  int users = 1;                 // N (the VO is scaled by 1/N, eq. 9)
  double period_s = 0.002;       // T (nominal step)
  // Variable steps T_k (eq. 9, rt/README.md "Variable steps"): the bounds T_i^min <= T_k <= T_i^max
  // that eq. (18)'s D term and eq. (26)'s T_k/T_{k-1} assume (0: period_s). tick(k, q, step_s)
  // clamps a requested step into them (counted) and integrates with the nearest of the prefactored
  // steps: period_s + m * step_resolution_s inside the bounds, plus the two bounds themselves.
  double period_min_s = 0;
  double period_max_s = 0;
  double step_resolution_s = 0;  // 0: (period_max - period_min) / 8
  double t_min() const { return period_min_s > 0 ? period_min_s : period_s; }
  double t_max() const { return period_max_s > 0 ? period_max_s : period_s; }
  const Scene* scene = nullptr;
  double damping_Ns_per_m = 0;   // B_i = beta I (eq. 15), set from eq. (18)
  std::vector<NeighborConfig> neighbors;
  RxRule rx_rule = RxRule::kNewestBySequence;  // receive rule of every neighbour (rt/rx_link.hpp)
  // The neighbour state check of every edge (rt/edge_monitor.hpp; default off): an edge whose
  // reported states fail it is isolated (acts as the damper) until re-admitted. Not with pspm.
  EdgeMonitorParams state_check{};
  // kSetPositionModulation: every edge's P term acts towards a modulated set-position and its D term
  // on the local velocity only (rt/set_position_modulation.hpp); eq. (14) holds by construction with
  // c^2 = pspm_reservoir0_J per edge, so no index-delay bound applies (no edge is dropped) and B_i
  // may be 0. kEq18Damping: the paper's law with B_i from eq. (18) and the bound above.
  ConsensusPassivity consensus_passivity = ConsensusPassivity::kEq18Damping;
  double pspm_reservoir0_J = 0.0;  // initial energy reservoir of each edge (>= 0)
  // With kSetPositionModulation only: while a neighbour's packet is held (nothing newer arrived), the
  // modulator's target is its position extrapolated with its own velocity, x_hat_j + h T v_hat_j,
  // h = ticks since that packet was first used, T = period_s (the receiving half of the predictive
  // transmission deadband, rt/tx_deadband.hpp). Passivity is unaffected: the modulation keeps eq.
  // (14) whatever the target; eq. (18)'s proof does not cover extrapolated data (validate refuses).
  bool predict_held_state = false;
  // ... with each coordinate's extrapolation offset h T v_hat limited to this, m (the sender's
  // TxDeadbandConfig::prediction_limit_m(); +inf: unlimited).
  double predict_held_limit_m = std::numeric_limits<double>::infinity();
  // An edge whose data returns after an outage of at least return_ramp_after_s (or any edge after
  // arm_return_ramps(): a rejoin) couples to the neighbour's copy minus the offset between the two
  // copies at the return, taken off linearly over return_ramp_s (rt/return_ramp.hpp). 0: off, the
  // edge couples at once (the paper's law). Not with kSetPositionModulation (no edge is dropped).
  double return_ramp_s = 0;
  double return_ramp_after_s = 0.1;
  // An edge dropped because its data aged out (over the index-delay bound; not an isolated or gated
  // one: those drop at once) couples to the last state it used, frozen, with its stiffness faded
  // linearly to 0 over drop_fade_s (rt/drop_fade.hpp); back during the fade, it hands over to the
  // return ramp. 0: off, the edge drops at once (the paper's x_hat_j := x(k)). Not with
  // kSetPositionModulation (no edge is dropped).
  double drop_fade_s = 0;
  // Resilient consensus (rt/resilient.hpp): each tick the resilient_f neighbours whose received
  // configuration is farthest from this copy's are left out (eq. 18: the over-bound damper; pspm:
  // the modulator's target is this copy's own state). 0: off. With eq. 18 every neighbour's
  // energy_bound_J must be finite: a one-sided exclusion breaks eq. (18)'s pairing of the two
  // directions of an edge, and the per-edge energy bound is what covers it (rt/README.md).
  int resilient_f = 0;
  VirtualProxyParams vp{};
  std::vector<int> contact_nodes;     // the contact mesh C_i (node indices)
  StepSolverConfig solver{};          // the linear step's solver (auto: by scene size)
  Vec3 vp_initial_position_m = Vec3::Zero();
  double device_damping_Ns_per_m = 0.5;  // b_d of the device (eq. 26)
  bool device_force_feedback = true;     // false: position-input device (no force out): eq. (26) does not apply
  double max_device_force_N = 10.0;      // output limit (the station sets the device's own limit)
  double divergence_speed_m_per_s = 50;  // any node faster than this: diverged, safe state
  void validate() const;                 // throws std::invalid_argument naming the key
};

// The prefactored steps of a configuration, ascending: period_s + m * resolution inside
// [t_min, t_max], plus t_min and t_max (at most kMaxStepLevels). Start-up only.
inline constexpr int kMaxStepLevels = 33;
std::vector<double> step_levels(const StationConfig& config);

// Centroid and (unnormalized) normal, from the order of its first three nodes, of a contact mesh
// in configuration x. RT-safe.
struct ContactFace {
  Vec3 centroid;
  Vec3 normal;
};
ContactFace contact_face(const Eigen::VectorXd& x, const std::vector<int>& nodes);
// +1 or -1: the sign that turns face.normal outward (away from the scene mesh's centroid), as the
// core orients its contact normal. RT-safe.
double outward_normal_sign(const ContactFace& face, const Scene& scene);

// Status flags of one tick.
enum TickFlags : std::uint32_t {
  kTickOk = 0,
  kContactOnset = 1u << 0,
  kContactRelease = 1u << 1,
  kEdgeDropped = 1u << 2,      // a neighbour's packet exceeded its index-delay bound
  kForceClamped = 1u << 3,
  kDiverged = 1u << 4,         // state not finite or too fast: safe state entered
  kBadDeviceSample = 1u << 5,  // non-finite device position: safe state for this tick
  kSafeState = 1u << 6,
  kEdgeEnergyGated = 1u << 7,  // an edge's energy account is over its bound: it acts as the damper
  kResilientExcluded = 1u << 8,  // the resilient rule left a neighbour out (StationConfig::resilient_f)
  kEdgeIsolated = 1u << 9,       // a neighbour's reported states failed the state check: its edge acts as the damper
};

// The one definition of what each TickFlags bit means: its name (a word, as in a CSV column or an
// h5py script) and a sentence. The session log stores it with its flags (firmware/session/log.hpp,
// the `flag_bits` attribute) and `haptic-station log info` decodes with it.
struct TickFlagName {
  std::uint32_t bit;
  const char* name;
  const char* meaning;
};
inline constexpr TickFlagName kTickFlagNames[] = {
    {kContactOnset, "contact_onset", "the virtual proxy touched the scene this tick"},
    {kContactRelease, "contact_release", "the virtual proxy left the scene this tick"},
    {kEdgeDropped, "edge_dropped", "a neighbour's packet exceeded its index-delay bound: its edge was dropped"},
    {kForceClamped, "force_clamped", "the device force was clamped to max_device_force_N"},
    {kDiverged, "diverged", "the state was not finite or too fast: safe state entered"},
    {kBadDeviceSample, "bad_device_sample", "the device position was not finite: safe state for this tick"},
    {kSafeState, "safe_state", "the station is in its safe state"},
    {kEdgeEnergyGated, "edge_energy_gated", "an edge's energy account is over its bound: it acts as a damper"},
    {kResilientExcluded, "resilient_excluded", "the resilient consensus rule left out the neighbours farthest from this copy"},
    {kEdgeIsolated, "edge_isolated", "a neighbour's reported states failed the state check (rt/edge_monitor.hpp): its edge is isolated"},
};

// Cumulative energies (J) for the passivity monitor.
struct EnergyMonitor {
  double port_J = 0;        // sum_k v_hat^T f T: energy into the VO through the contact port (13)
  double controller_J = 0;  // sum_k v_hat^T tau T: energy from the consensus control port (14)
  double vo_J = 0;          // E_i(k) = 1/N (|v|_M^2/2 + |x-x_d|_K^2/2) at the start of the last tick
  double device_port_J = 0; // sum_k F_dev . (q_k - q_{k-1}): energy the station put into the device
  // -sum_k v_hat^T r T with r = b - A v_hat the VO rows' residual: energy an inexact (iterative)
  // solve put into the VO; exactly 0 for the direct solve. E(k) - E(0) = port + controller + this
  // (B = 0), so the passivity accounting stays exact.
  double solver_residual_J = 0;
};

class StationCore {
 public:
  explicit StationCore(const StationConfig& config);  // factorizes; throws on bad configuration
  StationCore(const StationCore&) = delete;
  StationCore& operator=(const StationCore&) = delete;
  StationCore(StationCore&&) = default;

  struct TickOutput {
    Vec3 device_force_N = Vec3::Zero();  // u_i(t), held over this tick
    std::uint32_t flags = kTickOk;
  };

  // Neighbour n's receive-side bookkeeping (feed it packets before calling tick()).
  RxLink& rx(int neighbor_index) { return rx_[static_cast<std::size_t>(neighbor_index)]; }
  const RxLink& rx(int neighbor_index) const { return rx_[static_cast<std::size_t>(neighbor_index)]; }
  int neighbor_count() const { return static_cast<int>(cfg_.neighbors.size()); }
  // Gain groups among the neighbours (equal gains are one group, whichever object holds them).
  int gain_groups() const { return static_cast<int>(group_leaders_.size()); }
  const NeighborConfig& neighbor(int n) const { return cfg_.neighbors[static_cast<std::size_t>(n)]; }

  // One step at cycle k (the caller's loop index, the same index its rx(n).offer sequence numbers
  // use: N_ij^k = k - seq) with the device position sampled at t_k, integrating over the nominal
  // step period_s. Cycles the caller skipped (overruns) are simply absent: k may jump. RT-safe.
  TickOutput tick(std::int64_t k, const Vec3& device_position_m) { return tick(k, device_position_m, cfg_.period_s); }
  // The same with this tick's step T_k = step_s (eq. 9, 21): clamped to [t_min, t_max] (counted in
  // step_clamped_ticks) and rounded to the nearest prefactored step (last_step_s()). RT-safe.
  TickOutput tick(std::int64_t k, const Vec3& device_position_m, double step_s);
  // The next cycle (sequence() + 1): for callers that never skip a cycle. RT-safe.
  TickOutput tick(const Vec3& device_position_m) { return tick(k_, device_position_m); }

  // State after the last tick.
  std::int64_t sequence() const { return k_ - 1; }  // k of the last tick (the x_hat/v_hat below)
  const double* x_hat() const { return x_hat_.data(); }
  const double* v_hat() const { return v_hat_.data(); }
  const Eigen::VectorXd& x() const { return x_; }
  const Eigen::VectorXd& v() const { return v_; }
  const Vec3& vp_position_m() const { return y_; }
  const Vec3& contact_force_on_vp_N() const { return f_contact_vp_; }
  bool in_contact() const { return in_contact_; }
  const EnergyMonitor& energy() const { return energy_; }
  // eq. (14)'s controller energy split per edge (neighbour index n = edge n); sums to
  // energy().controller_J.
  const EdgeEnergyAccount& edge_energy() const { return edge_energy_; }
  // The per-edge damage bound on those accounts: trips, gated ticks, latch state per edge.
  const EdgeEnergyGate& edge_gate() const { return edge_gate_; }
  // The neighbour state check (rt/edge_monitor.hpp): isolations, re-admissions, reasons per edge.
  const EdgeMonitor& edge_monitor() const { return edge_monitor_; }
  const StationConfig& config() const { return cfg_; }
  std::uint64_t edge_drop_events() const {
    std::uint64_t total = 0;
    for (auto d : edge_drops_) total += d;
    return total;
  }
  std::uint64_t edge_drop_events(int n) const { return edge_drops_[static_cast<std::size_t>(n)]; }
  // Ticks the resilient rule left neighbour n out (StationConfig::resilient_f).
  std::uint64_t resilient_excluded_ticks(int n) const { return resilient_excluded_[static_cast<std::size_t>(n)]; }
  // Set-position modulation of edge n (consensus_passivity = pspm; nullptr otherwise).
  const SetPositionModulator* set_position_modulator(int n) const {
    return pspm_.empty() ? nullptr : &pspm_[static_cast<std::size_t>(n)];
  }
  std::uint64_t safe_state_ticks() const { return safe_state_ticks_; }
  double last_step_s() const { return T_; }  // T_k of the last tick (a prefactored step)
  std::uint64_t step_clamped_ticks() const { return step_clamped_ticks_; }  // requested steps outside [t_min, t_max]
  int step_level_count() const { return static_cast<int>(steps_.size()); }
  const char* solver_name() const { return steps_[0].solver->name(); }
  long solver_stored_doubles() const {
    long total = 0;
    for (const auto& l : steps_) total += l.solver->stored_doubles();
    return total;
  }
  // Bytes of the arrays one tick at the nominal step reads or writes, each counted once: this
  // level's solver data (A, its diagonals, work vectors), the right-hand side's operator, the state
  // and scratch vectors the tick uses, the contact data Z, each neighbour's receive buffers (held
  // and landing). What BM_TickFloor streams (tools/bench). Not RT-relevant.
  long tick_bytes() const;
  int solver_last_iterations() const { return solver_last_iterations_; }
  // Iterations of the linear step's solver per tick over the ticks so far (0 for the direct solve).
  double solver_iterations_mean() const {
    return solver_ticks_ > 0 ? static_cast<double>(solver_iterations_total_) / static_cast<double>(solver_ticks_) : 0.0;
  }
  std::uint64_t solver_unconverged_ticks() const { return solver_unconverged_ticks_; }
  // Start-up / tests: overwrite the state (allocates nothing; sizes must match).
  void set_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v);
  // A rejoined station (its state adopted from a neighbour): each edge's first data ramps in
  // (StationConfig::return_ramp_s; nothing when that is 0). RT-safe.
  void arm_return_ramps() { return_ramp_.arm_all(); }
  // The edges' return ramps (started, running, offsets).
  const ReturnRamp& return_ramp() const { return return_ramp_; }
  // The edges' drop fades (StationConfig::drop_fade_s: started, running).
  const DropFade& drop_fade() const { return drop_fade_; }
  // What edge n coupled to on the last tick (its data, a ramp's or a fade's target), or nullptr when
  // it acted as the damper (x_hat_n := x(k)); valid until the next tick.
  const double* coupled_state(int n) const {
    return active_[static_cast<std::size_t>(n)] ? views_[static_cast<std::size_t>(n)].x_hat : nullptr;
  }
  // Tests: false runs the baseline build of the station's own lane kernels (post-solve, warm start,
  // contact correction); returns whether AVX is used.
  bool use_avx(bool allow) { return avx_kernels_ = allow && cpu_has_avx(); }

 private:
  using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3 * kMaxContactNodes + 3, 3 * kMaxContactNodes + 3>;
  using SmallRhs = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3 * kMaxContactNodes + 3, 3>;
  // Everything of the step that depends on T: A(T)'s solver, the contact Schur data Z = A^{-1} U
  // and the LU of the bordered system, the VP diagonal a_w(T). One per prefactored step.
  struct StepLevel {
    double T = 0;
    std::unique_ptr<StepSolver> solver;
    Eigen::MatrixXd Z;  // nf x m: A^{-1} e_unit
    Eigen::PartialPivLU<Small> lu;
    double a_w = 0;     // VP diagonal without contact
    // P_0 v_hat without a matvec (iterative solver, one gain group, P_0's off-diagonal rho x A's,
    // D_0 diagonal): P_0 v_hat = alpha v_hat + rho A v_hat with alpha_i = (P_0)_ii - rho A_ii and
    // A v_hat = b - r + U coef (Z = A^{-1} U). Empty alpha: the [D, P] operator pass.
    double rho = 0;
    std::vector<double> alpha;  // per node
  };
  void init_edges();  // start-up: receive links, views, drop counters, pspm, energy accounts and gates
  void build_level(StepLevel& level, double T, bool iso);  // start-up: A(T)'s solver, contact data
  void prepare_contact_solve(StepLevel& level);  // start-up: Z, G and its LU
  void p_from_a(StepLevel& level, const SparseRowMajor& A);  // start-up: StepLevel::rho, alpha if they apply
  void engage_contact();
  bool first_of_gain(int j) const;  // first neighbour using this gain object
  // Step 4 without contact: b and energy_.vo_J in one fused pass for the first gain group (+ two
  // matvecs per further group). RT-safe.
  void build_rhs();
  // The iterative solver's initial guess in y0_: g = 2 y0(k-1) - y0(k-2), the linear extrapolation
  // of the last two solutions of A y0 = b (y0(k-1) until two exist), then, when both were solved
  // with this tick's A and the solver keeps A's diagonal D, one Jacobi step g += D^{-1}(b - A g)
  // with A g = 2 (b(k-1) - r(k-1)) - (b(k-2) - r(k-2)) from the kept right-hand sides and
  // residuals (no matvec). RT-safe: one pass, no allocation.
  void warm_start_y0();
  // The steps of tick(), in order (each RT-safe):
  // 0. this tick's step T_k: the request clamped to [T^min, T^max] (counted), the nearest level.
  void select_step(double step_s);
  // 1. the device sample qk (the previous one if not finite: flags), its velocity vq over T_{k-1}
  // and the virtual coupling's force u_i(t) (Section III-C), limited; the device port's energy.
  Vec3 device_force(const Vec3& q, Vec3& qk, Vec3& vq, std::uint32_t& flags);
  // 2. each neighbour's newest packet (views_), the resilient rule (excluded_), the delay and energy
  // bounds (active_), pspm targets.
  void read_neighbours(std::int64_t k, std::uint32_t& flags);
  // The resilient rule on this tick's views: excluded_[j] for the resilient_f candidates farthest
  // from x(k) (eq. 18: within their delay bound; pspm: any packet), counted; flags. RT-safe.
  void exclude_resilient(std::uint32_t& flags);
  // 2'. whether edge j is excluded this tick by a check of its reported states (the state check,
  // rt/edge_monitor.hpp, fed with its packet when within the delay bound). RT-safe.
  bool edge_excluded(int j, std::int64_t k, bool within_bound);
  // 2''. what edge j couples to this tick: its data or the return ramp's target; over the bound only
  // (not `distrusted`: gated or isolated) and used on the last tick, the drop's fading target (then
  // active_[j] = 1 and no neighbour velocity). RT-safe.
  const double* edge_target(int j, std::int64_t k, bool ok, bool distrusted, bool was_active);
  // 3. contact onset / release, decided from the state at the start of the tick.
  void update_contact_set(std::uint32_t& flags);
  // 4. b (rhs_) and the VP row's right-hand side (returned), contact springs included.
  Vec3 build_step_rhs(const Vec3& qk, const Vec3& vq);
  // 5. A y0 = b (direct: into v_hat_; iterative: warm-started y0_, the kept b, r rotated), then
  // the contact/VP Schur complement: v_hat_ corrected, the VP's w_hat returned.
  void solve_vo();
  Vec3 solve_contact(const Vec3& bw, double c);
  // 6. x_hat, the port (13) and controller (14) energies, per edge; the state advance of step 7
  // (fused for one gain group). Returns max |v| after the advance (NaN: not finite).
  double account_energies(const Vec3& w_hat);
  double contact_port_power(const Vec3& w_hat);  // v_hat^T f on the contact nodes; sets f_contact_vp_
  void further_groups_energy(double& ctrl_J);    // gain groups after the first: matvecs, per edge
  // Iterative solver in contact: v_hat = y0 + Z coef from the Schur solution X_ (Z = A^{-1} U of
  // this tick's step) in one pass over the rows, instead of the copy and one column pass per unit
  // and column. RT-safe.
  void contact_correction(const double* y0, double c);
  // pspm: the set-position target of edge j at tick k: the held packet's x_hat_j, extrapolated by its
  // v_hat_j over the ticks it has been held when predict_held_state (views_[j] from begin_tick). RT-safe.
  const double* modulation_target(int j, std::int64_t k);
  // pspm: the edges read_neighbours prepared this tick (pspm_prepared_) take their forms and move
  // their set-positions, a gain group's in one pass over its P. RT-safe.
  void modulate_prepared_edges();
  // Gain group g's (neighbours sharing cfg_.neighbors[g].gains) active neighbours' x_hat (na) and
  // fresh ones' v_hat (nf), in neighbour order.
  void group_inputs(int g, const double** xs, int& na, const double** vs, int& nf) const;
  // Sums of gain group g: sx = sum_active (x - x_hat_j), sv = sum_{active, fresh} v_hat_j, and (if d)
  // d = x - x_d, in one pass. RT-safe.
  void sum_group(int g, double* sx, double* sv, double* d) const;
  // Steps 6 and 7 of the first gain group: D_0 v_hat and P_0 v_hat in one operator pass, then ONE
  // pass over the dofs for x_hat = x + T/2 v_hat, |v_hat|^2 and the residual's energy
  // (solver_residual_J), each of the group's edges' coupling energy (edge_tick_J_) and (advance)
  // x += T v_hat, v = 2 v_hat - v. RT-safe.
  struct PostSolveSums {
    double vv = 0;            // |v_hat|^2
    double dissipated_J = 0;  // T v_hat^T D_0 v_hat
    double vmax = 0;          // max |v| after the advance (NaN if x or v not finite; advance only)
  };
  PostSolveSums post_solve_pass(bool advance);
  // Step 7 for the VO: x += T v_hat, v = 2 v_hat - v; returns max |v| (NaN if x or v not finite). RT-safe.
  double advance_state();

  StationConfig cfg_;
  const Scene& scene_;
  double T_;            // T_k of the current (last) tick
  double T_prev_;       // T_{k-1}: the interval of the device sample difference (Section III-C)
  int n_;        // nodes
  int dofs_;     // 3n
  int w_;        // 3 when the system is isotropic (factor n x n, 3 RHS), else 1 (factor 3n x 3n)
  int nf_;       // factor dimension
  std::vector<StepLevel> steps_;  // prefactored steps, ascending T (A constant at any neighbour state)
  StepLevel* step_ = nullptr;     // this tick's
  std::uint64_t step_clamped_ticks_ = 0;
  int solver_last_iterations_ = 0;
  std::uint64_t solver_iterations_total_ = 0, solver_ticks_ = 0;
  std::uint64_t solver_unconverged_ticks_ = 0;
  std::vector<RxLink> rx_;

  // State
  Eigen::VectorXd x_, v_, x_hat_, v_hat_;
  Vec3 y_ = Vec3::Zero(), w_vp_ = Vec3::Zero(), w_hat_prev_ = Vec3::Zero();
  Vec3 q_prev_ = Vec3::Zero();
  Vec3 f_dev_prev_ = Vec3::Zero();
  Vec3 f_contact_vp_ = Vec3::Zero();
  std::int64_t k_ = 0;   // cycle after the last tick (sequence() + 1)
  bool stepped_ = false; // a tick has run (q_prev_ is a real sample)
  bool in_contact_ = false;
  bool safe_state_ = false;
  std::vector<Vec3> anchor_;  // r_p: contact node offset from the VP at onset
  double normal_sign_ = 1.0;
  EnergyMonitor energy_{};
  EdgeEnergyAccount edge_energy_{};
  double prev_ctrl_J_ = 0, prev_vo_J_ = 0, prev_T_ = 0;  // the last tick's controller energy and E at its start (the leak)
  bool have_prev_energy_ = false;
  EdgeEnergyGate edge_gate_{};
  ReturnRamp return_ramp_{};
  DropFade drop_fade_{};
  EdgeMonitor edge_monitor_{};
  std::array<double, kMaxNeighbors> edge_tick_J_{};  // this tick's coupling energy per edge
  std::uint64_t safe_state_ticks_ = 0;
  std::vector<SetPositionModulator> pspm_;  // one per edge when consensus_passivity = pspm
  Eigen::VectorXd pspm_scratch_;                // each edge's d and r (2 x dofs per edge)
  std::array<unsigned char, kMaxNeighbors> pspm_prepared_{};  // edges prepared this tick
  Eigen::VectorXd predicted_;               // predict_held_state: the extrapolated target (dofs)
  std::vector<std::int64_t> held_since_;    // predict_held_state: tick each held packet was first used
  std::vector<unsigned char> edge_was_dropped_;
  std::vector<std::uint64_t> edge_drops_;
  std::array<unsigned char, kMaxNeighbors> excluded_{};  // the resilient rule's verdict this tick
  std::vector<std::uint64_t> resilient_excluded_;

  // The right-hand side's matrices [M, K, P_0, D_0] (P_0, D_0: the first gain group's) in one
  // fused pass, and [D_0, P_0] for D v_hat and P v_hat of the controller energy (rt/README.md).
  MultiTermOperator rhs_op_, dp_op_;
  std::vector<int> group_leaders_;  // first neighbour of each gain group, in order

  // Scratch (sized at start-up)
  Eigen::VectorXd rhs_, tmp_, tmp2_, scratch_, resid_;
  // The VO solve's solutions y0 = A^{-1} b of the last two ticks (before the contact correction):
  // the iterative solver's warm start is their linear extrapolation (rt/README.md).
  Eigen::VectorXd y0_, y0_prev_;
  int y0_solves_ = 0;
  // ... and for the Jacobi step: b(k-1), b(k-2) (rhs_ is b(k)), r(k-2) (resid_ is r(k-1) until the
  // solve), the step level each of y0(k-1), y0(k-2) was solved with. Rotated by swaps.
  Eigen::VectorXd rhs_prev_, rhs_prev2_, resid_prev_;
  const StepLevel* y0_level_[2] = {nullptr, nullptr};
  std::uint32_t y0_active_[2] = {0, 0};  // the active-neighbour masks of the last two solves
  std::vector<RxLink::TickView> views_;
  std::vector<unsigned char> active_;

  // Contact Schur data (per step level above; the contact mesh is fixed per station).
  int m_units_ = 0, vp_units_ = 0;
  std::vector<int> unit_row_;     // factor row of contact unit a
  std::vector<int> unit_vp_;      // VP unit that contact unit a couples to
  SmallRhs R_, X_;
  // This tick's contact coefficients (v_hat = y0 + Z coef, iterative path) and D_0's diagonal (per
  // node) for P_0 v_hat from A (StepLevel::alpha).
  double contact_coef_[3 * kMaxContactNodes][3] = {};
  bool contact_coef_set_ = false;
  std::vector<double> d0_diag_;
  bool avx_kernels_ = cpu_has_avx();  // the AVX build of the post-solve, warm-start and contact passes (same bits)
};

}  // namespace haptic::rt
