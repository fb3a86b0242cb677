#pragma once
// Per-source datagram rate limit of the I/O thread: a token bucket (rate per second, burst) for
// each neighbour's configured address and one shared by every unknown address, applied before any
// decoding or MAC work, so a flood costs a receive and this. I/O thread only; RT-safe.
#include <algorithm>
#include <cstdint>
#include <vector>

namespace haptic::net {

class SourceRateLimit {
 public:
  // rate_per_s datagrams per second for each of `sources` neighbours and for the unknown addresses together.
  SourceRateLimit(double rate_per_s, double burst, std::size_t sources)
      : rate_per_s_(rate_per_s), burst_(burst), buckets_(sources + 1) {}
  // One datagram from neighbour `source` (an index; < 0: an unknown address) at now_ns; false: over the limit.
  bool take(int source, std::int64_t now_ns) {
    Bucket& b = source >= 0 ? buckets_[static_cast<std::size_t>(source)] : buckets_.back();
    if (b.last_ns < 0) b.tokens = burst_;
    else b.tokens = std::min(burst_, b.tokens + static_cast<double>(now_ns - b.last_ns) * 1e-9 * rate_per_s_);
    b.last_ns = now_ns;
    if (b.tokens < 1.0) return false;
    b.tokens -= 1.0;
    return true;
  }
  double rate_per_s() const { return rate_per_s_; }
  double burst() const { return burst_; }

 private:
  struct Bucket {
    double tokens = 0.0;
    std::int64_t last_ns = -1;
  };
  double rate_per_s_, burst_;
  std::vector<Bucket> buckets_;
};

}  // namespace haptic::net
