// Tick cost of one station against fair baselines, in one run (rt/README.md, tools/bench/README):
//  - the station's tick with each solver of the linear step: auto (by size), direct (the project's
//    sparse LDL^T, the only solver before the solver by size), iterative (Jacobi-preconditioned CG), and two
//    baselines plugged in through StepSolverConfig::custom: a dense Cholesky (Eigen LLT) factored
//    ONCE at start-up and solved per tick, and CHOLMOD (SuiteSparse) factored once at start-up;
//  - the old strawman (a dense assemble-and-factor every tick) at 33 nodes only, labelled as such;
//  - the worst case (neighbour set changing every tick while in contact);
//  - start-up to the first tick, and the peak memory of a station by its neighbour count;
//  - each size's floor: one pass reading as many bytes as its tick touches (BM_TickFloor).
// Each tick includes what DESIGN.md's tick does in rt/: handing the neighbours' newest packets to
// their receive links as a real station does (in place, RxBuffers below), the solve with contact
// active, energies and the state update.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Cholesky>
#include <Eigen/IterativeLinearSolvers>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "firmware/scenario.hpp"
#include "firmware/sim/simulator.hpp"
#include "tests/support/dense_reference.hpp"
#include "rt/edge_monitor.hpp"
#include "rt/gains.hpp"
#include "rt/rx_link.hpp"
#include "rt/scene.hpp"
#include "rt/station.hpp"
#include "rt/step_solver.hpp"
#include "rt/tick_driver.hpp"

#ifdef HAPTIC_HAVE_CHOLMOD
#include <suitesparse/cholmod.h>
#endif

using namespace haptic::rt;
using haptic::test::DenseStationReference;

namespace {

enum SolverArg { kAutoArg = 0, kDirectArg = 1, kIterativeArg = 2, kDenseOnceArg = 3, kCholmodArg = 4, kEigenCgArg = 5 };

// Baseline: dense Cholesky of the step matrix, factored once; the solve per tick is two dense
// triangular solves with the interleaved right-hand sides (Eigen, vectorized).
class DenseOnceSolver final : public StepSolver {
 public:
  explicit DenseOnceSolver(const SparseColMajor& A) : llt_(Eigen::MatrixXd(A)) {}
  Report solve(const double* b, double* x, double*, int width) override {
    const long n = llt_.rows();
    for (long i = 0; i < n * width; ++i) x[i] = b[i];
    if (width == 3) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> X(x, n, 3);
      llt_.solveInPlace(X);
    } else {
      Eigen::Map<Eigen::VectorXd> X(x, n);
      llt_.solveInPlace(X);
    }
    return {};
  }
  void solve_accurately(const double* b, double* x, int width) override { solve(b, x, nullptr, width); }
  bool exact() const override { return true; }
  const char* name() const override { return "dense-once"; }
  long stored_doubles() const override { return llt_.rows() * llt_.rows(); }

 private:
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

// Baseline: Eigen's ConjugateGradient with its diagonal (Jacobi) preconditioner on A (lower and upper
// triangles: the full rows), to the station's default tolerance 1e-8, each column solved from the
// station's guess (the previous v_hat; solveWithGuess). Reported exact(): the station counts no
// residual energy for it and gives it no warm start of its own, so it does less bookkeeping per
// tick than the project's CG (a baseline that favours Eigen).
class EigenCgSolver final : public StepSolver {
 public:
  EigenCgSolver(const SparseColMajor& A, int width) : A_(A), b_(A.rows()), x_(A.rows()) {
    cg_.setTolerance(1e-8);
    cg_.compute(A_);
    (void)width;
  }
  Report solve(const double* b, double* x, double*, int width) override {
    const long n = A_.rows();
    Report rep;
    for (int c = 0; c < width; ++c) {
      for (long i = 0; i < n; ++i) {
        b_[i] = b[i * width + c];
        x_[i] = x[i * width + c];
      }
      x_ = cg_.solveWithGuess(b_, x_);
      rep.iterations += static_cast<int>(cg_.iterations());
      for (long i = 0; i < n; ++i) x[i * width + c] = x_[i];
    }
    return rep;
  }
  void solve_accurately(const double* b, double* x, int width) override {
    Eigen::ConjugateGradient<SparseColMajor, Eigen::Lower | Eigen::Upper> accurate;
    accurate.setTolerance(1e-15);
    accurate.compute(A_);
    const long n = A_.rows();
    for (int c = 0; c < width; ++c) {
      for (long i = 0; i < n; ++i) b_[i] = b[i * width + c];
      x_ = accurate.solve(b_);
      for (long i = 0; i < n; ++i) x[i * width + c] = x_[i];
    }
  }
  bool exact() const override { return true; }
  const char* name() const override { return "eigen-cg"; }
  long stored_doubles() const override { return A_.nonZeros() * 3 / 2 + 3 * A_.rows(); }

