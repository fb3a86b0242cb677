// The linear step's solvers (rt/step_solver, rt/jacobi_cg), the over-bound action (an edge over
// its delay bound is a damper) and the memory that no longer depends on the neighbour count.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "rt/jacobi_cg.hpp"
#include "rt/multi_term_operator.hpp"
#include "rt/station.hpp"
#include "rt/step_solver.hpp"
#include "tests/rt/fixtures.hpp"
#include "tests/support/ball_station.hpp"

using namespace haptic;
using namespace haptic::rt;
using haptic::test::PaperWorld;

TEST_GROUP(StepSolver){};

TEST(StepSolver, jacobi_cg_reaches_the_tolerance_within_its_proven_cap_for_three_interleaved_rhs) {
  const auto& w = PaperWorld::get();
  const SpatialMatrix I = SpatialMatrix::identity(w.scene.nodes);
  const SpatialMatrix A = linear_combination({{50.0, &I}, {0.001, &w.scene.K_int}, {0.003, &w.gains.P}});
  const SparseColMajor As(A.S);
  JacobiCg cg(As, 3, 1e-12);
  CHECK_TRUE(cg.condition_bound() < 1.2);
  const int n = w.scene.nodes;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> B = Eigen::MatrixXd::Random(n, 3), X(n, 3), R(n, 3);
  X.setZero();
  const int it = cg.solve(B.data(), X.data(), R.data(), 3, 1e-12, cg.iteration_cap());
  CHECK_TRUE(it <= cg.iteration_cap());
  const Eigen::MatrixXd dense = Eigen::MatrixXd(As);
  const Eigen::MatrixXd true_r = Eigen::MatrixXd(B) - dense * Eigen::MatrixXd(X);
  CHECK_TRUE(true_r.norm() <= 1e-12 * B.norm() * 1.01);
  CHECK_TRUE((true_r - Eigen::MatrixXd(R)).norm() < 1e-14 * B.norm());  // returned residual is b - A x
}

namespace {

// x and b random (width interleaved columns); bits of the solver's initial residual b - A x and of
// multiply()'s A x against Eigen's column-ordered product (ascending column within each row).
void check_full_product_bits(const SparseColMajor& As, JacobiCg& cg, int width, unsigned seed) {
  const int n = static_cast<int>(As.rows());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> x(static_cast<std::size_t>(n) * width), b(x.size()), r(x.size()), y(x.size());
  for (auto& e : x) e = U(rng);
  for (auto& e : b) e = U(rng);
  const std::vector<double> x0 = x;
  CHECK_EQUAL(1, cg.solve(b.data(), x.data(), r.data(), width, 1e-8, 0));  // initial pass only
  cg.multiply(x0.data(), y.data(), width);
  for (int c = 0; c < width; ++c) {
    Eigen::VectorXd xc(n), bc(n);
    for (int i = 0; i < n; ++i) {
      xc[i] = x0[static_cast<std::size_t>(i * width + c)];
      bc[i] = b[static_cast<std::size_t>(i * width + c)];
    }
    const Eigen::VectorXd ax = As * xc;
    const Eigen::VectorXd res = bc - ax;
    for (int i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i * width + c);
      if (std::memcmp(&r[k], &res[i], sizeof(double)) != 0 || std::memcmp(&y[k], &ax[i], sizeof(double)) != 0)
        FAIL(("row " + std::to_string(i) + " column " + std::to_string(c) + " differs from the full product").c_str());
    }
  }
}

}  // namespace

