#include "rt/station.hpp"

#include "rt/cpu_avx.hpp"
#include "rt/lanes.hpp"
#include "rt/resilient.hpp"
#include "rt/tx_deadband.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace haptic::rt {

namespace {
[[noreturn]] void bad(const std::string& key, const std::string& range) {
  throw std::invalid_argument("station." + key + " must be " + range);
}
SpatialMatrix combine(const std::vector<std::pair<double, const SpatialMatrix*>>& terms) {
  SpatialMatrix acc = linear_combination({terms[0]});
  for (std::size_t i = 1; i < terms.size(); ++i) acc = linear_combination({{1.0, &acc}, terms[i]});
  return acc;
}
}  // namespace

ContactFace contact_face(const Eigen::VectorXd& x, const std::vector<int>& nodes) {
  ContactFace f{Vec3::Zero(), Vec3::Zero()};
  for (int p : nodes) f.centroid += x.segment<3>(3 * p);
  f.centroid /= static_cast<double>(nodes.size());
  const Vec3 p0 = x.segment<3>(3 * nodes[0]);
  f.normal = (x.segment<3>(3 * nodes[1]) - p0).cross(x.segment<3>(3 * nodes[2]) - p0);
  return f;
}

double outward_normal_sign(const ContactFace& face, const Scene& scene) {
  return face.normal.dot(face.centroid - scene.mesh.centroid()) >= 0 ? 1.0 : -1.0;
}

void StationConfig::validate() const {
  if (!scene) bad("scene", "set");
  if (users < 1) bad("users", ">= 1");
  if (!(period_s > 0 && period_s < 1)) bad("period_s", "in (0, 1)");
  if (!(period_min_s >= 0 && t_min() <= period_s)) bad("period_min_s", "in (0, period_s] (0: period_s)");
  if (!(period_max_s >= 0 && t_max() >= period_s && t_max() < 1)) bad("period_max_s", "in [period_s, 1) (0: period_s)");
  if (!(step_resolution_s >= 0 && std::isfinite(step_resolution_s))) bad("step_resolution_s", ">= 0");
  if (t_max() > t_min() && step_levels(*this).size() > static_cast<std::size_t>(kMaxStepLevels))
    bad("step_resolution_s", "coarse enough for at most " + std::to_string(kMaxStepLevels) + " steps between period_min_s and period_max_s");
  if (!(damping_Ns_per_m >= 0 && std::isfinite(damping_Ns_per_m))) bad("damping_Ns_per_m", ">= 0");
  if (!(pspm_reservoir0_J >= 0 && std::isfinite(pspm_reservoir0_J))) bad("pspm_reservoir0_J", "finite and >= 0");
  if (!(predict_held_limit_m >= 0)) bad("predict_held_limit_m", ">= 0 (+inf: unlimited)");
  if (predict_held_state && consensus_passivity != ConsensusPassivity::kSetPositionModulation)
    bad("predict_held_state", "used only with consensus_passivity = pspm (eq. 18 does not cover extrapolated data)");
  if (!(return_ramp_s >= 0 && std::isfinite(return_ramp_s))) bad("return_ramp_s", "finite and >= 0 (0: off)");
  if (!(return_ramp_after_s >= 0 && std::isfinite(return_ramp_after_s))) bad("return_ramp_after_s", "finite and >= 0");
  if (!(drop_fade_s >= 0 && std::isfinite(drop_fade_s))) bad("drop_fade_s", "finite and >= 0 (0: the immediate drop)");
  state_check.validate();
  if (state_check.enabled() && consensus_passivity == ConsensusPassivity::kSetPositionModulation)
    bad("state_check", "not used with consensus_passivity = pspm (its edges are never dropped)");
  if (static_cast<int>(neighbors.size()) > kMaxNeighbors) bad("neighbors", "at most " + std::to_string(kMaxNeighbors));
  if (resilient_f < 0 || resilient_f > kMaxNeighbors) bad("resilient_f", "in [0, " + std::to_string(kMaxNeighbors) + "] (0: off)");
  if (resilient_f > 0 && consensus_passivity == ConsensusPassivity::kEq18Damping)
    for (const auto& n : neighbors)
      if (!std::isfinite(n.energy_bound_J))
        bad("resilient_f", "0 unless every neighbour's energy_bound_J is finite (eq. 18: the energy bound covers a one-sided exclusion)");
  for (const auto& n : neighbors) {
    if (!n.gains) bad("neighbors[].gains", "set");
    if (n.gains->P.dofs() != scene->dofs) bad("neighbors[].gains", "sized like the scene");
    if (n.index_delay_bound_ticks < 0) bad("neighbors[].index_delay_bound_ticks", ">= 0");
    if (!(n.damping_share >= 0 && std::isfinite(n.damping_share))) bad("neighbors[].damping_share", "finite and >= 0");
    if (!(n.energy_bound_J > 0)) bad("neighbors[].energy_bound_J", "> 0 (+inf: off)");
    if (!(n.energy_hold_s >= 0 && n.energy_hold_s <= 3600)) bad("neighbors[].energy_hold_s", "in [0, 3600] s (0: no timed release)");
    if (!(n.energy_leak_W >= 0 && std::isfinite(n.energy_leak_W))) bad("neighbors[].energy_leak_W", ">= 0 and finite");
    if (std::isfinite(n.energy_bound_J) && !(std::isfinite(n.energy_release_J) && n.energy_release_J < n.energy_bound_J))
      bad("neighbors[].energy_release_J", "finite and below energy_bound_J");
  }
  if (!(vp.mass_kg > 0)) bad("vp.mass_kg", "> 0");
  if (!(vp.contact_damping_Ns_per_m >= 0)) bad("vp.contact_damping_Ns_per_m", ">= 0");
  if (!(vp.contact_stiffness_N_per_m >= 0)) bad("vp.contact_stiffness_N_per_m", ">= 0");
  if (!(vp.contact_damping_Ns_per_m + vp.contact_stiffness_N_per_m > 0)) bad("vp.contact_stiffness_N_per_m", "> 0 when b_c = 0");
  if (contact_nodes.size() < 3 || contact_nodes.size() > static_cast<std::size_t>(kMaxContactNodes))
    bad("contact_nodes", "3 to 8 node indices (the contact mesh)");
  for (int p : contact_nodes)
    if (p < 0 || p >= scene->nodes) bad("contact_nodes[]", "valid node indices");
  if (!(max_device_force_N > 0)) bad("max_device_force_N", "> 0");
  if (!vp_initial_position_m.allFinite()) bad("vp_initial_position_m", "finite");
  // eq. (26) at the worst step: T_k = T^max, T_k / T_{k-1} = T^max / T^min
  if (device_force_feedback) check_eq26(vp.coupling, device_damping_Ns_per_m, t_max(), t_max() / t_min());
  solver.validate();
}

std::vector<double> step_levels(const StationConfig& c) {
  const double T = c.period_s, lo = c.t_min(), hi = c.t_max();
  std::vector<double> levels = {lo};
  if (hi > lo) {
    const double h = c.step_resolution_s > 0 ? c.step_resolution_s : (hi - lo) / 8.0;
    const double tol = 1e-9 * T;
    for (double m = std::ceil((lo - T) / h); T + m * h < hi - tol; m += 1.0)
      if (T + m * h > lo + tol) levels.push_back(T + m * h);
    levels.push_back(hi);
  }
  return levels;
}