 private:
  SparseColMajor A_;
  Eigen::ConjugateGradient<SparseColMajor, Eigen::Lower | Eigen::Upper> cg_;
  Eigen::VectorXd b_, x_;
};

#ifdef HAPTIC_HAVE_CHOLMOD
// Baseline: CHOLMOD's analysis and factorization once; per tick
// cholmod_solve2 with workspace reused across calls (no allocation after the first solve).
class CholmodSolver final : public StepSolver {
 public:
  explicit CholmodSolver(const SparseColMajor& A, int width) {
    cholmod_start(&cm_);
    // The configuration measured best for this matrix: simplicial LDL^T, METIS ordering
    // (no BLAS threads competing with the tick).
    cm_.supernodal = CHOLMOD_SIMPLICIAL;
    cm_.final_ll = 0;
    cm_.nmethods = 1;
    cm_.method[0].ordering = CHOLMOD_METIS;
    const int n = static_cast<int>(A.rows());
    cholmod_sparse* S = cholmod_allocate_sparse(n, n, static_cast<std::size_t>(A.nonZeros()), 1, 1, -1, CHOLMOD_REAL, &cm_);
    auto* cp = static_cast<int*>(S->p);
    auto* ri = static_cast<int*>(S->i);
    auto* vx = static_cast<double*>(S->x);
    int q = 0;
    for (int j = 0; j < n; ++j) {
      cp[j] = q;
      for (SparseColMajor::InnerIterator it(A, j); it; ++it)
        if (it.row() >= j) {
          ri[q] = static_cast<int>(it.row());
          vx[q++] = it.value();
        }
    }
    cp[n] = q;
    L_ = cholmod_analyze(S, &cm_);
    cholmod_factorize(S, L_, &cm_);
    cholmod_free_sparse(&S, &cm_);
    if (cm_.status != CHOLMOD_OK) throw std::runtime_error("CHOLMOD factorization failed");
    B_ = cholmod_allocate_dense(static_cast<std::size_t>(n), static_cast<std::size_t>(width), static_cast<std::size_t>(n), CHOLMOD_REAL, &cm_);
    n_ = n;
  }
  ~CholmodSolver() override {
    cholmod_free_dense(&B_, &cm_);
    cholmod_free_dense(&X_, &cm_);
    cholmod_free_dense(&Y_, &cm_);
    cholmod_free_dense(&E_, &cm_);
    cholmod_free_factor(&L_, &cm_);
    cholmod_finish(&cm_);
  }
  Report solve(const double* b, double* x, double*, int width) override {
    auto* bx = static_cast<double*>(B_->x);
    B_->ncol = static_cast<std::size_t>(width);
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < width; ++c) bx[static_cast<long>(c) * n_ + i] = b[static_cast<long>(i) * width + c];
    cholmod_solve2(CHOLMOD_A, L_, B_, nullptr, &X_, nullptr, &Y_, &E_, &cm_);
    const auto* xx = static_cast<const double*>(X_->x);
    for (int i = 0; i < n_; ++i)
      for (int c = 0; c < width; ++c) x[static_cast<long>(i) * width + c] = xx[static_cast<long>(c) * n_ + i];
    return {};
  }
  void solve_accurately(const double* b, double* x, int width) override { solve(b, x, nullptr, width); }
  bool exact() const override { return true; }
  const char* name() const override { return "cholmod"; }
  long stored_doubles() const override { return static_cast<long>(L_->is_super ? L_->xsize : L_->nzmax); }

 private:
  cholmod_common cm_{};
  cholmod_factor* L_ = nullptr;
  cholmod_dense *B_ = nullptr, *X_ = nullptr, *Y_ = nullptr, *E_ = nullptr;
  int n_ = 0;
};
#endif

bool set_solver(StepSolverConfig& s, int arg) {
  switch (arg) {
    case kDirectArg:
      s.kind = StepSolverKind::kDirect;
      return true;
    case kIterativeArg:
      s.kind = StepSolverKind::kIterative;
      return true;
    case kDenseOnceArg:
      s.custom = [](const SparseColMajor& A, int) { return std::make_unique<DenseOnceSolver>(A); };
      return true;
    case kEigenCgArg:
      s.custom = [](const SparseColMajor& A, int w) { return std::make_unique<EigenCgSolver>(A, w); };
      return true;
    case kCholmodArg:
#ifdef HAPTIC_HAVE_CHOLMOD
      s.custom = [](const SparseColMajor& A, int w) { return std::make_unique<CholmodSolver>(A, w); };
      return true;
#else
      return false;
#endif
    default:
      return true;
  }
}

