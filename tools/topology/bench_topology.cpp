// Optimizer timing (Google Benchmark): one eq. (27) evaluation by each method on the paper's
// worst-case lifted size, and the whole topology search for N = 16, 32, 64 synthetic users.
// Results kept in tools/bench/results/topology_bench.json (see tools/topology/README.md).
#include <benchmark/benchmark.h>

#include "tools/topology/topology.hpp"

namespace topo = haptic::topology;

namespace {

void BM_ScorePaperGraph(benchmark::State& state, topo::EigenMethod method) {
  const Eigen::MatrixXd d = topo::paper_delay_matrix_ms();
  const topo::Graph g = topo::parse_graph_1based("1-4,2-3,2-4", 4);  // lifted size 484
  topo::SpectrumOptions opt;
  opt.method = method;
  opt.self_weight = 0.5;
  double lambda = 0;
  int size = 0;
  for (auto _ : state) {
    const topo::GraphScore s = topo::score_graph(g, d, 0.002, topo::paper_gains(4, {}), opt);
    lambda = s.lambda_next_abs;
    size = s.lifted_size;
    benchmark::ClobberMemory();  // (DoNotOptimize(double&) corrupts the value with GCC 12 + benchmark 1.7.1)
  }
  state.counters["lambda_next_abs"] = lambda;
  state.counters["lifted_size"] = size;
}
BENCHMARK_CAPTURE(BM_ScorePaperGraph, dense, topo::EigenMethod::Dense)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ScorePaperGraph, power, topo::EigenMethod::Power)->Unit(benchmark::kMillisecond);

void BM_Search(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  topo::SyntheticMap map;
  map.seed = 1;
  const Eigen::MatrixXd d = topo::synthetic_delays_ms(n, map, nullptr);
  topo::SpectrumOptions opt;
  topo::SearchOptions so;
  so.degree_cap = 4;
  so.max_evaluations = 500;
  topo::SearchResult r;
  for (auto _ : state) {
    r = topo::search_topology(d, 0.002, topo::paper_gains(n, {}), opt, so);
    benchmark::ClobberMemory();
  }
  state.counters["users"] = n;
  state.counters["evaluations"] = r.evaluations;
  state.counters["improvements"] = r.improvements;
  state.counters["seed_lambda"] = r.seed_score.lambda_next_abs;
  state.counters["best_lambda"] = r.best_score.lambda_next_abs;
  state.counters["lifted_size"] = r.best_score.lifted_size;
}
BENCHMARK(BM_Search)->Arg(16)->Arg(32)->Arg(64)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
