#pragma once
// Fixed-size latency histogram (no allocation): kBins bins of bin_ns each plus an overflow
// count, exact min/max/sum. add() is RT-safe; percentile() is O(kBins) and meant for reports.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace haptic::platform {

struct LatencyHistogram {
  static constexpr std::size_t kBins = 10000;  // 10 ms at the default 1 us bins
  std::int64_t bin_ns = 1000;  // width of one bin
  std::array<std::uint64_t, kBins> counts{};
  std::uint64_t overflow = 0;  // samples >= kBins * bin_ns
  std::uint64_t underflow = 0;  // samples < 0 (clock went "early"; counted in bin 0 too)
  std::uint64_t samples = 0;
  std::int64_t min_ns = std::numeric_limits<std::int64_t>::max();
  std::int64_t max_ns = std::numeric_limits<std::int64_t>::min();
  std::int64_t sum_ns = 0;

  // RT-safe.
  void add(std::int64_t value_ns) {
    ++samples;
    sum_ns += value_ns;
    if (value_ns < min_ns) min_ns = value_ns;
    if (value_ns > max_ns) max_ns = value_ns;
    if (value_ns < 0) {
      ++underflow;
      ++counts[0];
      return;
    }
    const std::int64_t bin = value_ns / bin_ns;
    if (bin >= static_cast<std::int64_t>(kBins)) {
      ++overflow;
    } else {
      ++counts[static_cast<std::size_t>(bin)];
    }
  }
  // RT-safe. Keeps the bin width.
  void reset() {
    const std::int64_t width = bin_ns;
    *this = LatencyHistogram{};
    bin_ns = width;
  }
  double mean_ns() const { return samples ? static_cast<double>(sum_ns) / static_cast<double>(samples) : 0.0; }
  // Smallest bin upper edge below which at least fraction p (0..1) of the samples lie, capped
  // at max_ns (so a percentile never exceeds the exact maximum). 0 when empty. RT-safe.
  std::int64_t percentile_ns(double p) const {
    if (samples == 0) return 0;
    const double wanted = p * static_cast<double>(samples);
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBins; ++i) {
      seen += counts[i];
      if (static_cast<double>(seen) >= wanted && seen > 0) {
        const std::int64_t edge = static_cast<std::int64_t>(i + 1) * bin_ns;
        return edge < max_ns ? edge : max_ns;
      }
    }
    return max_ns;
  }
};

}  // namespace haptic::platform
