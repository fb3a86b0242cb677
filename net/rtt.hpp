#pragma once
// Round-trip measurement for one neighbor, from echoed send timestamps (net/README.md).
//
// Station i stamps every packet with its CLOCK_MONOTONIC send time; neighbor j echoes the
// newest (sequence, stamp) it received from i in its own packets; when i first sees a new echo
// it takes the sample  rtt = now_i - stamp. The sample covers N_ij + N_ji of eq. (18) including
// j's hold time, so it is conservative. Clock offsets between stations do not matter.
//
// Life cycle: begin_probing() -> samples -> finish_probing() fixes the bound
//   bound = policy(max_probe, margin_fraction, margin_s)
// from which the station sets B_i with eq. (18) (round trip in ticks: bound_ticks(T)). The policy
// is not net/'s (net/ measures, it knows no physics): the station hands in its passivity budget's
// (firmware/model/passivity_budget.hpp, model::round_trip_bound_s); without one the bound is the
// measured maximum itself.
// Afterwards a sample above the bound is an over-bound event: it is counted, the bound is
// raised to cover it (by the same policy) and `generation()` increments, so the station
// knows it must act (raise B_i or drop the edge; policy in net/README.md).
// Not thread-safe: owned by one thread (the I/O thread); publish copies across threads.
#include <cstdint>

namespace haptic::net {

// The bound a measured round trip (s) turns into, given the margins below. Called on the I/O thread.
using RoundTripBoundPolicy = double (*)(double round_trip_s, double margin_fraction, double margin_s);

struct RttConfig {
  double margin_fraction = 0.25;  // net.rtt_margin_fraction, in [0, 10]
  double margin_s = 0.004;        // net.rtt_margin_s (two 2 ms ticks), in [0, 10]
  std::uint64_t min_probe_samples = 20;  // net.rtt_min_probe_samples, >= 1
  RoundTripBoundPolicy bound_policy = nullptr;  // the caller's (the station: model::round_trip_bound_s); null: the maximum itself
  void validate() const;  // throws std::invalid_argument naming the key and range
};

// A round-trip bound in seconds as ticks of period_s (ceil, 1e-9 relative slack for a bound that is
// a whole number of ticks): N_bar_ij + N_bar_ji of eq. (18). 0 for period_s <= 0. RT-safe.
std::uint32_t bound_ticks(double bound_s, double period_s);

class RttEstimator {
 public:
  explicit RttEstimator(const RttConfig& cfg = {});
  void begin_probing();
  // Ends probing and fixes the bound. Returns false (and stays probing) if fewer than
  // min_probe_samples samples were taken.
  bool finish_probing();
  // Adds a sample (seconds). Returns true when it was an over-bound event. RT-safe.
  bool add_sample(double rtt_s);

  bool probing() const { return probing_; }
  bool has_bound() const { return has_bound_; }
  std::uint64_t samples() const { return samples_; }
  std::uint64_t probe_samples() const { return probe_samples_; }
  double last_s() const { return last_s_; }
  double min_s() const { return min_s_; }
  double max_s() const { return max_s_; }
  double mean_s() const { return samples_ ? sum_s_ / static_cast<double>(samples_) : 0.0; }
  double bound_s() const { return bound_s_; }
  // The bound finish_probing() fixed (0 before): over-bound events later raise bound_s() only.
  double probe_bound_s() const { return probe_bound_s_; }
  std::uint64_t over_bound_events() const { return over_bound_; }
  std::uint64_t generation() const { return generation_; }  // bumps when the bound changes
  // The bound as a round trip in ticks of period_s (ceil): N_bar_ij + N_bar_ji of eq. (18).
  std::uint32_t bound_ticks(double period_s) const;

 private:
  double with_margin(double rtt_s) const { return cfg_.bound_policy ? cfg_.bound_policy(rtt_s, cfg_.margin_fraction, cfg_.margin_s) : rtt_s; }
  RttConfig cfg_;
  bool probing_ = false;
  bool has_bound_ = false;
  std::uint64_t samples_ = 0, probe_samples_ = 0, over_bound_ = 0, generation_ = 0;
  double last_s_ = 0.0, min_s_ = 0.0, max_s_ = 0.0, sum_s_ = 0.0, probe_max_s_ = 0.0, bound_s_ = 0.0, probe_bound_s_ = 0.0;
};

}  // namespace haptic::net