struct World {
  Scene scene;
  EdgeGains gains;
  StationConfig cfg;
  Eigen::Vector3d push_to, inward;
  explicit World(int nodes, int neighbours = 3)
      : scene(build_scene(nodes == 33 ? make_paper_ball(0.05) : make_lattice_ball(nodes, 0.05), SceneParams{})),
        gains(paper_edge_gains(scene)) {
    const int f = scene.mesh.face_towards(Eigen::Vector3d(1, 1, 1));
    const auto& face = scene.mesh.surface[static_cast<std::size_t>(f)];
    cfg.users = neighbours + 1;
    cfg.scene = &scene;
    cfg.damping_Ns_per_m = 30.45;
    for (int p = 1; p <= neighbours; ++p) cfg.neighbors.push_back({p, &gains, 1 << 30});
    cfg.contact_nodes = {face[0], face[1], face[2]};
    cfg.vp_initial_position_m = scene.mesh.face_center(f);
    inward = -scene.mesh.face_normal(f).normalized();
    push_to = cfg.vp_initial_position_m + 0.01 * inward;
  }
  // The device at tick k: pressed 1 cm into the face, moving in and out by 5 mm at 2 Hz (250 ticks
  // of 2 ms), so the object never settles: a static push converges, the warm-started CG then needs
  // no iteration at all and the tick time would depend on how long the benchmark ran.
  Eigen::Vector3d device_at(std::int64_t k) const {
    return push_to + 0.005 * std::sin(2.0 * M_PI * static_cast<double>(k) / 250.0) * inward;
  }
};

// The neighbours' packets as a real station's tick gets them (firmware/station/tick.cpp): each in an
// RX buffer of its own that the receive link reads in place (RxLink::take; the endpoint judged it
// and its decoder wrote it, on the I/O thread), a new buffer every tick and the one replaced given
// back. Two buffers per link, used alternately, each holding the state x then v.
struct RxBuffers {
  int dofs = 0;
  std::vector<std::vector<double>> buf;  // link n, slot s at 2 n + s
  RxBuffers(const std::vector<double>& x, const std::vector<double>& v, int links) : dofs(static_cast<int>(x.size())) {
    for (int b = 0; b < 2 * links; ++b) {
      std::vector<double> xv(x);
      xv.insert(xv.end(), v.begin(), v.end());
      buf.push_back(std::move(xv));
    }
  }
};

// One tick at k as every caller drives a core (rt::drive_tick): neighbour n's packet of tick k (the
// state x, v) handed in for every n < links (and for the last one too when last_too), then the step
// with the device at q over the nominal period.
StationCore::TickOutput drive(StationCore& st, std::int64_t k, const Eigen::Vector3d& q, const RxBuffers& rx, int links, bool last_too = true) {
  return drive_tick(st, TickDrive{k, 0, q, st.config().period_s}, [&](auto&& offer) {
    for (int n = 0; n < links; ++n) {
      if (n + 1 == links && !last_too) continue;
      const auto slot = static_cast<std::uint32_t>(2 * n + (k & 1));
      const double* p = rx.buf[slot].data();
      std::uint32_t released = RxLink::kNoSlot;
      offer(ReceivedState{n, k, 0, p, p + rx.dofs, rx.dofs, slot, &released});
    }
  });
}
// The strawman is no StationCore: the same packets offered by hand (checked and copied), then its tick.
Eigen::Vector3d drive(DenseStationReference& st, std::int64_t k, const Eigen::Vector3d& q, const RxBuffers& rx, int links) {
  for (int n = 0; n < links; ++n) {
    const double* p = rx.buf[static_cast<std::size_t>(2 * n + (k & 1))].data();
    st.rx(n).offer(k, 0, p, p + rx.dofs, rx.dofs);
  }
  return st.tick(q);
}

// Ticks in contact with the moving device (World::device_at). Counters: iterations_mean (CG
// iterations per measured tick) and contact_fraction (measured ticks in contact).
template <class Station>
void run_ticks(benchmark::State& state, Station& st, const World& w) {
  const int dofs = w.scene.dofs;
  const int nn = static_cast<int>(w.cfg.neighbors.size());
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  const RxBuffers rx(x, v, nn);
  std::int64_t seq = 0;
  // settle into contact first
  for (int k = 0; k < 50; ++k) {
    drive(st, seq, w.device_at(seq), rx, nn);
    ++seq;
  }
  double iterations = 0, contact = 0, ticks = 0;
  for (auto _ : state) {
    auto out = drive(st, seq, w.device_at(seq), rx, nn);
    ++seq;
    benchmark::DoNotOptimize(out);
    if constexpr (requires { st.solver_last_iterations(); }) iterations += st.solver_last_iterations();
    contact += st.in_contact() ? 1 : 0;
    ticks += 1;
  }
  state.counters["iterations_mean"] = ticks > 0 ? iterations / ticks : 0;
  state.counters["contact_fraction"] = ticks > 0 ? contact / ticks : 0;
}