StationCore::StationCore(const StationConfig& config)
    : cfg_(config), scene_((config.validate(), *config.scene)), T_(config.period_s), T_prev_(config.period_s) {
  n_ = scene_.nodes;
  dofs_ = scene_.dofs;
  const int nn = neighbor_count();
  // Neighbours whose gains are equal but held in separate objects (the scenario builder keeps one
  // copy per edge) share the first one: one gain group, its sums in the fused passes, instead of
  // two matvecs a tick for each further copy (and two more for the energy).
  for (int j = 1; j < nn; ++j)
    for (int i = 0; i < j; ++i)
      if (same_gains(*cfg_.neighbors[static_cast<std::size_t>(i)].gains, *cfg_.neighbors[static_cast<std::size_t>(j)].gains)) {
        cfg_.neighbors[static_cast<std::size_t>(j)].gains = cfg_.neighbors[static_cast<std::size_t>(i)].gains;
        break;
      }
  bool iso = scene_.M.is_isotropic() && scene_.B.is_isotropic() && scene_.K.is_isotropic();
  for (const auto& nb : cfg_.neighbors) iso = iso && nb.gains->P.is_isotropic() && nb.gains->D.is_isotropic();
  w_ = iso ? 3 : 1;
  nf_ = iso ? n_ : dofs_;
  {
    std::vector<const SpatialMatrix*> rhs_terms = {&scene_.M, &scene_.K};
    if (nn > 0) {
      const EdgeGains* g0 = cfg_.neighbors[0].gains;
      rhs_terms.push_back(&g0->P);
      rhs_terms.push_back(&g0->D);
      dp_op_ = MultiTermOperator({&g0->D, &g0->P});
    }
    rhs_op_ = MultiTermOperator(rhs_terms);
    for (int j = 0; j < nn; ++j)
      if (first_of_gain(j)) group_leaders_.push_back(j);
  }
  x_ = scene_.x_d;
  v_ = Eigen::VectorXd::Zero(dofs_);
  x_hat_ = x_;
  v_hat_ = v_;
  rhs_.resize(dofs_);
  tmp_.resize(dofs_);
  tmp2_.resize(dofs_);
  scratch_.resize(dofs_);
  resid_ = Eigen::VectorXd::Zero(dofs_);
  y0_ = Eigen::VectorXd::Zero(dofs_);
  y0_prev_ = Eigen::VectorXd::Zero(dofs_);
  rhs_prev_ = Eigen::VectorXd::Zero(dofs_);
  rhs_prev2_ = Eigen::VectorXd::Zero(dofs_);
  resid_prev_ = Eigen::VectorXd::Zero(dofs_);
  init_edges();
  y_ = cfg_.vp_initial_position_m;
  q_prev_ = y_;
  anchor_.assign(cfg_.contact_nodes.size(), Vec3::Zero());
  // Contact units: isotropic -> one unit per node (3 columns); else three units per node.
  const int C = static_cast<int>(cfg_.contact_nodes.size());
  vp_units_ = iso ? 1 : 3;
  m_units_ = iso ? C : 3 * C;
  for (int a = 0; a < C; ++a) {
    const int p = cfg_.contact_nodes[static_cast<std::size_t>(a)];
    if (iso) {
      unit_row_.push_back(p);
      unit_vp_.push_back(0);
    } else {
      for (int d = 0; d < 3; ++d) {
        unit_row_.push_back(3 * p + d);
        unit_vp_.push_back(d);
      }
    }
  }
  R_.resize(m_units_ + vp_units_, w_);
  X_.resize(m_units_ + vp_units_, w_);
  // Orientation of the contact face normal: outward at rest.
  const ContactFace rest = contact_face(x_, cfg_.contact_nodes);
  normal_sign_ = outward_normal_sign(rest, scene_);
  const std::vector<double> levels = step_levels(cfg_);
  steps_.resize(levels.size());
  for (std::size_t l = 0; l < levels.size(); ++l) build_level(steps_[l], levels[l], iso);
  step_ = &steps_[0];
  for (auto& l : steps_)
    if (std::abs(l.T - cfg_.period_s) < std::abs(step_->T - cfg_.period_s)) step_ = &l;
}

void StationCore::init_edges() {
  const int nn = neighbor_count();
  rx_.resize(static_cast<std::size_t>(nn));
  for (auto& r : rx_) r.init(dofs_, x_.data(), v_.data(), -1, cfg_.rx_rule);
  views_.resize(static_cast<std::size_t>(nn));
  active_.assign(static_cast<std::size_t>(nn), 0);
  edge_was_dropped_.assign(static_cast<std::size_t>(nn), 0);
  edge_drops_.assign(static_cast<std::size_t>(nn), 0);
  resilient_excluded_.assign(static_cast<std::size_t>(nn), 0);
  if (cfg_.consensus_passivity == ConsensusPassivity::kSetPositionModulation) {
    pspm_.resize(static_cast<std::size_t>(nn));
    for (auto& m : pspm_) m.init(dofs_, x_.data(), cfg_.pspm_reservoir0_J);
    pspm_scratch_ = Eigen::VectorXd::Zero(2 * dofs_ * nn);  // each edge's d and r (SetPositionModulator::prepare)
    if (cfg_.predict_held_state) {
      predicted_ = Eigen::VectorXd::Zero(dofs_);
      held_since_.assign(static_cast<std::size_t>(nn), 0);
    }
  }
  {
    std::vector<double> shares;
    for (const auto& nb : cfg_.neighbors) shares.push_back(nb.damping_share);
    edge_energy_.init(nn, shares);
    std::vector<double> bounds, releases, leaks;
    std::vector<std::int64_t> holds;
    for (const auto& nb : cfg_.neighbors) {
      bounds.push_back(nb.energy_bound_J);
      releases.push_back(nb.energy_release_J);
      leaks.push_back(nb.energy_leak_W);
      holds.push_back(static_cast<std::int64_t>(std::llround(nb.energy_hold_s / cfg_.period_s)));
    }
    edge_gate_.init(nn, bounds, releases, holds);
    edge_energy_.set_leak(leaks);
  }
  const bool ramps = cfg_.return_ramp_s > 0 && pspm_.empty();
  return_ramp_.init(nn, dofs_, ramps ? std::llround(cfg_.return_ramp_s / cfg_.period_s) : 0,
                    std::llround(cfg_.return_ramp_after_s / cfg_.period_s));
  drop_fade_.init(nn, dofs_, pspm_.empty() ? std::llround(cfg_.drop_fade_s / cfg_.period_s) : 0);
  const Eigen::VectorXd x_hat0 = x_;  // every copy starts here, at rest
  const Eigen::VectorXd v0 = Eigen::VectorXd::Zero(dofs_);
  std::vector<StepBox> steps;
  for (const auto& nb : cfg_.neighbors) steps.push_back({nb.step_min_s, nb.step_max_s});
  edge_monitor_.init(nn, dofs_, cfg_.period_s, cfg_.state_check, x_hat0.data(), v0.data(), steps);
}

long StationCore::tick_bytes() const {
  const StepLevel& level = *step_;
  long doubles = level.solver->stored_doubles() + rhs_op_.stored_doubles();
  const bool iterative = !level.solver->exact();
  if (!iterative || level.alpha.empty()) doubles += dp_op_.stored_doubles() + tmp_.size() + tmp2_.size();  // the [D, P] pass
  const Eigen::VectorXd* used[] = {&x_, &v_, &x_hat_, &v_hat_, &rhs_, &resid_};
  for (const auto* vec : used) doubles += vec->size();
  if (iterative) {
    const Eigen::VectorXd* kept[] = {&y0_, &y0_prev_, &rhs_prev_, &rhs_prev2_, &resid_prev_};
    for (const auto* vec : kept) doubles += vec->size();
    doubles += static_cast<long>(level.alpha.size() + d0_diag_.size());
  }
  doubles += level.Z.size();
  doubles += 4L * dofs_ * neighbor_count();  // x_hat_j, v_hat_j held and landing
  return 8 * doubles;
}

