// Tick cost of one station: the precomputed sparse step against a dense baseline that assembles
// and factors the same (3n+3) system every tick, and the sparse tick against scene size.
// Each tick includes what DESIGN.md's tick does in rt/: feeding the neighbours' newest packets
// to the receive bookkeeping, the solve with contact active, energies and the state update.
#include <benchmark/benchmark.h>

#include <memory>
#include <vector>

#include "tests/support/dense_reference.hpp"
#include "rt/gains.hpp"
#include "rt/scene.hpp"
#include "rt/sparse_ldlt.hpp"
#include "rt/station.hpp"

using namespace haptic::rt;

namespace {

struct World {
  Scene scene;
  EdgeGains gains;
  StationConfig cfg;
  Eigen::Vector3d push_to;
  explicit World(int nodes)
      : scene(build_scene(nodes == 33 ? make_paper_ball(0.05) : make_lattice_ball(nodes, 0.05), SceneParams{})),
        gains(paper_edge_gains(scene)) {
    const int f = scene.mesh.face_towards(Eigen::Vector3d(1, 1, 1));
    const auto& face = scene.mesh.surface[static_cast<std::size_t>(f)];
    cfg.users = 4;
    cfg.scene = &scene;
    cfg.damping_Ns_per_m = 30.45;
    for (int p = 1; p <= 3; ++p) cfg.neighbors.push_back({p, &gains, 1 << 30});
    cfg.contact_nodes = {face[0], face[1], face[2]};
    cfg.vp_initial_position_m = scene.mesh.face_center(f);
    push_to = cfg.vp_initial_position_m - 0.01 * scene.mesh.face_normal(f);
  }
};

template <class Station>
void run_ticks(benchmark::State& state, Station& st, const World& w) {
  const int dofs = w.scene.dofs;
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  std::int64_t seq = 0;
  // settle into contact first
  for (int k = 0; k < 50; ++k) {
    for (int n = 0; n < 3; ++n) st.rx(n).offer(seq, 0, x.data(), v.data(), dofs);
    ++seq;
    st.tick(w.push_to);
  }
  for (auto _ : state) {
    for (int n = 0; n < 3; ++n) st.rx(n).offer(seq, 0, x.data(), v.data(), dofs);
    ++seq;
    auto out = st.tick(w.push_to);
    benchmark::DoNotOptimize(out);
  }
}

void BM_SparseTick(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  StationCore st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  state.counters["nodes"] = w.scene.nodes;
  state.counters["factor_nnz"] = static_cast<double>(st.factor_nonzeros());
  state.counters["factorizations"] = st.factorizations();
}

void BM_DenseBaselineTick(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  DenseStationReference st(w.cfg);
  run_ticks(state, st, w);
  if (!st.in_contact()) state.SkipWithError("contact not active");
  state.counters["nodes"] = w.scene.nodes;
}

// Worst-case tick: the neighbour set changes every tick while in contact (one neighbour's
// packets arrive every other tick and its index-delay bound is 0), so the Schur data are rebuilt
// from the other factorization on every tick: one extra sparse solve per contact unit.
void BM_SparseTickWorstCase(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  w.cfg.neighbors[2].index_delay_bound_ticks = 0;
  StationCore st(w.cfg);
  const int dofs = w.scene.dofs;
  std::vector<double> x(w.scene.x_d.data(), w.scene.x_d.data() + dofs), v(static_cast<std::size_t>(dofs), 1e-4);
  std::int64_t k = 0;
  std::uint64_t drops = 0;
  auto one = [&] {
    for (int n = 0; n < 2; ++n) st.rx(n).offer(k, 0, x.data(), v.data(), dofs);
    if (k % 2 == 0) st.rx(2).offer(k, 0, x.data(), v.data(), dofs);
    ++k;
    return st.tick(w.push_to);
  };
  for (int i = 0; i < 50; ++i) one();
  for (auto _ : state) {
    auto out = one();
    drops += (out.flags & kEdgeDropped) != 0;
    benchmark::DoNotOptimize(out);
  }
  if (!st.in_contact()) state.SkipWithError("contact not active");
  state.counters["nodes"] = w.scene.nodes;
  state.counters["edge_drop_ticks"] = static_cast<double>(drops);
}

// The sparse triangular solves alone (3 interleaved right-hand sides), the floor of the tick.
void BM_FactorSolveOnly(benchmark::State& state) {
  World w(static_cast<int>(state.range(0)));
  const SpatialMatrix I = SpatialMatrix::identity(w.scene.nodes);
  const SpatialMatrix A = linear_combination({{40.0, &I}, {0.00025, &w.scene.K}, {0.003, &w.gains.P}});
  const SparseLdlt F{SparseColMajor(A.S)};
  Eigen::VectorXd x = Eigen::VectorXd::Random(w.scene.dofs), scratch(w.scene.dofs);
  for (auto _ : state) {
    F.solve_in_place(x.data(), 3, scratch.data());
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["factor_nnz"] = static_cast<double>(F.factor_nonzeros());
}

}  // namespace

BENCHMARK(BM_FactorSolveOnly)->Arg(33)->Arg(3000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SparseTick)->Arg(33)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DenseBaselineTick)->Arg(33)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SparseTick)->Arg(100)->Arg(300)->Arg(1000)->Arg(3000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DenseBaselineTick)->Arg(300)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SparseTickWorstCase)->Arg(33)->Arg(3000)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