void station_counters(benchmark::State& state, const StationCore& st, const World& w) {
  state.counters["nodes"] = w.scene.nodes;
  state.counters["solver_MB"] = static_cast<double>(st.solver_stored_doubles()) * 8e-6;
  state.counters["unconverged_ticks"] = static_cast<double>(st.solver_unconverged_ticks());
  state.SetLabel(st.solver_name());
}

// Args: nodes, solver (0 auto, 1 direct, 2 iterative, 3 dense factored once, 4 CHOLMOD once).
void BM_Tick(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  if (!set_solver(w.cfg.solver, static_cast<int>(state.range(1)))) {
    state.SkipWithError("CHOLMOD not built in (libsuitesparse-dev missing)");
    return;
  }
  StationCore st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  station_counters(state, st, w);
}

// BM_Tick/NODES/0 with each neighbour's gains in an object of its own, equal in value: how the
// scenario builder (firmware/scenario.cpp) and so `sim` and every station hold them, one copy per
// edge. Args: nodes.
void BM_TickEdgeCopies(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  std::vector<EdgeGains> copies(w.cfg.neighbors.size(), w.gains);
  for (std::size_t n = 0; n < copies.size(); ++n) w.cfg.neighbors[n].gains = &copies[n];
  StationCore st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  station_counters(state, st, w);
  state.counters["gain_groups"] = st.gain_groups();
}

// BM_Tick/NODES/0 under set-position modulation (consensus_passivity = pspm, as the deadband's
// predictive mode needs): each edge's modulator takes one P d matvec a tick besides the step.
// Args: nodes.
void BM_TickPspm(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  w.cfg.consensus_passivity = ConsensusPassivity::kSetPositionModulation;
  w.cfg.pspm_reservoir0_J = 1e-3;
  StationCore st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  station_counters(state, st, w);
}

// The set-position modulator's two forms d^T P d and r^T P d on the paper's P (one edge, one tick's
// work): method 0 forms P d (SpatialMatrix::multiply_add) and takes two dot products, as the
// modulator did before; 1 is SpatialMatrix::pair_forms (one pass, no P d). Args: nodes, method.
void BM_PspmForms(benchmark::State& state) {
  const Scene scene = build_scene(state.range(0) == 33 ? make_paper_ball(0.05) : make_lattice_ball(static_cast<int>(state.range(0)), 0.05),
                                  SceneParams{});
  const EdgeGains g = paper_edge_gains(scene);
  const int n = g.P.dofs();
  std::vector<double> d(static_cast<std::size_t>(n)), r(d.size()), Pd(d.size());
  for (int k = 0; k < n; ++k) {
    d[static_cast<std::size_t>(k)] = 1e-4 * std::sin(0.37 * k);
    r[static_cast<std::size_t>(k)] = 1e-3 * std::cos(0.11 * k);
  }
  double sink = 0;
  for (auto _ : state) {
    if (state.range(1) == 0) {
      std::fill(Pd.begin(), Pd.end(), 0.0);
      g.P.multiply_add(1.0, d.data(), Pd.data());
      double dPd = 0, rPd = 0;
      for (int k = 0; k < n; ++k) {
        dPd += d[static_cast<std::size_t>(k)] * Pd[static_cast<std::size_t>(k)];
        rPd += r[static_cast<std::size_t>(k)] * Pd[static_cast<std::size_t>(k)];
      }
      sink += dPd + rPd;
    } else {
      const PairForms f = g.P.pair_forms(d.data(), r.data());
      sink += f.dAd + f.rAd;
    }
    benchmark::DoNotOptimize(sink);
  }
  state.counters["nodes"] = static_cast<double>(n / 3);
}