// The CG stores A as its diagonal plus strict upper triangle with 16-bit column offsets (0.45 of
// the full rows' bytes). A pass adds row i's terms in ascending column order, the lower ones through
// the ring of partial sums, as the full rows do, so A x keeps the full product's bits: checked
// against Eigen's A x through the initial residual b - A x and multiply(), for widths 3 and 1, in
// the AVX and the scalar build, on the 2945-node ball (rows reaching the last node run scalar);
// a whole solve gives the same bits in both builds.
// A band past 16 bits keeps the full rows (a 70,000-row chain closed by a corner entry).
TEST(StepSolver, the_upper_triangle_storage_gives_the_full_products_bits_and_keeps_the_full_rows_past_16_bit_offsets) {
  const Scene s = build_scene(make_lattice_ball(3000, 0.05), SceneParams{});
  const EdgeGains g = paper_edge_gains(s);
  const SpatialMatrix I = SpatialMatrix::identity(s.nodes);
  const SpatialMatrix A = linear_combination({{50.0, &I}, {0.001, &s.K_int}, {0.003, &g.P}});
  const SparseColMajor As(A.S);
  for (int width : {3, 1})
    for (bool avx : {true, false}) {
      JacobiCg cg(As, width, 1e-8);
      CHECK_TRUE(cg.upper_storage());
      CHECK_TRUE(cg.band() > 0 && cg.band() < s.nodes);
      if (cg.use_avx(avx) != avx) {
        printf("\n  SKIPPED: this CPU has no AVX, only the scalar build runs\n");
        continue;
      }
      check_full_product_bits(As, cg, width, static_cast<unsigned>(10 * width + avx));
    }
  for (int width : {3, 1}) {  // a whole solve: the AVX build's x, r and iteration count are the scalar's
    JacobiCg wide(As, width, 1e-8), scalar(As, width, 1e-8);
    if (!wide.use_avx(true)) break;
    scalar.use_avx(false);
    std::mt19937 rng(static_cast<unsigned>(width));
    std::uniform_real_distribution<double> U(-1, 1);
    const auto m = static_cast<std::size_t>(s.nodes * width);
    std::vector<double> b(m), xw(m, 0.0), xs(m, 0.0), rw(m), rs(m);
    for (auto& e : b) e = U(rng);
    const int it = wide.solve(b.data(), xw.data(), rw.data(), width, 1e-12, 100);
    CHECK_TRUE(it >= 3 && it <= 100);
    CHECK_EQUAL(it, scalar.solve(b.data(), xs.data(), rs.data(), width, 1e-12, 100));
    CHECK_EQUAL(0, std::memcmp(xw.data(), xs.data(), sizeof(double) * m));
    CHECK_EQUAL(0, std::memcmp(rw.data(), rs.data(), sizeof(double) * m));
  }
  const int n = 70000;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 4.0);
    if (i + 1 < n) {
      t.emplace_back(i, i + 1, -1.0);
      t.emplace_back(i + 1, i, -1.0);
    }
  }
  t.emplace_back(0, n - 1, -0.5);
  t.emplace_back(n - 1, 0, -0.5);
  SparseColMajor chain(n, n);
  chain.setFromTriplets(t.begin(), t.end());
  JacobiCg wide(chain, 3, 1e-10);
  CHECK_FALSE(wide.upper_storage());
  check_full_product_bits(chain, wide, 3, 7);
  std::vector<double> b(static_cast<std::size_t>(n) * 3, 1.0), x(b.size(), 0.0), r(b.size());
  CHECK_TRUE(wide.solve(b.data(), x.data(), r.data(), 3, 1e-10, wide.iteration_cap()) <= wide.iteration_cap());
  chain.coeffRef(0, 1) = -0.9;  // one stored triangle serves both: a non-symmetric A is refused
  CHECK_THROWS(std::invalid_argument, JacobiCg(chain, 1, 1e-8));
}

TEST(StepSolver, iterative_is_refused_when_the_cap_cannot_meet_the_tolerance_and_auto_falls_back) {
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 4, {1}, 10, test::tetra_dirs()[0]);
  cfg.solver.kind = StepSolverKind::kIterative;
  cfg.solver.max_iterations_cap = 1;
  try {
    StationCore s(cfg);
    FAIL("expected the iterative solver to be refused");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("max_iterations_cap", e.what());
  }
  cfg.solver.kind = StepSolverKind::kAuto;
  cfg.solver.iterative_from_rows = 0;
  StationCore s(cfg);
  STRCMP_EQUAL("direct", s.solver_name());
  CHECK_THROWS(std::invalid_argument, parse_step_solver_kind("cg"));
}

