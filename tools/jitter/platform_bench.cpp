// bench_platform: cost of what the tick calls from platform/ (Google Benchmark). Results are
// kept in tools/bench/results/bench_platform.json.
#include <benchmark/benchmark.h>

#include <atomic>
#include <memory>

#include "platform/gpio.hpp"
#include "platform/latency_histogram.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/telemetry.hpp"
#include "platform/trace.hpp"

namespace hp = haptic::platform;

// tick_begin + tick_end with no tracing session: the cost every tick pays when not traced.
static void BM_trace_tick_pair_not_recording(benchmark::State& state) {
  std::uint64_t i = 0;
  for (auto _ : state) {
    hp::trace::tick_begin(i, 1000, 20);
    hp::trace::tick_end(i, 100);
    ++i;
  }
}
BENCHMARK(BM_trace_tick_pair_not_recording);

static void BM_histogram_add(benchmark::State& state) {
  auto h = std::make_unique<hp::LatencyHistogram>();
  std::int64_t v = 0;
  for (auto _ : state) {
    h->add(v);
    v = (v + 7919) % 3'000'000;
  }
  benchmark::DoNotOptimize(h->samples);
}
BENCHMARK(BM_histogram_add);

static void BM_monotonic_clock_now(benchmark::State& state) {
  hp::MonotonicClock clock;
  for (auto _ : state) benchmark::DoNotOptimize(clock.now_ns());
}
BENCHMARK(BM_monotonic_clock_now);

// The ring push that record() does (plus the logger's pop, same thread, so the ring never fills).
static void BM_telemetry_ring_push_pop(benchmark::State& state) {
  auto ring = std::make_unique<haptic::platform::SpscRing<hp::TelemetryRecord, hp::Telemetry::kRingCapacity>>();
  hp::TelemetryRecord r, out;
  for (auto _ : state) {
    r.tick++;
    benchmark::DoNotOptimize(ring->writer_try_push(r));
    benchmark::DoNotOptimize(ring->reader_try_pop(out));
  }
}
BENCHMARK(BM_telemetry_ring_push_pop);

// record() when the ring is full (the logger sleeps): the drop path the tick takes on overload.
static void BM_telemetry_record_ring_full(benchmark::State& state) {
  hp::TelemetryConfig c;
  c.postmortem_dir = "/tmp";
  c.drain_period_ns = 1'000'000'000;
  hp::Telemetry t(c);
  hp::TelemetryRecord r;
  for (std::size_t i = 0; i < hp::Telemetry::kRingCapacity; ++i) t.record(r);
  for (auto _ : state) benchmark::DoNotOptimize(t.record(r));
}
BENCHMARK(BM_telemetry_record_ring_full);

// GPIO toggles when no chip is configured (the no-op path every lab PC without a scope takes).
static void BM_gpio_toggle_pair_inactive(benchmark::State& state) {
  hp::GpioToggler g(hp::GpioConfig{});
  for (auto _ : state) {
    g.tick_high();
    g.tick_low();
  }
}
BENCHMARK(BM_gpio_toggle_pair_inactive);

BENCHMARK_MAIN();