// A hub's three modulated edges sharing P (one gain group), one tick's forms: method 0 one pass over
// P per edge (SpatialMatrix::pair_forms three times), 1 one pass for the three
// (SpatialMatrix::pair_forms_many, what StationCore does). Args: nodes, method.
void BM_PspmFormsEdges(benchmark::State& state) {
  const Scene scene = build_scene(state.range(0) == 33 ? make_paper_ball(0.05) : make_lattice_ball(static_cast<int>(state.range(0)), 0.05),
                                  SceneParams{});
  const EdgeGains g = paper_edge_gains(scene);
  const int n = g.P.dofs();
  constexpr int kEdges = 3;
  std::vector<std::vector<double>> d(kEdges, std::vector<double>(static_cast<std::size_t>(n))), r = d;
  std::array<const double*, kEdges> dp{}, rp{};
  for (int e = 0; e < kEdges; ++e) {
    for (int k = 0; k < n; ++k) {
      d[e][static_cast<std::size_t>(k)] = 1e-4 * std::sin(0.37 * k + e);
      r[e][static_cast<std::size_t>(k)] = 1e-3 * std::cos(0.11 * k - e);
    }
    dp[e] = d[e].data();
    rp[e] = r[e].data();
  }
  std::array<PairForms, kEdges> f{};
  double sink = 0;
  for (auto _ : state) {
    if (state.range(1) == 0)
      for (int e = 0; e < kEdges; ++e) f[e] = g.P.pair_forms(dp[e], rp[e]);
    else
      g.P.pair_forms_many(dp.data(), rp.data(), kEdges, f.data());
    for (const PairForms& x : f) sink += x.dAd + x.rAd;
    benchmark::DoNotOptimize(sink);
  }
  state.counters["nodes"] = static_cast<double>(n / 3);
}

// The floor of BM_Tick/NODES/0: reading once, in one pass, as many bytes as that tick touches
// (StationCore::tick_bytes(): each array it reads or writes counted once), from a buffer that stays
// as warm as the tick's own arrays do between ticks (the same process, the same size). Read with
// 4 independent 4-lane sums so that the adds are not the limit. Args: nodes. Counters: bytes, and
// GB_per_s of the pass.
void BM_TickFloor(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  long bytes = 0;
  {
    StationCore st(w.cfg);
    bytes = st.tick_bytes();
  }
  const long n = (bytes / 8 + 15) / 16 * 16;
  std::vector<double> buf(static_cast<std::size_t>(n), 1.0);
  for (auto _ : state) {
    typedef double V4 __attribute__((vector_size(32)));
    V4 s0 = {}, s1 = {}, s2 = {}, s3 = {};
    const double* p = buf.data();
    for (long i = 0; i < n; i += 16) {
      V4 a, b, c, d;
      __builtin_memcpy(&a, p + i, sizeof a);
      __builtin_memcpy(&b, p + i + 4, sizeof b);
      __builtin_memcpy(&c, p + i + 8, sizeof c);
      __builtin_memcpy(&d, p + i + 12, sizeof d);
      s0 += a;
      s1 += b;
      s2 += c;
      s3 += d;
    }
    const V4 t = (s0 + s1) + (s2 + s3);
    double sum = t[0] + t[1] + t[2] + t[3];
    benchmark::DoNotOptimize(sum);
    benchmark::ClobberMemory();
  }
  state.counters["nodes"] = w.scene.nodes;
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["GB_per_s"] = benchmark::Counter(static_cast<double>(n) * 8e-9, benchmark::Counter::kIsIterationInvariantRate);
}

// Speed against accuracy: the iterative solve's tolerance ||b - A v_hat|| <= 10^-e ||b||.
// Args: nodes, e. Counters: CG iterations per tick (mean), the residual's energy per tick
// (-v_hat^T r T, counted in EnergyMonitor::solver_residual_J) in absolute value and relative to the
// controller port's energy per tick (eq. 14) in the same ticks (tools/bench/plot_tolerance.py charts them).
void BM_TickTolerance(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  w.cfg.solver.kind = StepSolverKind::kIterative;
  w.cfg.solver.relative_tolerance = std::pow(10.0, -static_cast<double>(state.range(1)));
  w.cfg.solver.max_iterations_cap = 1000;
  StationCore st(w.cfg);
  const int dofs = w.scene.dofs;
  const int nn = static_cast<int>(w.cfg.neighbors.size());
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  const RxBuffers rx(x, v, nn);
  std::int64_t seq = 0;
  auto one = [&] {
    const std::int64_t k = seq++;
    return drive(st, k, w.device_at(k), rx, nn);
  };
  for (int k = 0; k < 50; ++k) one();
  const double res0 = st.energy().solver_residual_J, ctrl0 = st.energy().controller_J;
  double iterations = 0, ticks = 0;
  for (auto _ : state) {
    auto out = one();
    iterations += st.solver_last_iterations();
    ticks += 1;
    benchmark::DoNotOptimize(out);
  }
  if (!st.in_contact()) state.SkipWithError("contact not active");
  const double res = std::abs(st.energy().solver_residual_J - res0) / ticks;
  const double ctrl = std::abs(st.energy().controller_J - ctrl0) / ticks;
  state.counters["nodes"] = w.scene.nodes;
  state.counters["tolerance"] = w.cfg.solver.relative_tolerance;
  state.counters["iterations_mean"] = iterations / ticks;
  state.counters["residual_J_per_tick"] = res;
  state.counters["controller_J_per_tick"] = ctrl;
  state.counters["residual_over_controller"] = ctrl > 0 ? res / ctrl : 0.0;
  state.counters["unconverged_ticks"] = static_cast<double>(st.solver_unconverged_ticks());
}