void StationCore::build_level(StepLevel& level, double T, bool iso) {
  level.T = T;
  const double N = cfg_.users;
  // A(T) = (1/N)(2M/T + B + T/2 K) + B_i + sum_j (D_ij + T/2 P_ij) over every configured edge (an
  // over-bound edge acts as a damper, rt/README.md).
  const SpatialMatrix I = SpatialMatrix::identity(n_);
  std::vector<std::pair<double, const SpatialMatrix*>> terms = {
      {2.0 / (N * T), &scene_.M}, {1.0 / N, &scene_.B}, {T / (2.0 * N), &scene_.K}, {cfg_.damping_Ns_per_m, &I}};
  for (const auto& nb : cfg_.neighbors) {
    terms.emplace_back(1.0, &nb.gains->D);
    terms.emplace_back(T / 2.0, &nb.gains->P);
  }
  const SpatialMatrix A = combine(terms);
  level.solver = make_step_solver(cfg_.solver, iso ? SparseColMajor(A.S) : SparseColMajor(A.as_full()), w_);
  if (iso && !level.solver->exact() && group_leaders_.size() == 1) p_from_a(level, A.S);
  const auto& g = cfg_.vp.coupling;
  level.a_w = 2.0 * cfg_.vp.mass_kg / T + g.b_v_Ns_per_m + g.B_vc_Ns_per_m + g.K_vc_N_per_m * T / 2.0;
  prepare_contact_solve(level);
}

void StationCore::p_from_a(StepLevel& level, const SparseRowMajor& A) {
  // Start-up. P_0 v_hat = alpha v_hat + rho A v_hat needs P_0's off-diagonal entries to be rho x A's
  // on A's pattern (to 1e-14 each; the paper's P = p[I/2 + K_int/(2 lambda_max)] and A's
  // off-diagonal T/(2N) K_int + sum_j T/2 P_j are both multiples of K_int's) and D_0 diagonal.
  const EdgeGains* g0 = cfg_.neighbors[0].gains;
  const SparseRowMajor& P = g0->P.S;
  const SparseRowMajor& D = g0->D.S;
  std::vector<double> pdiag(static_cast<std::size_t>(n_), 0.0), adiag(static_cast<std::size_t>(n_), 0.0);
  std::vector<double> ddiag(static_cast<std::size_t>(n_), 0.0);
  double rho = 0;
  for (int pass = 0; pass < 2; ++pass)  // pass 0: rho from the first entry; pass 1: check every entry
    for (int i = 0; i < n_; ++i) {
      for (SparseRowMajor::InnerIterator it(D, i); it; ++it) {
        if (it.col() != i && it.value() != 0.0) return;  // D_0 not diagonal
        if (pass == 1) ddiag[static_cast<std::size_t>(i)] += it.value();
      }
      SparseRowMajor::InnerIterator ia(A, i), ip(P, i);
      for (; ia; ++ia) {
        double pv = 0;
        while (ip && ip.col() < ia.col()) {
          if (ip.value() != 0.0) return;  // an entry of P_0 outside A's pattern
          ++ip;
        }
        if (ip && ip.col() == ia.col()) {
          pv = ip.value();
          ++ip;
        }
        if (ia.col() == i) {
          pdiag[static_cast<std::size_t>(i)] = pv;
          adiag[static_cast<std::size_t>(i)] = ia.value();
        } else if (pass == 0) {
          if (rho == 0 && ia.value() != 0.0) rho = pv / ia.value();
        } else if (!(std::abs(pv - rho * ia.value()) <= 1e-14 * std::abs(pv))) {
          return;
        }
      }
      for (; ip; ++ip)
        if (ip.value() != 0.0) return;
    }
  level.rho = rho;
  level.alpha.resize(static_cast<std::size_t>(n_));
  for (int i = 0; i < n_; ++i)
    level.alpha[static_cast<std::size_t>(i)] = pdiag[static_cast<std::size_t>(i)] - rho * adiag[static_cast<std::size_t>(i)];
  d0_diag_ = ddiag;
}

bool StationCore::first_of_gain(int j) const {
  for (int i = 0; i < j; ++i)
    if (cfg_.neighbors[static_cast<std::size_t>(i)].gains == cfg_.neighbors[static_cast<std::size_t>(j)].gains) return false;
  return true;
}

void StationCore::set_state(const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  if (x.size() != dofs_ || v.size() != dofs_) throw std::invalid_argument("set_state: size mismatch");
  x_ = x;
  v_ = v;
  for (auto& m : pspm_) m.reset(x_.data());  // the adopted copy's springs start relaxed
}

void StationCore::engage_contact() {
  for (std::size_t a = 0; a < cfg_.contact_nodes.size(); ++a)
    anchor_[a] = x_.segment<3>(3 * cfg_.contact_nodes[a]) - y_;
  in_contact_ = true;
}

void StationCore::prepare_contact_solve(StepLevel& level) {
  const double c = cfg_.vp.contact_damping_Ns_per_m + cfg_.vp.contact_stiffness_N_per_m * level.T / 2.0;
  Eigen::MatrixXd& Z = level.Z;
  Z = Eigen::MatrixXd::Zero(nf_, m_units_);
  Eigen::VectorXd unit = Eigen::VectorXd::Zero(nf_);
  for (int a = 0; a < m_units_; ++a) {
    unit[unit_row_[static_cast<std::size_t>(a)]] = 1.0;
    level.solver->solve_accurately(unit.data(), Z.col(a).data(), 1);
    unit[unit_row_[static_cast<std::size_t>(a)]] = 0.0;
  }
  const int m = m_units_;
  Small G = Small::Zero(m + vp_units_, m + vp_units_);
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) {
      const double W = Z(unit_row_[static_cast<std::size_t>(a)], b);
      G(a, b) = (a == b ? 1.0 : 0.0) + c * W;
      G(a, m + unit_vp_[static_cast<std::size_t>(b)]) -= c * W;
    }
    G(m + unit_vp_[static_cast<std::size_t>(a)], a) = -c;
  }
  const int per_vp = m / vp_units_;
  for (int e = 0; e < vp_units_; ++e) G(m + e, m + e) = level.a_w + c * per_vp;
  level.lu.compute(G);
}

void StationCore::group_inputs(int g, const double** xs, int& na, const double** vs, int& nf) const {
  const EdgeGains* eg = cfg_.neighbors[static_cast<std::size_t>(g)].gains;
  na = 0;
  nf = 0;
  for (int j = g; j < neighbor_count(); ++j) {
    if (!active_[static_cast<std::size_t>(j)] || cfg_.neighbors[static_cast<std::size_t>(j)].gains != eg) continue;
    xs[na++] = views_[static_cast<std::size_t>(j)].x_hat;
    if (views_[static_cast<std::size_t>(j)].fresh) vs[nf++] = views_[static_cast<std::size_t>(j)].v_hat;
  }
}

void StationCore::sum_group(int g, double* sx, double* sv, double* d) const {
  const double* xs[kMaxNeighbors];
  const double* vs[kMaxNeighbors];
  int na = 0, nf = 0;
  group_inputs(g, xs, na, vs, nf);
  const double* x = x_.data();
  const double* xd = scene_.x_d.data();
  for (int i = 0; i < dofs_; ++i) {
    double a = na * x[i], s = 0;
    for (int n = 0; n < na; ++n) a -= xs[n][i];
    for (int n = 0; n < nf; ++n) s += vs[n][i];
    sx[i] = a;
    sv[i] = s;
    if (d) d[i] = x[i] - xd[i];
  }
}