TEST(StepSolver, one_solver_of_the_same_size_at_any_degree_up_to_16) {
  const auto& w = PaperWorld::get();
  std::vector<int> peers16;
  for (int p = 1; p <= 16; ++p) peers16.push_back(p);
  for (StepSolverKind kind : {StepSolverKind::kDirect, StepSolverKind::kIterative}) {
    auto c1 = w.station(0, 17, {1}, 10, test::tetra_dirs()[0]);
    auto c16 = w.station(0, 17, peers16, 10, test::tetra_dirs()[0]);
    c1.solver.kind = c16.solver.kind = kind;
    StationCore s1(c1), s16(c16);
    CHECK_EQUAL(s1.solver_stored_doubles(), s16.solver_stored_doubles());
  }
  std::vector<int> peers17 = peers16;
  peers17.push_back(17);
  CHECK_THROWS(std::invalid_argument, StationCore{w.station(0, 18, peers17, 10, test::tetra_dirs()[0])});
}

TEST_GROUP(OverBound){};

TEST(OverBound, an_edge_over_its_bound_is_a_damper_its_controller_energy_never_increases) {
  // Both neighbours send stale data (index delay above the bound 0 from tick 1 on) far from this
  // copy: if the held data were used, the P-coupling would pull and inject energy.
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 3, {1, 2}, 0.0, test::tetra_dirs()[0], 0);
  cfg.vp_initial_position_m = Eigen::Vector3d(1, 1, 1);  // no contact
  StationCore st(cfg);
  Eigen::VectorXd far = w.scene.x_d, v0 = Eigen::VectorXd::Zero(w.scene.dofs);
  far.array() += 0.01;
  for (int n = 0; n < 2; ++n) st.rx(n).offer(0, 0, far.data(), v0.data(), w.scene.dofs);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd x = w.scene.x_d, v(w.scene.dofs);
  for (int i = 0; i < w.scene.dofs; ++i) v[i] = 0.1 * u(rng);
  st.set_state(x, v);
  st.tick(Eigen::Vector3d(1, 1, 1));  // k = 0: the packet is within the bound
  double prev = st.energy().controller_J;
  int dissipating = 0;
  for (int k = 1; k < 200; ++k) {
    const auto out = st.tick(Eigen::Vector3d(1, 1, 1));
    CHECK_TRUE(out.flags & kEdgeDropped);
    const double now = st.energy().controller_J;
    CHECK_TRUE(now <= prev + 1e-15);
    dissipating += now < prev;
    prev = now;
  }
  CHECK_TRUE(dissipating > 150);
}

TEST_GROUP(SolverEnergy){};

