// Google Benchmark cost table of the study: one step + felt-force output of each reference
// integrator on the push problem (tools/study/model_selector.hpp) for 33..3065 nodes, and of the modal
// reduced model (r modes, static correction). JSON kept in tools/study/results/bench_study.json.
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "tools/study/integrators.hpp"
#include "tools/study/modal.hpp"
#include "tools/study/model_selector.hpp"

using namespace haptic::rt;
using namespace haptic::study;

namespace {
const PushProblem& problem(int nodes) {
  static std::map<int, std::unique_ptr<PushProblem>> cache;
  auto& p = cache[nodes];
  if (!p) p = std::make_unique<PushProblem>(make_push_problem(make_ball_mesh(nodes, 0.05), PushProblemParams{}));
  return *p;
}

void BM_full_step(benchmark::State& state) {
  const auto method = static_cast<Integrator>(state.range(0));
  const auto& p = problem(static_cast<int>(state.range(1)));
  LinearIntegrator integ(p.model, method, 0.002);
  double sink = 0;
  for (auto _ : state) {
    integ.step();
    sink += integ.output(p.felt_w);
    if (integ.time_s() > 1.0) integ.reset();
    benchmark::DoNotOptimize(sink);
  }
  state.SetLabel(std::string(integrator_name(method)) + " n=" + std::to_string(p.model.nodes));
}

void BM_modal_step(benchmark::State& state) {
  const auto& p = problem(static_cast<int>(state.range(1)));
  static std::map<int, std::unique_ptr<ModalBasis>> bases;
  auto& b = bases[p.model.nodes];
  if (!b) b = std::make_unique<ModalBasis>(compute_modes(p.model));
  ModalReducedModel red(*b, p.model, static_cast<int>(state.range(0)), 0.002, true, p.felt_w);
  double sink = 0;
  for (auto _ : state) {
    red.step();
    sink += red.output();
    benchmark::DoNotOptimize(sink);
  }
  state.SetLabel("modal+sc r=" + std::to_string(state.range(0)) + " n=" + std::to_string(p.model.nodes));
}
}  // namespace

BENCHMARK(BM_full_step)
    ->ArgsProduct({{static_cast<long>(Integrator::kNpmi), static_cast<long>(Integrator::kExplicitEuler),
                    static_cast<long>(Integrator::kSemiImplicitEuler), static_cast<long>(Integrator::kBackwardEuler),
                    static_cast<long>(Integrator::kRk4)},
                   {33, 100, 300, 1000, 3100}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_modal_step)->ArgsProduct({{3, 25, 100, 400}, {1000}})->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