void StationCore::build_rhs() {
  const double N = cfg_.users;
  double quad[MultiTermOperator::kMaxTerms] = {};
  // Terms [M, K, P_0, D_0] on [v, d = x - x_d, sx_0, sv_0] (an over-bound edge contributes nothing:
  // x - x_hat_j = 0, delta_ij = 0).
  const double to_b[4] = {2.0 / (N * T_), -1.0 / N, -1.0, 1.0};
  if (rhs_op_.fuses_consensus()) {  // the terms' inputs formed inside the pass (sum_group's sums)
    const double* xs[kMaxNeighbors];
    const double* vs[kMaxNeighbors];
    MultiTermOperator::ConsensusInputs in;
    in.v = v_.data();
    in.x = x_.data();
    in.x_d = scene_.x_d.data();
    in.xs = xs;
    in.vs = vs;
    group_inputs(0, xs, in.na, vs, in.nf);
    rhs_op_.apply_consensus(in, to_b, rhs_.data(), quad);
  } else {
    if (neighbor_count() > 0) {
      sum_group(0, tmp2_.data(), scratch_.data(), tmp_.data());
    } else {
      tmp_ = x_ - scene_.x_d;
    }
    const double* u[4] = {v_.data(), tmp_.data(), tmp2_.data(), scratch_.data()};
    rhs_op_.apply(u, to_b, nullptr, rhs_.data(), nullptr, quad);
  }
  // E_i(k) = 1/N (|v|_M^2 / 2 + |x - x_d|_K^2 / 2) at the start of the tick (eq. 12)
  energy_.vo_J = 0.5 * (quad[0] + quad[1]) / N;
  // Further gain groups (edges with their own gains; rare): two matvecs each.
  for (std::size_t gi = 1; gi < group_leaders_.size(); ++gi) {
    const int g = group_leaders_[gi];
    const EdgeGains* eg = cfg_.neighbors[static_cast<std::size_t>(g)].gains;
    sum_group(g, tmp2_.data(), scratch_.data(), nullptr);
    eg->P.multiply_add(-1.0, tmp2_.data(), rhs_.data());
    eg->D.multiply_add(1.0, scratch_.data(), rhs_.data());
  }
}

namespace {
// The row-local part of steps 6 and 7 for NE edges (compile-time: accumulators in registers; -1:
// ne at run time): one pass over the dofs. RT-safe.
struct PostSolveRows {
  const double* vh;     // v_hat
  const double* r;      // the solve's residual
  const double* Dv;     // D_0 v_hat
  const double* Pv;     // P_0 v_hat
  // FromA (Dv, Pv unused): D_0 v_hat = dd v_hat, P_0 v_hat = alpha v_hat + rho (b - r), per node
  // (b: this tick's b with the contact coefficients added on the contact rows: A v_hat = b - r).
  const double* b = nullptr;
  const double* alpha = nullptr;
  const double* dd = nullptr;
  double rho = 0;
  double* x;
  double* v;
  double* xh;           // x_hat (written)
  const double* vj[kMaxNeighbors];
  const double* xj[kMaxNeighbors];
  double delta[kMaxNeighbors];
  int ne = 0;
  long dofs = 0;
  double T = 0;
  bool avx = false;     // run the AVX build (same bits)
};
struct PostSolveOut {
  double vv = 0, vr = 0, dvv = 0, vmax = 0, nonfinite = 0;
  double e[kMaxNeighbors] = {};
};
// One node (3 columns, lane 3 unused) at a time, every sum kept per lane and the lanes added at the
// end in a fixed order: the same bits in the baseline (SSE2) and the AVX build (rt/lanes.hpp).
template <int NE, bool Advance, bool FromA>
[[gnu::always_inline]] inline PostSolveOut post_solve_body(const PostSolveRows& p) {
  constexpr int kE = NE >= 0 ? NE : kMaxNeighbors;
  const int ne = NE >= 0 ? NE : p.ne;
  // x may be an edge's xj (an over-bound edge reads x(k)): a node's x is stored after its edge
  // terms are read, and 3 lanes only, so no later read sees a new value.
  const double* vh = p.vh;
  const double* r = p.r;
  double* x = p.x;
  double* v = p.v;
  double* xh = p.xh;
  const double half_T = p.T / 2.0, T = p.T;
  Lanes4 vv = {}, vr = {}, dvv = {}, vmax = {}, nonfinite = {};  // nonfinite: 0 unless some x or v is inf/NaN
  Lanes4 e[kE > 0 ? kE : 1] = {};
  const double* vj[kE > 0 ? kE : 1];
  const double* xj[kE > 0 ? kE : 1];
  double delta[kE > 0 ? kE : 1];
  for (int n = 0; n < ne; ++n) {
    vj[n] = p.vj[n];
    xj[n] = p.xj[n];
    delta[n] = p.delta[n];
  }
  const double rho = p.rho;
  const long nodes = p.dofs / 3;
  for (long i = 0; i < nodes; ++i) {
    const bool last = i == nodes - 1;
    const Lanes4 a = HAPTIC_NODE_LANES(vh, i, last);
    const Lanes4 ri = HAPTIC_NODE_LANES(r, i, last);
    const Lanes4 xi = HAPTIC_NODE_LANES(x, i, last);
    vv += a * a;
    vr += a * ri;
    const Lanes4 xk = xi + half_T * a;  // x_hat; the edge terms read x(k) before the advance
    HAPTIC_STORE_NODE(xh, i, xk);
    Lanes4 dv, pv;
    if constexpr (FromA) {
      dv = p.dd[i] * a;
      pv = p.alpha[i] * a + rho * (HAPTIC_NODE_LANES(p.b, i, last) - ri);
    } else {
      dv = HAPTIC_NODE_LANES(p.Dv, i, last);
      pv = HAPTIC_NODE_LANES(p.Pv, i, last);
    }
    dvv += dv * a;
    for (int n = 0; n < ne; ++n)
      e[n] += dv * (a - delta[n] * HAPTIC_NODE_LANES(vj[n], i, last)) + pv * (xk - HAPTIC_NODE_LANES(xj[n], i, last));
    if constexpr (Advance) {
      const Lanes4 xn = xi + T * a;
      const Lanes4 vn = 2.0 * a - HAPTIC_NODE_LANES(v, i, last);
      HAPTIC_STORE_NODE(x, i, xn);
      HAPTIC_STORE_NODE(v, i, vn);
      const Lanes4 av = vn < 0.0 ? -vn : vn;
      vmax = vmax > av ? vmax : av;  // a NaN is caught by nonfinite
      nonfinite += 0.0 * xn + 0.0 * vn;
    }
  }
  PostSolveOut out;
  out.vv = lane_sum<3>(vv);
  out.vr = lane_sum<3>(vr);
  out.dvv = lane_sum<3>(dvv);
  out.vmax = std::max(std::max(vmax[0], vmax[1]), vmax[2]);
  out.nonfinite = lane_sum<3>(nonfinite);
  for (int n = 0; n < ne; ++n) out.e[n] = lane_sum<3>(e[n]);
  return out;
}
template <int NE, bool Advance, bool FromA>
[[gnu::noinline]] PostSolveOut post_solve_rows(const PostSolveRows& p) {
  return post_solve_body<NE, Advance, FromA>(p);
}
#if defined(__x86_64__)
template <int NE, bool Advance, bool FromA>
[[gnu::noinline]] __attribute__((target("avx"))) PostSolveOut post_solve_rows_avx(const PostSolveRows& p) {
  return post_solve_body<NE, Advance, FromA>(p);
}
#endif
template <int NE, bool Advance, bool FromA, bool Avx>
PostSolveOut post_solve_rows_on(const PostSolveRows& p) {
#if defined(__x86_64__)
  if constexpr (Avx) return post_solve_rows_avx<NE, Advance, FromA>(p);
#endif
  return post_solve_rows<NE, Advance, FromA>(p);
}
template <bool Advance, bool FromA, bool Avx>
PostSolveOut post_solve_rows_by_edges_on(const PostSolveRows& p) {
  switch (p.ne) {
    case 0: return post_solve_rows_on<0, Advance, FromA, Avx>(p);
    case 1: return post_solve_rows_on<1, Advance, FromA, Avx>(p);
    case 2: return post_solve_rows_on<2, Advance, FromA, Avx>(p);
    case 3: return post_solve_rows_on<3, Advance, FromA, Avx>(p);
    case 4: return post_solve_rows_on<4, Advance, FromA, Avx>(p);
    default: return post_solve_rows_on<-1, Advance, FromA, Avx>(p);
  }
}
template <bool Advance, bool FromA>
PostSolveOut post_solve_rows_by_edges(const PostSolveRows& p) {
  return p.avx ? post_solve_rows_by_edges_on<Advance, FromA, true>(p) : post_solve_rows_by_edges_on<Advance, FromA, false>(p);
}
}  // namespace