// The strawman (tools/bench/results/README.md): assemble and factor the dense (3n+3) system every tick.
void BM_DenseRefactorEveryTick(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  DenseStationReference st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  state.counters["nodes"] = w.scene.nodes;
}

// Worst-case tick: the neighbour set changes every tick while in contact (one neighbour's packets
// arrive every other tick and its index-delay bound is 0). Args: nodes, solver.
void BM_TickWorstCase(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  set_solver(w.cfg.solver, static_cast<int>(state.range(1)));
  w.cfg.neighbors[2].index_delay_bound_ticks = 0;
  StationCore st(w.cfg);
  const int dofs = w.scene.dofs;
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  const RxBuffers rx(x, v, 3);
  std::int64_t k = 0;
  std::uint64_t drops = 0;
  auto one = [&] {
    const auto out = drive(st, k, w.device_at(k), rx, 3, k % 2 == 0);  // neighbour 2 every other tick
    ++k;
    return out;
  };
  for (int i = 0; i < 50; ++i) one();
  double iterations = 0, contact = 0, ticks = 0;
  for (auto _ : state) {
    auto out = one();
    drops += (out.flags & kEdgeDropped) != 0;
    benchmark::DoNotOptimize(out);
    iterations += st.solver_last_iterations();
    contact += st.in_contact() ? 1 : 0;
    ticks += 1;
  }
  if (!st.in_contact()) state.SkipWithError("contact not active");
  station_counters(state, st, w);
  state.counters["edge_drop_ticks"] = static_cast<double>(drops);
  state.counters["iterations_mean"] = ticks > 0 ? iterations / ticks : 0;
  state.counters["contact_fraction"] = ticks > 0 ? contact / ticks : 0;
}

// Start-up to the first tick: scene, gains (lambda_max), station (matrix, solver, contact Schur
// data) and one tick. Args: nodes, neighbours.
void BM_StartupToFirstTick(benchmark::State& state) {
  for (auto _ : state) {
    World w(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
    StationCore st(w.cfg);
    auto out = drive_tick(st, TickDrive{0, 0, w.push_to, st.config().period_s}, [](auto&&) {});
    benchmark::DoNotOptimize(out);
    state.counters["nodes"] = w.scene.nodes;
    state.SetLabel(st.solver_name());
  }
}

// The paper-best scenario on the ~16k-node mesh (tools/bench/scenes/ball16k.msh, mm), ending after
// its first tick: what `sim --scene ... --scene-unit-m 0.001` and a station with that scene file build.
haptic::firmware::ScenarioSpec mesh_scenario() {
  haptic::firmware::ScenarioSpec spec = haptic::firmware::make_scenario("paper-best");
  spec.scene_file.path = std::string(HAPTIC_SOURCE_DIR) + "/tools/bench/scenes/ball16k.msh";
  spec.scene_file.unit_m = 0.001;
  spec.duration_s = spec.period_s;
  return spec;
}

// The simulator's start-up on the mesh: read it, build the scene, the gains and eq. (18) for every
// user, every station's core (4), then one tick; no output written.
void BM_SimStartupMesh(benchmark::State& state) {
  const haptic::firmware::ScenarioSpec spec = mesh_scenario();
  for (auto _ : state) {
    const haptic::firmware::BuiltScenario built = haptic::firmware::build_scenario(spec);
    const haptic::firmware::SimResult r = haptic::firmware::run_simulation(built, {});
    benchmark::DoNotOptimize(r.ticks);
    state.counters["nodes"] = built.scene.nodes;
    state.counters["stations"] = spec.users;
  }
}

// One station's start-up on the mesh (`haptic-station run` without its probing): the same scenario
// build, station 1's core (the hub: 3 neighbours), its first tick.
void BM_StationStartupMesh(benchmark::State& state) {
  const haptic::firmware::ScenarioSpec spec = mesh_scenario();
  for (auto _ : state) {
    const haptic::firmware::BuiltScenario built = haptic::firmware::build_scenario(spec);
    StationCore st(built.station_config(0));
    auto out = drive_tick(st, TickDrive{0, 0, built.vp_start[0], spec.period_s}, [](auto&&) {});
    benchmark::DoNotOptimize(out);
    state.counters["nodes"] = built.scene.nodes;
    state.SetLabel(st.solver_name());
  }
}

void run_ticks_child(StationCore& st, const World& w) {
  const int dofs = w.scene.dofs;
  const int nn = static_cast<int>(w.cfg.neighbors.size());
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  const RxBuffers rx(x, v, nn);
  for (std::int64_t k = 0; k < 100; ++k) drive(st, k, w.push_to, rx, nn);
}

long hwm_kB() {  // peak resident set since the last clear_refs "5"
  long kb = 0;
  if (FILE* f = std::fopen("/proc/self/status", "r")) {
    char line[256];
    while (std::fgets(line, sizeof line, f))
      if (std::sscanf(line, "VmHWM: %ld kB", &kb) == 1) break;
    std::fclose(f);
  }
  return kb;
}

long rss_kB() {
  long pages = 0, rss = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &rss) != 2) rss = 0;
    std::fclose(f);
  }
  return rss * (sysconf(_SC_PAGESIZE) / 1024);
}

