#include "platform/periodic_loop.hpp"

#include <cstdio>

namespace haptic::platform {

void validate(const LoopConfig& c) {
  if (c.period_ns < 10'000 || c.period_ns > 1'000'000'000) {
    throw std::invalid_argument("loop.period_ns = " + std::to_string(c.period_ns) + ": allowed range is 10000..1000000000");
  }
  if (c.histogram_bin_ns < 1 || c.histogram_bin_ns > 1'000'000) {
    throw std::invalid_argument("loop.histogram_bin_ns = " + std::to_string(c.histogram_bin_ns) + ": allowed range is 1..1000000");
  }
  if (c.report_interval_ns < 1'000'000'000) {
    throw std::invalid_argument("loop.report_interval_ns = " + std::to_string(c.report_interval_ns) +
                                ": allowed range is >= 1000000000 (reports are throttled to at most one per second)");
  }
  if (c.overrun_storm_count < 1) {
    throw std::invalid_argument("loop.overrun_storm_count = 0: allowed range is >= 1");
  }
  if (c.overrun_storm_window_ns <= 0) {
    throw std::invalid_argument("loop.overrun_storm_window_ns = " + std::to_string(c.overrun_storm_window_ns) + ": allowed range is > 0");
  }
}

std::string format_report(const LoopReport& r) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "loop: %llu ticks, %llu overruns (%llu missed cycles, %llu storms); last window %llu ticks, "
                "%llu overruns, wake-up latency min/avg/max %.1f/%.1f/%.1f us, exec max %.1f us",
                static_cast<unsigned long long>(r.ticks), static_cast<unsigned long long>(r.overruns),
                static_cast<unsigned long long>(r.missed_cycles), static_cast<unsigned long long>(r.overrun_storms),
                static_cast<unsigned long long>(r.window_ticks), static_cast<unsigned long long>(r.window_overruns),
                static_cast<double>(r.window_latency_min_ns) / 1e3, r.window_latency_avg_ns / 1e3,
                static_cast<double>(r.window_latency_max_ns) / 1e3, static_cast<double>(r.window_exec_max_ns) / 1e3);
  return buf;
}

}  // namespace haptic::platform