StationCore::PostSolveSums StationCore::post_solve_pass(bool advance) {
  // Group 0's edges (the leader's gains): the data each edge's energy term reads.
  const EdgeGains* g0 = neighbor_count() > 0 ? cfg_.neighbors[0].gains : nullptr;
  PostSolveRows p;
  int edge[kMaxNeighbors];
  for (int j = 0; j < neighbor_count(); ++j) {
    if (cfg_.neighbors[static_cast<std::size_t>(j)].gains != g0) continue;
    const auto& view = views_[static_cast<std::size_t>(j)];
    edge[p.ne] = j;
    p.delta[p.ne] = (active_[static_cast<std::size_t>(j)] && view.fresh) ? 1.0 : 0.0;
    p.vj[p.ne] = view.v_hat;
    p.xj[p.ne] = active_[static_cast<std::size_t>(j)] ? view.x_hat : x_.data();  // over the bound: x_hat_j := x(k)
    ++p.ne;
  }
  const bool from_a = g0 && !step_->alpha.empty();
  // b with the contact coefficients on the contact rows (A v_hat = b - r + U coef), restored below.
  double saved_b[3 * kMaxContactNodes][3];
  double* b = rhs_prev_.data();  // b(k) (rotated after the solve)
  const bool add_coef = from_a && contact_coef_set_;
  if (add_coef)
    for (int a = 0; a < m_units_; ++a)
      for (int col = 0; col < 3; ++col) {
        const long k = 3L * unit_row_[static_cast<std::size_t>(a)] + col;
        saved_b[a][col] = b[k];
        b[k] += contact_coef_[a][col];
      }
  if (from_a) {
    p.b = b;
    p.alpha = step_->alpha.data();
    p.dd = d0_diag_.data();
    p.rho = step_->rho;
  } else if (g0) {  // D_0 v_hat -> tmp_, P_0 v_hat -> tmp2_ in one pass
    const double* u[2] = {v_hat_.data(), v_hat_.data()};
    static constexpr double kD[2] = {1.0, 0.0}, kP[2] = {0.0, 1.0};
    dp_op_.apply(u, kD, kP, tmp_.data(), tmp2_.data(), nullptr);
  } else {
    tmp_.setZero();
    tmp2_.setZero();
  }
  p.vh = v_hat_.data();
  p.r = resid_.data();
  p.Dv = tmp_.data();
  p.Pv = tmp2_.data();
  p.x = x_.data();
  p.v = v_.data();
  p.xh = x_hat_.data();
  p.dofs = dofs_;
  p.T = T_;
  p.avx = avx_kernels_;
  const PostSolveOut o = from_a ? (advance ? post_solve_rows_by_edges<true, true>(p) : post_solve_rows_by_edges<false, true>(p))
                                : (advance ? post_solve_rows_by_edges<true, false>(p) : post_solve_rows_by_edges<false, false>(p));
  if (add_coef)
    for (int a = 0; a < m_units_; ++a)
      for (int col = 0; col < 3; ++col) b[3L * unit_row_[static_cast<std::size_t>(a)] + col] = saved_b[a][col];
  // The VO rows' residual r of an inexact solve acted as the extra force -r (A v_hat = b - r; the
  // Schur step solves the contact/VP part exactly on top, so r is y0's residual).
  if (!step_->solver->exact()) energy_.solver_residual_J -= o.vr * T_;
  for (int n = 0; n < p.ne; ++n) edge_tick_J_[static_cast<std::size_t>(edge[n])] = -o.e[n] * T_;
  PostSolveSums out;
  out.vv = o.vv;
  out.dissipated_J = T_ * o.dvv;
  out.vmax = o.nonfinite == 0.0 ? o.vmax : std::nan("");
  return out;
}

const double* StationCore::modulation_target(int j, std::int64_t k) {
  const auto& view = views_[static_cast<std::size_t>(j)];
  if (!cfg_.predict_held_state) return view.x_hat;
  auto& since = held_since_[static_cast<std::size_t>(j)];
  if (view.fresh) since = k;  // first tick this packet is used
  const double h = static_cast<double>(k - since) * cfg_.period_s;
  if (h <= 0) return view.x_hat;
  const double lim = cfg_.predict_held_limit_m;
  for (int i = 0; i < dofs_; ++i) predicted_[i] = extrapolated_position(view.x_hat[i], view.v_hat[i], h, lim);
  return predicted_.data();
}

namespace {
// contact_correction's common case: v_hat = ((y0 + z0 c0) + z1 c1) + z2 c2 per node, the column
// passes' order, in 4 lanes (the baseline and AVX builds give the same bits).
struct ContactRows {
  int nodes;
  double* vh;
  const double* y0;
  const double* z[3];
  Lanes4 coef[3];
};
[[gnu::always_inline]] inline void contact_body(const ContactRows& a) {
  for (int i = 0; i < a.nodes; ++i) {
    const bool last = i == a.nodes - 1;
    const Lanes4 v = ((HAPTIC_NODE_LANES(a.y0, i, last) + a.z[0][i] * a.coef[0]) + a.z[1][i] * a.coef[1]) + a.z[2][i] * a.coef[2];
    HAPTIC_STORE_NODE(a.vh, i, v);
  }
}
void contact_rows(const ContactRows& a) { contact_body(a); }
#if defined(__x86_64__)
__attribute__((target("avx"))) void contact_rows_avx(const ContactRows& a) { contact_body(a); }
#endif
}  // namespace

void StationCore::contact_correction(const double* y0, double c) {
  // v_hat = y0 + sum_a Z_a coef_a, coef_a = c (X_vp - X_a) per column, the terms added in the order
  // a = 0, 1, ... as the column passes of the direct path do.
  constexpr int kU = 3 * kMaxContactNodes;
  const int m = m_units_, w = w_;
  double coef[kU][3];
  const double* za[kU];
  for (int a = 0; a < m; ++a) {
    za[a] = step_->Z.col(a).data();
    for (int col = 0; col < w; ++col) coef[a][col] = contact_coef_[a][col] = c * (X_(m + unit_vp_[a], col) - X_(a, col));
  }
  contact_coef_set_ = true;
  double* vh = v_hat_.data();
  if (w == 3 && m == 3) {  // the common case (three contact nodes, isotropic): one node per 4 lanes
    ContactRows rows{nf_, vh, y0, {za[0], za[1], za[2]}, {}};
    for (int a = 0; a < 3; ++a) rows.coef[a] = Lanes4{coef[a][0], coef[a][1], coef[a][2], 0.0};
#if defined(__x86_64__)
    if (avx_kernels_)
      contact_rows_avx(rows);
    else
#endif
      contact_rows(rows);
    return;
  }
  for (int r = 0; r < nf_; ++r)
    for (int col = 0; col < w; ++col) {
      const long k = static_cast<long>(r) * w + col;
      double s = y0[k];
      for (int a = 0; a < m; ++a) s += za[a][r] * coef[a][col];
      vh[k] = s;
    }
}

namespace {
// warm_start_y0's Jacobi-step pass with two solves kept, isotropic: per node (3 lanes)
// g = 2 y - g + dinv (b - 2 (b1 - r1) + (b2 - r2)). Baseline and AVX builds: the same bits.
struct WarmRows {
  int nodes;
  double* g;
  const double *y, *dinv, *b, *b1, *r1, *b2, *r2;
};
// SameAsTwoBack: the neighbour set alternates (this tick's active set is that of tick k-2, not of
// k-1): g = y0(k-2) + dinv (b - (b2 - r2)), the last solution with this right-hand side's pattern.
template <bool SameAsTwoBack>
[[gnu::always_inline]] inline void warm_body(const WarmRows& a) {
  for (int i = 0; i < a.nodes; ++i) {
    const bool last = i == a.nodes - 1;
    if constexpr (SameAsTwoBack) {
      const Lanes4 h = HAPTIC_NODE_LANES(a.b, i, last) - (HAPTIC_NODE_LANES(a.b2, i, last) - HAPTIC_NODE_LANES(a.r2, i, last));
      const Lanes4 g = HAPTIC_NODE_LANES(a.g, i, last) + a.dinv[i] * h;
      HAPTIC_STORE_NODE(a.g, i, g);
    } else {
      const Lanes4 h = HAPTIC_NODE_LANES(a.b, i, last) - 2.0 * (HAPTIC_NODE_LANES(a.b1, i, last) - HAPTIC_NODE_LANES(a.r1, i, last)) +
                       (HAPTIC_NODE_LANES(a.b2, i, last) - HAPTIC_NODE_LANES(a.r2, i, last));
      const Lanes4 g = 2.0 * HAPTIC_NODE_LANES(a.y, i, last) - HAPTIC_NODE_LANES(a.g, i, last) + a.dinv[i] * h;
      HAPTIC_STORE_NODE(a.g, i, g);
    }
  }
}
void warm_rows(const WarmRows& a, bool two_back) { two_back ? warm_body<true>(a) : warm_body<false>(a); }
#if defined(__x86_64__)
__attribute__((target("avx"))) void warm_rows_avx(const WarmRows& a, bool two_back) {
  two_back ? warm_body<true>(a) : warm_body<false>(a);
}
#endif
}  // namespace