TEST(SolverEnergy, eq12_balance_is_exact_with_a_loose_iterative_solve_when_its_residual_is_counted) {
  // B = 0: E(end) - E(0) = port + controller + solver residual energy, to roundoff, although the
  // solve stops at 5e-4 relative residual (that term alone is far above the check's tolerance).
  const auto& w = PaperWorld::get();
  auto cfg = w.station(0, 3, {1, 2}, 12.0, test::tetra_dirs()[1]);
  cfg.solver.kind = StepSolverKind::kIterative;
  cfg.solver.relative_tolerance = 5e-4;
  StationCore st(cfg);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd xj(w.scene.dofs), vj(w.scene.dofs);
  const Eigen::Vector3d p0 = cfg.vp_initial_position_m, in = w.face_inward(test::tetra_dirs()[1]);
  for (int k = 0; k < 3000; ++k) {
    for (int n = 0; n < 2; ++n) {
      if (u(rng) < 0) continue;
      for (int i = 0; i < w.scene.dofs; ++i) {
        xj[i] = w.scene.x_d[i] + 2e-3 * u(rng);
        vj[i] = 0.05 * u(rng);
      }
      st.rx(n).offer(k, 0, xj.data(), vj.data(), w.scene.dofs);
    }
    st.tick(p0 + (0.01 + 0.01 * u(rng)) * in + 0.003 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
  }
  const auto& e = st.energy();
  const double Eend = w.scene.energy(st.x(), st.v()) / cfg.users;
  const double supplied = e.port_J + e.controller_J + e.solver_residual_J;
  const double flows = std::abs(e.port_J) + std::abs(e.controller_J);
  CHECK_TRUE(std::abs(e.solver_residual_J) > 1e-6 * flows);  // the residual term matters here
  CHECK_TRUE(std::abs(Eend - supplied) < 1e-9 * flows);
}

TEST_GROUP(WarmStart){};

// Four users on a lattice ball, three neighbours with the paper's gains, the iterative solver, and
// the push 1 cm into the face towards (1, 1, 1) (returned in push).
// The iterative solve starts from the linear extrapolation g = 2 y0(k-1) - y0(k-2) of the last two
// solutions of A y0 = b (before the contact correction), improved by one Jacobi step
// g += D^{-1}(b - A g) whose A g comes from the kept b(k-1) - r(k-1) and b(k-2) - r(k-2) (no
// matvec). On a 1021-node ball pushed into contact while three neighbours send their state every
// tick, the CG needs 3.12 iterations per tick to 1e-10 over ticks 100-399; from the extrapolation
// alone it needed 4.12, from the last v_hat (the guess before, which carries the contact
// correction) 4.91. The check sits between 3.12 and 4.12. Iteration counts are deterministic (no
// timing).
TEST(WarmStart, extrapolated_guess_with_a_jacobi_step_needs_a_cg_iteration_less_than_extrapolation_alone_on_a_1021_node_ball) {
  test::BallStation ball(1000);
  ball.cfg.solver.kind = StepSolverKind::kIterative;
  const Scene& scene = ball.scene;
  const Eigen::Vector3d push = ball.push;
  StationConfig cfg = ball.cfg;
  cfg.solver.relative_tolerance = 1e-10;
  StationCore st(cfg);
  std::vector<double> x(scene.x_d.data(), scene.x_d.data() + scene.dofs), v(static_cast<std::size_t>(scene.dofs), 1e-4);
  long iterations = 0;
  for (int k = 0; k < 400; ++k) {
    for (int n = 0; n < 3; ++n) st.rx(n).offer(k, 0, x.data(), v.data(), scene.dofs);
    st.tick(push);
    if (k >= 100) iterations += st.solver_last_iterations();
  }
  CHECK_TRUE(st.in_contact());
  CHECK_EQUAL(0, static_cast<int>(st.solver_unconverged_ticks()));
  const double mean = static_cast<double>(iterations) / 300.0;
  printf("\n  warm start: %.2f CG iterations per tick (1021 nodes, 1e-10)\n", mean);
  CHECK_TRUE(mean <= 3.6);
}

// When one edge goes over its delay bound every other tick (the benchmark's worst case), b
// alternates between two patterns; the linear extrapolation then mixes them and the CG needs an
// iteration more. The warm start detects the alternation from the active-neighbour masks and
// starts from the solution two ticks back (the same pattern) with its Jacobi step. Iterations at
// the default tolerance over ticks 100-299 on a 1021-node ball: 2.67 per tick, 3.00 from the
// extrapolation (measured 2026-12-01); the check sits between the two.
TEST(WarmStart, an_alternating_neighbour_set_costs_fewer_iterations_with_the_guess_from_two_ticks_back) {
  test::BallStation ball(1000);
  ball.cfg.solver.kind = StepSolverKind::kIterative;
  const Scene& scene = ball.scene;
  const Eigen::Vector3d push = ball.push;
  StationConfig cfg = ball.cfg;
  cfg.neighbors[2].index_delay_bound_ticks = 0;
  StationCore st(cfg);
  std::vector<double> x(scene.x_d.data(), scene.x_d.data() + scene.dofs), v(static_cast<std::size_t>(scene.dofs), 1e-4);
  long iterations = 0, drops = 0;
  for (int k = 0; k < 300; ++k) {
    for (int n = 0; n < 2; ++n) st.rx(n).offer(k, 0, x.data(), v.data(), scene.dofs);
    if (k % 2 == 0) st.rx(2).offer(k, 0, x.data(), v.data(), scene.dofs);
    const auto out = st.tick(k, push + 0.005 * std::sin(2.0 * M_PI * k / 250.0) * scene.mesh.face_normal(0));
    if (k >= 100) {
      iterations += st.solver_last_iterations();
      drops += (out.flags & kEdgeDropped) != 0;
    }
  }
  CHECK_TRUE(st.in_contact());
  CHECK_EQUAL(100, static_cast<int>(drops));  // the set alternates: every other tick drops the edge
  const double mean = static_cast<double>(iterations) / 200.0;
  printf("\n  alternating set: %.2f CG iterations per tick (1021 nodes, default tolerance)\n", mean);
  CHECK_TRUE(mean <= 2.85);  // 2.67 with the guess from two ticks back, 3.00 with the extrapolation
}

// The station's own lane kernels (the post-solve pass and the warm start's Jacobi step, one node in
// a 4-lane vector) run an AVX build where the CPU has it. Replay needs the same bits on every CPU:
// two stations fed the same ticks, one on the baseline build, must agree bit for bit in state,
// predicted state and every energy, through contact and neighbours that skip packets.
TEST(WarmStart, the_station_kernels_avx_build_gives_the_baseline_builds_bits) {
  test::BallStation ball(1000);
  ball.cfg.solver.kind = StepSolverKind::kIterative;
  const Scene& scene = ball.scene;
  const Eigen::Vector3d push = ball.push;
  const StationConfig cfg = ball.cfg;
  StationCore wide(cfg), base(cfg);
  if (!wide.use_avx(true)) {
    printf("\n  SKIPPED: this CPU has no AVX, only the baseline build runs\n");
    return;
  }
  CHECK_FALSE(base.use_avx(false));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> x(static_cast<std::size_t>(scene.dofs)), v(x.size());
  for (int k = 0; k < 80; ++k) {
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] = scene.x_d[static_cast<long>(i)] + 1e-4 * U(rng);
      v[i] = 1e-3 * U(rng);
    }
    for (int n = 0; n < 3; ++n)
      if (n != 2 || k % 3 == 0) {  // neighbour 2 skips two packets in three: held, not fresh
        wide.rx(n).offer(k, 0, x.data(), v.data(), scene.dofs);
        base.rx(n).offer(k, 0, x.data(), v.data(), scene.dofs);
      }
    wide.tick(push);
    base.tick(push);
  }
  CHECK_TRUE(wide.in_contact());
  const auto bytes = sizeof(double) * static_cast<std::size_t>(scene.dofs);
  CHECK_EQUAL(0, std::memcmp(wide.x().data(), base.x().data(), bytes));
  CHECK_EQUAL(0, std::memcmp(wide.v().data(), base.v().data(), bytes));
  CHECK_EQUAL(0, std::memcmp(wide.x_hat(), base.x_hat(), bytes));
  CHECK_EQUAL(0, std::memcmp(wide.v_hat(), base.v_hat(), bytes));
  const EnergyMonitor& a = wide.energy();
  const EnergyMonitor& b = base.energy();
  CHECK_TRUE(a.controller_J == b.controller_J && a.port_J == b.port_J && a.vo_J == b.vo_J &&
             a.solver_residual_J == b.solver_residual_J && a.device_port_J == b.device_port_J);
  CHECK_TRUE(a.controller_J != 0.0 && a.solver_residual_J != 0.0);
}