// Peak memory of a station by neighbour count: a child process builds the world, returns its free
// heap pages to the kernel (malloc_trim), resets its RSS high-water mark (/proc/self/clear_refs,
// "5"), records its RSS, builds the station and runs 100 ticks with every neighbour fed; VmHWM minus
// the RSS before is the station's peak (start-up temporaries included). Args: nodes, neighbours,
// solver. Counters: station_peak_MB, and station_heap_MB, the heap the live station holds after
// the ticks (glibc mallinfo2: bytes in use, not pages). The time of this benchmark is not a figure.
void BM_StationPeakMemory(benchmark::State& state) {
  for (auto _ : state) {
    int fd[2];
    if (pipe(fd) != 0) {
      state.SkipWithError("pipe failed");
      return;
    }
    const pid_t pid = fork();
    if (pid == 0) {
      close(fd[0]);
      World w(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
      set_solver(w.cfg.solver, static_cast<int>(state.range(2)));
      // Hand the pages freed while building the world (lambda_max, scene temporaries) back to the
      // kernel: else the station's allocations reuse them, never raise the RSS, and its peak reads
      // as almost nothing (0.44 MB at 2945 nodes with 16 neighbours before this was done).
      malloc_trim(0);
      const std::size_t heap_before = mallinfo2().uordblks + mallinfo2().hblkhd;
      if (FILE* f = std::fopen("/proc/self/clear_refs", "w")) {
        std::fputs("5", f);
        std::fclose(f);
      }
      const long before = rss_kB();
      long heap_kB = 0;
      {
        StationCore st(w.cfg);
        run_ticks_child(st, w);
        heap_kB = static_cast<long>((mallinfo2().uordblks + mallinfo2().hblkhd - heap_before) / 1024);
      }
      const long peak[3] = {before, hwm_kB(), heap_kB};
      if (write(fd[1], peak, sizeof peak) != static_cast<ssize_t>(sizeof peak)) _exit(2);
      _exit(0);
    }
    close(fd[1]);
    long peak[3] = {0, 0, 0};
    const bool got = read(fd[0], peak, sizeof peak) == static_cast<ssize_t>(sizeof peak);
    close(fd[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    if (!got || !WIFEXITED(status) || WEXITSTATUS(status) != 0 || peak[1] <= 0) {
      state.SkipWithError("child failed (or no VmHWM in /proc/self/status)");
      return;
    }
    state.counters["station_peak_MB"] = static_cast<double>(peak[1] - peak[0]) / 1024.0;
    state.counters["station_heap_MB"] = static_cast<double>(peak[2]) / 1024.0;
  }
}

// One received packet of n nodes into a receive link, as the station hands it over: mode 0 offer()
// (the checked way in: size, finiteness, a copy: what the station did before the receive link read
// the packet in its RX buffer), mode 1 take() (the tick rules only, read in place).
void BM_RxLinkReceive(benchmark::State& state) {
  const int dofs = 3 * static_cast<int>(state.range(0));
  const bool in_place = state.range(1) == 1;
  std::vector<double> x0(static_cast<std::size_t>(dofs), 0.0), pkt(2 * static_cast<std::size_t>(dofs), 0.001);
  haptic::rt::RxLink link;
  link.init(dofs, x0.data(), nullptr);
  std::int64_t seq = 0;
  std::uint32_t released = 0;
  for (auto _ : state) {
    ++seq;
    const auto v = in_place ? link.take(seq, 0.0, pkt.data(), pkt.data() + dofs, static_cast<std::uint32_t>(seq % 2), released)
                            : link.offer(seq, 0.0, pkt.data(), pkt.data() + dofs, dofs);
    benchmark::DoNotOptimize(v);
    benchmark::DoNotOptimize(link.newest_x_hat());
    benchmark::ClobberMemory();
  }
  state.counters["payload_bytes"] = 2.0 * dofs * sizeof(double);
}

// The neighbour state check on one new packet of n nodes (rt/edge_monitor: check K, the tick's cost
// per packet and edge): mode 0 a fixed-step neighbour, consecutive sequences (the trapezoid at T);
// mode 1 a variable-step neighbour (T -+ 0.4 ms: the step fit's extra pass); mode 2 a fixed-step
// neighbour after a gap of 2 (a skipped period or a lost packet: the fit too). Two packets alternate
// (the values do not change the work), the edge admitted throughout.
void BM_StateCheck(benchmark::State& state) {
  const int dofs = 3 * static_cast<int>(state.range(0));
  const int mode = static_cast<int>(state.range(1));
  const std::size_t n = static_cast<std::size_t>(dofs);
  std::vector<double> x0(n, 0.0), v0(n, 0.01), own(n, 0.0), xa(n, 2e-5), xb(n, 4e-5), va(n, 0.01), vb(n, 0.011);
  for (std::size_t i = 0; i < n; ++i) va[i] += 1e-4 * static_cast<double>(i % 7);  // not all parallel: the fit's 2x2 is regular
  haptic::rt::EdgeMonitorParams p;
  p.kinematic_bound_m = 1.0;  // the packets alternate: a bound they never reach keeps the edge admitted (the usual path)
  const haptic::rt::StepBox box = mode == 1 ? haptic::rt::StepBox{0.0016, 0.0024} : haptic::rt::StepBox{0.002, 0.002};
  haptic::rt::EdgeMonitor m;
  m.init(1, dofs, 0.002, p, x0.data(), v0.data(), std::span<const haptic::rt::StepBox>(&box, 1));
  const std::int64_t gap = mode == 2 ? 2 : 1;
  std::int64_t seq = 0;
  for (auto _ : state) {
    seq += gap;
    const bool a = (seq / gap) % 2 == 0;
    benchmark::DoNotOptimize(m.observe(0, seq, seq, a ? xa.data() : xb.data(), a ? va.data() : vb.data(), 0, own.data()));
    benchmark::ClobberMemory();
  }
}

}  // namespace

BENCHMARK(BM_StateCheck)->ArgsProduct({{33, 3000, 16000}, {0, 1, 2}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RxLinkReceive)->ArgsProduct({{33, 16000}, {0, 1}})->Unit(benchmark::kNanosecond);
// 33 nodes: every solver and the strawman
BENCHMARK(BM_Tick)->ArgsProduct({{33}, {kDirectArg, kIterativeArg, kDenseOnceArg, kCholmodArg, kAutoArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DenseRefactorEveryTick)->Arg(33)->Unit(benchmark::kMicrosecond);
// crossover and large scenes
BENCHMARK(BM_Tick)->ArgsProduct({{300, 1000}, {kDirectArg, kIterativeArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Tick)->ArgsProduct({{300}, {kCholmodArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Tick)->ArgsProduct({{3000}, {kDirectArg, kIterativeArg, kDenseOnceArg, kCholmodArg, kAutoArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Tick)->ArgsProduct({{10000}, {kAutoArg}})->Unit(benchmark::kMicrosecond);
// 16,000 nodes (a 15,943-node lattice ball), its baselines, and every size's floor
BENCHMARK(BM_Tick)->ArgsProduct({{300, 1000, 16000}, {kAutoArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickEdgeCopies)->Arg(3000)->Arg(16000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickPspm)->Arg(3000)->Arg(16000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PspmForms)->ArgsProduct({{33, 3000, 16000}, {0, 1}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PspmFormsEdges)->ArgsProduct({{33, 3000, 16000}, {0, 1}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Tick)->ArgsProduct({{1000, 10000, 16000}, {kCholmodArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Tick)->ArgsProduct({{33, 300, 1000, 3000, 10000, 16000}, {kEigenCgArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickFloor)->Arg(33)->Arg(300)->Arg(1000)->Arg(3000)->Arg(10000)->Arg(16000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickTolerance)->ArgsProduct({{1000, 3000, 10000, 16000}, {4, 6, 8, 10, 12}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TickWorstCase)->ArgsProduct({{33, 3000}, {kAutoArg}})->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StartupToFirstTick)->Args({5000, 3})->Args({16000, 3})->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SimStartupMesh)->Iterations(1)->MeasureProcessCPUTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StationStartupMesh)->Iterations(1)->MeasureProcessCPUTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StationPeakMemory)->ArgsProduct({{3000}, {1, 6, 16}, {kAutoArg, kDirectArg}})->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StationPeakMemory)->ArgsProduct({{16000}, {3}, {kAutoArg, kCholmodArg}})->Iterations(1)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