void StationCore::warm_start_y0() {
  // y0_prev_ := 2 y0(k-1) - y0(k-2) (y0(k-1) until two solves exist) [+ the Jacobi step], then swap:
  // y0_ is the guess.
  double* g = y0_prev_.data();
  const double* y = y0_.data();
  const double* dinv = step_->solver->inverse_diagonal();
  const bool two = y0_solves_ >= 2;
  const bool jacobi = dinv != nullptr && y0_solves_ >= 1 && y0_level_[0] == step_ && (!two || y0_level_[1] == step_);
  // The active neighbours shape b: when they alternate tick by tick (an edge over its bound every
  // other tick), the solution two ticks back is the guess with the right pattern.
  std::uint32_t active = 0;
  for (int j = 0; j < neighbor_count(); ++j) active |= active_[static_cast<std::size_t>(j)] ? 1u << j : 0u;
  const bool two_back = two && active == y0_active_[1] && active != y0_active_[0];
  y0_active_[1] = y0_active_[0];
  y0_active_[0] = active;
  if (jacobi && two && w_ == 3) {  // the common case: one node (3 lanes) at a time
    const WarmRows rows{nf_, g, y, dinv, rhs_.data(), rhs_prev_.data(), resid_.data(), rhs_prev2_.data(), resid_prev_.data()};
#if defined(__x86_64__)
    if (avx_kernels_)
      warm_rows_avx(rows, two_back);
    else
#endif
      warm_rows(rows, two_back);
  } else if (jacobi) {
    // A g from A y0(j) = b(j) - r(j) (the solves of ticks k-1, k-2 with this A).
    const double* b = rhs_.data();
    const double* b1 = rhs_prev_.data();
    const double* r1 = resid_.data();
    const double* b2 = rhs_prev2_.data();
    const double* r2 = resid_prev_.data();
    const int w = w_;
    for (int i = 0; i < nf_; ++i) {
      const double di = dinv[i];
      for (int c = 0; c < w; ++c) {
        const long k = static_cast<long>(i) * w + c;
        if (two)
          g[k] = 2.0 * y[k] - g[k] + di * (b[k] - 2.0 * (b1[k] - r1[k]) + (b2[k] - r2[k]));
        else
          g[k] = y[k] + di * (b[k] - (b1[k] - r1[k]));
      }
    }
  } else if (two) {
    for (int i = 0; i < dofs_; ++i) g[i] = 2.0 * y[i] - g[i];
  } else {
    for (int i = 0; i < dofs_; ++i) g[i] = y[i];
  }
  y0_.swap(y0_prev_);  // swaps the buffers: no allocation
  if (y0_solves_ < 2) ++y0_solves_;
}

double StationCore::advance_state() {
  const double* vh = v_hat_.data();
  double* x = x_.data();
  double* v = v_.data();
  double vmax = 0, nonfinite = 0;  // nonfinite: 0 unless some x or v is inf/NaN
  for (int i = 0; i < dofs_; ++i) {
    x[i] += T_ * vh[i];
    v[i] = 2.0 * vh[i] - v[i];
    vmax = std::max(vmax, std::abs(v[i]));
    nonfinite += 0.0 * x[i] + 0.0 * v[i];
  }
  return nonfinite == 0.0 ? vmax : std::nan("");
}

[[gnu::always_inline]] inline void StationCore::select_step(double step_s) {
  double want = step_s;
  if (!(want >= cfg_.t_min() * (1 - 1e-9) && want <= cfg_.t_max() * (1 + 1e-9))) {
    ++step_clamped_ticks_;
    want = std::isfinite(want) ? std::clamp(want, cfg_.t_min(), cfg_.t_max()) : cfg_.period_s;
  }
  StepLevel* best = &steps_[0];
  for (auto& l : steps_)
    if (std::abs(l.T - want) < std::abs(best->T - want)) best = &l;
  step_ = best;
  if (stepped_) T_prev_ = T_;
  T_ = best->T;
}

[[gnu::always_inline]] inline Vec3 StationCore::device_force(const Vec3& q, Vec3& qk, Vec3& vq, std::uint32_t& flags) {
  const auto& g = cfg_.vp.coupling;
  qk = q;
  if (!qk.allFinite()) {
    flags |= kBadDeviceSample | kSafeState;
    qk = q_prev_;
  }
  // v_hat_q(k-1) = (q_k - q_{k-1}) / T_{k-1} (Section III-C)
  vq = !stepped_ ? Vec3::Zero() : Vec3((qk - q_prev_) / T_prev_);
  Vec3 f_dev = -g.B_vc_Ns_per_m * (vq - w_hat_prev_) - g.K_vc_N_per_m * (qk - y_);
  // Energy the station put into the device over the last hold interval: F(k-1) . (q_k - q_{k-1}).
  if (stepped_) energy_.device_port_J += f_dev_prev_.dot(qk - q_prev_);
  const double fn = f_dev.norm();
  if (fn > cfg_.max_device_force_N) {
    f_dev *= cfg_.max_device_force_N / fn;
    flags |= kForceClamped;
  }
  return f_dev;
}

void StationCore::exclude_resilient(std::uint32_t& flags) {
  const int nn = neighbor_count();
  std::array<double, kMaxNeighbors> d2{};
  std::array<unsigned char, kMaxNeighbors> candidate{};
  for (int j = 0; j < nn; ++j) {
    const auto n = static_cast<std::size_t>(j);
    candidate[n] = pspm_.empty() ? active_[n] : (views_[n].index_delay >= 0 ? 1 : 0);
    if (candidate[n]) d2[n] = squared_distance(views_[n].x_hat, x_.data(), dofs_);
  }
  if (exclude_farthest(d2.data(), candidate.data(), nn, cfg_.resilient_f, excluded_.data()) > 0) flags |= kResilientExcluded;
  for (int j = 0; j < nn; ++j) resilient_excluded_[static_cast<std::size_t>(j)] += excluded_[static_cast<std::size_t>(j)];
}

bool StationCore::edge_excluded(int j, std::int64_t k, bool within_bound) {
  const RxLink::TickView& view = views_[j];
  if (!within_bound) return edge_monitor_.isolated(j);  // data over the delay bound are not checked (not used either)
  return edge_monitor_.observe(j, k, rx_[j].newest_sequence(), view.x_hat, view.v_hat, view.index_delay, x_.data());
}

