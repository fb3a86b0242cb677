#pragma once
// Wake-up latency measurement on platform::PeriodicLoop, cyclictest style: the thread sleeps
// to absolute CLOCK_MONOTONIC deadlines and records (actual wake - deadline) in a histogram.
// The tick's work is a JitterWorkload, so the station can plug its real tick in; the default
// is a busy loop of N microseconds. Not RT-safe to set up; the measured loop is.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "platform/periodic_loop.hpp"
#include "platform/rt_thread.hpp"

namespace haptic::tools {

// The work done inside each tick. tick() runs on the RT thread: it must be RT-safe.
class JitterWorkload {
 public:
  virtual ~JitterWorkload() = default;
  virtual void tick(const platform::TickInfo& info) = 0;
  virtual std::string name() const = 0;
};

// Spins for busy_ns after wake-up; every overrun_every-th tick (0 = never) spins for
// overrun_periods periods instead, to provoke overruns on purpose (used by the trace test).
class BusyLoopWorkload final : public JitterWorkload {
 public:
  BusyLoopWorkload(std::int64_t busy_ns, std::uint64_t overrun_every = 0, double overrun_periods = 1.5,
                   std::int64_t period_ns = 0)
      : busy_ns_(busy_ns), overrun_every_(overrun_every), overrun_ns_(static_cast<std::int64_t>(overrun_periods * static_cast<double>(period_ns))) {}
  void tick(const platform::TickInfo& info) override;  // RT-safe
  std::string name() const override;

 private:
  std::int64_t busy_ns_;
  std::uint64_t overrun_every_;
  std::int64_t overrun_ns_;
};

struct JitterRunConfig {
  std::int64_t period_ns = 1'000'000;
  std::uint64_t ticks = 10'000;
  std::int64_t histogram_bin_ns = 1000;
};

struct JitterResult {
  std::int64_t period_ns = 0;
  std::string workload;
  platform::LoopStats stats;
  bool interrupted = false;
};

// Runs one measurement on the calling thread (which should already be set up by
// platform::apply_rt_config). `stop` ends it early. Not RT-safe (allocates the loop).
JitterResult run_jitter(const JitterRunConfig& config, JitterWorkload& workload, const std::atomic<bool>& stop);

// Human-readable summary lines and histogram; JSON document of all runs.
std::string format_result(const JitterResult& r, bool with_histogram);
std::string to_json(const std::vector<JitterResult>& runs, const platform::RtReport& rt, const platform::RtConfig& rt_config);

}  // namespace haptic::tools