TEST_GROUP(MultiTerm){};

// The right-hand side's fused pass [M, K, P, D] stores one off-diagonal value per block (K's and the
// paper's P's off-diagonals are multiples of K_int's) and runs an AVX build on CPUs that have it.
// Replay needs the same bits on every machine: the AVX build must equal the scalar one exactly, on
// random inputs, at 33 and 2945 nodes (rows that reach the last node stay scalar).
TEST(MultiTerm, the_avx_kernel_gives_the_scalar_kernels_bits_and_one_value_is_stored_per_block) {
  for (int nodes : {33, 3000}) {
    const Scene s = build_scene(nodes == 33 ? make_paper_ball(0.05) : make_lattice_ball(nodes, 0.05), SceneParams{});
    const EdgeGains g = paper_edge_gains(s);
    MultiTermOperator op({&s.M, &s.K, &g.P, &g.D});
    CHECK_TRUE(op.shared_values());
    if (!op.use_avx(true)) {
      printf("\n  SKIPPED: this CPU has no AVX, only the scalar kernel runs\n");
      return;
    }
    std::mt19937 rng(static_cast<unsigned>(nodes));
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<std::vector<double>> u(4, std::vector<double>(static_cast<std::size_t>(s.dofs)));
    for (auto& v : u)
      for (auto& e : v) e = 1e-3 * U(rng);
    const double* up[4] = {u[0].data(), u[1].data(), u[2].data(), u[3].data()};
    const double to_y[4] = {1000.0, -0.25, -1.0, 1.0};
    std::vector<double> wide(static_cast<std::size_t>(s.dofs)), scalar(wide.size());
    double qw[MultiTermOperator::kMaxTerms] = {}, qs[MultiTermOperator::kMaxTerms] = {};
    op.apply(up, to_y, nullptr, wide.data(), nullptr, qw);
    op.use_avx(false);
    op.apply(up, to_y, nullptr, scalar.data(), nullptr, qs);
    CHECK_EQUAL(0, std::memcmp(wide.data(), scalar.data(), sizeof(double) * wide.size()));
    CHECK_EQUAL(0, std::memcmp(qw, qs, sizeof(double) * 4));
  }
}