const double* StationCore::edge_target(int j, std::int64_t k, bool ok, bool distrusted, bool was_active) {
  RxLink::TickView& view = views_[j];
  const double* faded = nullptr;  // back during a fade: the ramp starts at the fade's target
  if (distrusted) {
    drop_fade_.stop(j);  // a liar's (or an over-bound account's) last state is not used
  } else if (ok) {
    faded = drop_fade_.handover(j, k, x_.data());
  } else if (was_active && !drop_fade_.fading(j)) {  // aged out: the anchor is what it coupled to last tick
    drop_fade_.start(j, k, return_ramp_.ramping(j) ? return_ramp_.last_target(j) : view.x_hat);
  }
  // x_hat itself unless ramping (an isolation or a gate's hold counts as an outage: a re-admitted or
  // released edge ramps in too)
  const double* t = return_ramp_.target(j, k, ok && !distrusted, view.x_hat, x_.data(), faded);
  if (ok || distrusted) return t;
  const double* f = drop_fade_.target(j, k, x_.data());
  if (!f) return t;  // dropped: the damper
  active_[j] = 1;
  view.fresh = false;  // delta_ij = 0: the held velocity is as old as the anchor
  return f;
}

[[gnu::always_inline]] inline void StationCore::read_neighbours(std::int64_t k, std::uint32_t& flags) {
  // Over the delay bound, over the energy bound or left out by the resilient rule: x_hat_j := x(k),
  // delta_ij = 0 (the edge acts as the damper D_ij + T/2 P_ij).
  for (int j = 0; j < neighbor_count(); ++j) {
    views_[j] = rx_[j].begin_tick(k);
    if (!pspm_.empty()) continue;  // set-position modulation: passive for any delay, no bound, no drop
    // A negative delay (data stamped ahead of our tick) is never trusted: over the bound.
    const bool ok = views_[j].index_delay >= 0 && views_[j].index_delay <= cfg_.neighbors[j].index_delay_bound_ticks;
    // The per-edge damage bound: an edge whose account is over its bound takes the same action.
    const bool gated = edge_gate_.update(j, edge_energy_.edge_J(j));
    if (gated) flags |= kEdgeEnergyGated;
    // The state check: an edge whose reported states failed it (isolated) too.
    const bool excluded = edge_excluded(j, k, ok);
    if (excluded) flags |= kEdgeIsolated;
    const bool was_active = active_[j] != 0;
    active_[j] = (ok && !gated && !excluded) ? 1 : 0;
    views_[j].x_hat = edge_target(j, k, ok, gated || excluded, was_active);
    if (ok) {
      edge_was_dropped_[j] = 0;
    } else {
      flags |= kEdgeDropped;
      if (!edge_was_dropped_[j]) ++edge_drops_[j];
      edge_was_dropped_[j] = 1;
    }
  }
  if (cfg_.resilient_f > 0) exclude_resilient(flags);  // among the edges the bounds left in
  bool any_prepared = false;
  for (int j = 0; j < neighbor_count(); ++j) {
    const bool excluded = excluded_[static_cast<std::size_t>(j)] != 0;
    if (pspm_.empty()) {
      if (excluded) {
        active_[j] = 0;
        drop_fade_.stop(j);  // left out: at once
      }
      continue;
    }
    auto& m = pspm_[static_cast<std::size_t>(j)];
    // left out: the set-position relaxes towards this copy (the modulation is passive for any target)
    if (views_[j].index_delay >= 0) {
      const double* target = modulation_target(j, k);  // (keeps the held-since count when left out)
      m.prepare(excluded ? x_.data() : target, x_.data(), pspm_scratch_.data() + 2L * dofs_ * j);
      pspm_prepared_[static_cast<std::size_t>(j)] = 1;
      any_prepared = true;
    }
    views_[j].x_hat = m.ybar();
    views_[j].fresh = false;  // D acts on the local velocity only
    active_[j] = 1;
  }
  if (any_prepared) modulate_prepared_edges();
}

void StationCore::modulate_prepared_edges() {
  // Each gain group's prepared edges (their P is the group's) take their forms in one pass over P's rows.
  std::array<const double*, kMaxNeighbors> d{}, r{};
  std::array<PairForms, kMaxNeighbors> forms{};
  std::array<int, kMaxNeighbors> edge{};
  for (const int g : group_leaders_) {
    const EdgeGains* eg = cfg_.neighbors[static_cast<std::size_t>(g)].gains;
    int m = 0;
    for (int j = g; j < neighbor_count(); ++j) {
      const auto u = static_cast<std::size_t>(j);
      if (!pspm_prepared_[u] || cfg_.neighbors[u].gains != eg) continue;
      pspm_prepared_[u] = 0;
      const auto e = static_cast<std::size_t>(m++);
      edge[e] = j;
      d[e] = pspm_scratch_.data() + 2L * dofs_ * j;
      r[e] = d[e] + dofs_;
    }
    if (m == 0) continue;
    eg->P.pair_forms_many(d.data(), r.data(), m, forms.data());
    for (int e = 0; e < m; ++e) pspm_[static_cast<std::size_t>(edge[static_cast<std::size_t>(e)])].finish(forms[static_cast<std::size_t>(e)], d[static_cast<std::size_t>(e)]);
  }
}

[[gnu::always_inline]] inline void StationCore::update_contact_set(std::uint32_t& flags) {
  const ContactFace face = contact_face(x_, cfg_.contact_nodes);
  const Vec3& xc = face.centroid;
  Vec3 nrm = normal_sign_ * face.normal;
  const double len = nrm.norm();
  if (len > 0) nrm /= len;
  if (in_contact_) {
    // Release when the contact pulls the VP into the object (tension): a passive switch,
    // it only removes the stored contact-spring energy.
    if (f_contact_vp_.dot(nrm) < 0.0) {
      in_contact_ = false;
      flags |= kContactRelease;
    }
  } else if (nrm.dot(y_ - xc) <= 0.0) {
    engage_contact();  // anchored at the current offsets: zero force, zero energy at onset
    flags |= kContactOnset;
  }
}

[[gnu::always_inline]] inline Vec3 StationCore::build_step_rhs(const Vec3& qk, const Vec3& vq) {
  // b = (1/N)((2M/T) v - K(x - x_d)) + sum_j delta_ij D_ij v_hat_j - sum_j P_ij (x - x_hat_j)
  const auto& g = cfg_.vp.coupling;
  const double kc = cfg_.vp.contact_stiffness_N_per_m;
  const auto& cn = cfg_.contact_nodes;
  build_rhs();
  Vec3 bw = (2.0 * cfg_.vp.mass_kg / T_) * w_vp_ + g.B_vc_Ns_per_m * vq - g.K_vc_N_per_m * (y_ - qk);
  if (in_contact_) {
    for (std::size_t a = 0; a < cn.size(); ++a) {
      const Vec3 s = kc * (y_ + anchor_[a] - x_.segment<3>(3 * cn[a]));
      rhs_.segment<3>(3 * cn[a]) += s;
      bw -= s;
    }
  }
  return bw;
}

[[gnu::always_inline]] inline void StationCore::solve_vo() {
  StepSolver::Report rep;
  if (step_->solver->exact()) {
    rep = step_->solver->solve(rhs_.data(), v_hat_.data(), resid_.data(), w_);
  } else {
    warm_start_y0();
    resid_prev_.swap(resid_);  // r(k-1) kept; the solve writes r(k) (swaps: no allocation)
    rep = step_->solver->solve(rhs_.data(), y0_.data(), resid_.data(), w_);
    if (!in_contact_) v_hat_ = y0_;  // same size: a copy, no allocation (in contact: below)
    rhs_prev2_.swap(rhs_prev_);  // b(k-1), b(k) kept; rhs_ is rebuilt next tick
    rhs_prev_.swap(rhs_);
    y0_level_[1] = y0_level_[0];
    y0_level_[0] = step_;
  }
  solver_last_iterations_ = rep.iterations;
  solver_iterations_total_ += static_cast<std::uint64_t>(rep.iterations);
  ++solver_ticks_;
  if (!rep.converged) ++solver_unconverged_ticks_;
}