// The tick's fused right-hand-side pass (apply_consensus) forms the terms' inputs inside the pass
// (x - x_d and na x - sum x_hat_j a band ahead in a ring, v and sum v_hat_j row by row). It must
// give the two-pass form's right-hand side (sum_group's inputs, then apply) bit for bit, in its AVX
// and its baseline build alike (replay needs the same bits on every CPU), and the same energies.
TEST(MultiTerm, the_fused_consensus_pass_gives_the_two_pass_right_hand_side_bit_for_bit) {
  for (int nodes : {33, 3000}) {
    const Scene s = build_scene(nodes == 33 ? make_paper_ball(0.05) : make_lattice_ball(nodes, 0.05), SceneParams{});
    const EdgeGains g = paper_edge_gains(s);
    MultiTermOperator op({&s.M, &s.K, &g.P, &g.D});
    CHECK_TRUE(op.fuses_consensus());
    CHECK_TRUE(op.ring_nodes() < s.nodes || nodes == 33);  // a band, not the whole object
    const auto n = static_cast<std::size_t>(s.dofs);
    std::mt19937 rng(static_cast<unsigned>(nodes) + 7);
    std::uniform_real_distribution<double> U(-1, 1);
    auto random_vec = [&](double scale, const double* base) {
      std::vector<double> r(n);
      for (std::size_t i = 0; i < n; ++i) r[i] = (base ? base[i] : 0.0) + scale * U(rng);
      return r;
    };
    const std::vector<double> x = random_vec(1e-3, s.x_d.data()), v = random_vec(1e-2, nullptr);
    std::vector<std::vector<double>> xj, vj;
    for (int k = 0; k < 3; ++k) {
      xj.push_back(random_vec(1e-3, s.x_d.data()));
      vj.push_back(random_vec(1e-2, nullptr));
    }
    // three active neighbours, two of them fresh
    const double* xs[3] = {xj[0].data(), xj[1].data(), xj[2].data()};
    const double* vs[2] = {vj[0].data(), vj[2].data()};
    std::vector<double> d(n), sx(n), sv(n);
    for (std::size_t i = 0; i < n; ++i) {
      d[i] = x[i] - s.x_d[static_cast<long>(i)];
      double a = 3 * x[i];
      for (const double* p : xs) a -= p[i];
      sx[i] = a;
      double b = 0;
      for (const double* p : vs) b += p[i];
      sv[i] = b;
    }
    const double* u[4] = {v.data(), d.data(), sx.data(), sv.data()};
    const double to_y[4] = {2.0 / (4 * 0.002), -0.25, -1.0, 1.0};
    std::vector<double> two_pass(n), fused(n), fused_base(n);
    double q2[MultiTermOperator::kMaxTerms] = {}, qf[MultiTermOperator::kMaxTerms] = {}, qb[MultiTermOperator::kMaxTerms] = {};
    op.apply(u, to_y, nullptr, two_pass.data(), nullptr, q2);
    MultiTermOperator::ConsensusInputs in;
    in.v = v.data();
    in.x = x.data();
    in.x_d = s.x_d.data();
    in.xs = xs;
    in.na = 3;
    in.vs = vs;
    in.nf = 2;
    const bool avx = op.use_avx(true);
    op.apply_consensus(in, to_y, fused.data(), qf);
    op.use_avx(false);
    op.apply_consensus(in, to_y, fused_base.data(), qb);
    CHECK_EQUAL(0, std::memcmp(two_pass.data(), fused.data(), sizeof(double) * n));
    CHECK_EQUAL(0, std::memcmp(fused.data(), fused_base.data(), sizeof(double) * n));
    CHECK_EQUAL(0, std::memcmp(qf, qb, sizeof(double) * 4));
    for (int t = 0; t < 4; ++t) DOUBLES_EQUAL(q2[t], qf[t], 1e-12 * std::abs(q2[t]));
    if (!avx) printf("\n  note: this CPU has no AVX; both runs used the baseline build\n");
  }
}