[[gnu::always_inline]] inline Vec3 StationCore::solve_contact(const Vec3& bw, double c) {
  contact_coef_set_ = false;
  if (!in_contact_) return bw / step_->a_w;
  const int m = m_units_;
  const double* y0 = step_->solver->exact() ? v_hat_.data() : y0_.data();  // A^{-1} b
  for (int a = 0; a < m; ++a)
    for (int col = 0; col < w_; ++col) R_(a, col) = y0[unit_row_[a] * w_ + col];
  for (int e = 0; e < vp_units_; ++e)
    for (int col = 0; col < w_; ++col) R_(m + e, col) = (w_ == 3) ? bw[col] : bw[e];
  X_.noalias() = step_->lu.solve(R_);
  if (step_->solver->exact()) {
    for (int a = 0; a < m; ++a) {
      const double* za = step_->Z.col(a).data();
      for (int col = 0; col < w_; ++col) {
        const double coef = c * (X_(m + unit_vp_[a], col) - X_(a, col));
        if (coef == 0.0) continue;
        for (int r = 0; r < nf_; ++r) v_hat_[r * w_ + col] += za[r] * coef;
      }
    }
  } else {
    contact_correction(y0_.data(), c);  // v_hat = y0 + Z coef in one pass (large scenes)
  }
  Vec3 w_hat;
  for (int d = 0; d < 3; ++d) w_hat[d] = (w_ == 3) ? X_(m, d) : X_(m + d, 0);
  return w_hat;
}

[[gnu::always_inline]] inline double StationCore::contact_port_power(const Vec3& w_hat) {
  const double kc = cfg_.vp.contact_stiffness_N_per_m, bc = cfg_.vp.contact_damping_Ns_per_m;
  const auto& cn = cfg_.contact_nodes;
  const Vec3 y_hat = y_ + (T_ / 2.0) * w_hat;
  double port_power = 0;
  f_contact_vp_.setZero();
  if (in_contact_) {
    for (std::size_t a = 0; a < cn.size(); ++a) {
      const Vec3 vp = v_hat_.segment<3>(3 * cn[a]);
      const Vec3 f = kc * (y_hat + anchor_[a] - x_hat_.segment<3>(3 * cn[a])) + bc * (w_hat - vp);  // on the VO node
      port_power += vp.dot(f);
      f_contact_vp_ -= f;
    }
  }
  return port_power;
}

[[gnu::always_inline]] inline void StationCore::further_groups_energy(double& ctrl_J) {
  const int nn = neighbor_count();
  for (std::size_t gi = 1; gi < group_leaders_.size(); ++gi) {  // D v_hat and P v_hat by matvecs
    const int j = group_leaders_[gi];
    const EdgeGains* eg = cfg_.neighbors[j].gains;
    tmp_.setZero();   // D v_hat
    tmp2_.setZero();  // P v_hat
    eg->D.multiply_add(1.0, v_hat_.data(), tmp_.data());
    eg->P.multiply_add(1.0, v_hat_.data(), tmp2_.data());
    const double dissipated_J = pspm_.empty() ? 0.0 : T_ * tmp_.dot(v_hat_);
    for (int i2 = j; i2 < nn; ++i2) {
      if (cfg_.neighbors[i2].gains != eg) continue;
      const double delta = (active_[i2] && views_[i2].fresh) ? 1.0 : 0.0;
      const double* vj = views_[i2].v_hat;
      const double* xj = active_[i2] ? views_[i2].x_hat : x_.data();
      double e = 0;
      for (int i = 0; i < dofs_; ++i) e += tmp_[i] * (v_hat_[i] - delta * vj[i]) + tmp2_[i] * (x_hat_[i] - xj[i]);
      edge_tick_J_[static_cast<std::size_t>(i2)] = -e * T_;
      ctrl_J -= e * T_;
      if (!pspm_.empty()) pspm_[static_cast<std::size_t>(i2)].credit(dissipated_J);
    }
  }
}

[[gnu::always_inline]] inline double StationCore::account_energies(const Vec3& w_hat) {
  // tau = -B_i v_hat - sum_j D_ij (v_hat - delta v_hat_j) - P_ij (x_hat - x_hat_j)   (eq. 15),
  // with x_hat_j := x(k), delta_ij = 0 for an over-bound edge. Split per edge (rt/edge_energy.hpp):
  // D_ij, P_ij are symmetric, so v_hat^T D u = (D v_hat)^T u: one D v_hat and one P v_hat per gain
  // set, then two dot products per edge, fused with x_hat and the advance in one pass
  // (post_solve_pass). Further gain groups (rare) read x(k): then the advance is a pass of its own.
  const int nn = neighbor_count();
  const bool one_group = group_leaders_.size() <= 1;
  const PostSolveSums sums = post_solve_pass(one_group);
  energy_.port_J += contact_port_power(w_hat) * T_;
  const double damping_J = -cfg_.damping_Ns_per_m * sums.vv * T_;
  double ctrl_J = damping_J;
  for (int j = 0; j < nn; ++j) {
    if (cfg_.neighbors[j].gains != cfg_.neighbors[0].gains) continue;
    ctrl_J += edge_tick_J_[static_cast<std::size_t>(j)];
    // pspm: T v_hat^T D v_hat, what each edge of this gain group dissipated (D on the local velocity)
    if (!pspm_.empty()) pspm_[static_cast<std::size_t>(j)].credit(sums.dissipated_J);
  }
  further_groups_energy(ctrl_J);
  // The previous tick's outflow: its controller energy minus the copy's energy change (E(k) is this
  // tick's energy_.vo_J): what left through the contact port, the object's damping or the solver.
  if (have_prev_energy_) edge_energy_.credit_outflow(prev_ctrl_J_ - (energy_.vo_J - prev_vo_J_), prev_T_);
  prev_T_ = T_;
  prev_ctrl_J_ = ctrl_J;
  prev_vo_J_ = energy_.vo_J;
  have_prev_energy_ = true;
  edge_energy_.record_tick(std::span<const double>(edge_tick_J_.data(), static_cast<std::size_t>(nn)), damping_J);
  for (int j = 0; j < nn; ++j) edge_gate_.record_tick(j, edge_tick_J_[static_cast<std::size_t>(j)]);
  energy_.controller_J += ctrl_J;
  return one_group ? sums.vmax : advance_state();
}

StationCore::TickOutput StationCore::tick(std::int64_t k, const Vec3& q, double step_s) {
  TickOutput out;
  // --- 0. this tick's step T_k: clamped to [T^min, T^max], the nearest prefactored one ---
  select_step(step_s);
  const double c = cfg_.vp.contact_damping_Ns_per_m + cfg_.vp.contact_stiffness_N_per_m * T_ / 2.0;
  // --- 1. device sample and the device force u_i(t) (Section III-C) ---
  Vec3 qk, vq;
  Vec3 f_dev = device_force(q, qk, vq, out.flags);
  // --- 2. neighbours: newest packet, indexing delay, duplication avoidance, delay bound ---
  read_neighbours(k, out.flags);
  // --- 3. contact set (decided from the state at the start of the tick) ---
  update_contact_set(out.flags);
  // --- 4. right-hand side b (DESIGN.md) ---
  const Vec3 bw = build_step_rhs(qk, vq);
  // --- 5. solve: A y0 = b, then the contact/VP Schur complement ---
  solve_vo();
  const Vec3 w_hat = solve_contact(bw, c);
  // --- 6. predicted states, energies (13), (14) and (one gain group) step 7's state advance ---
  const double vmax_seen = account_energies(w_hat);
  // --- 7. advance the state (eq. 9, eq. 21) ---
  y_ += T_ * w_hat;
  w_vp_ = 2.0 * w_hat - w_vp_;
  w_hat_prev_ = w_hat;
  q_prev_ = qk;
  k_ = k + 1;
  stepped_ = true;
  // --- 8. safety: divergence -> safe state (zero force), reported through flags ---
  if (!(vmax_seen <= cfg_.divergence_speed_m_per_s) || !y_.allFinite()) safe_state_ = true;
  if (safe_state_) out.flags |= kDiverged | kSafeState;
  if (out.flags & kSafeState) {
    ++safe_state_ticks_;
    f_dev.setZero();
  }
  out.device_force_N = f_dev;
  f_dev_prev_ = f_dev;
  return out;
}

}  // namespace haptic::rt
