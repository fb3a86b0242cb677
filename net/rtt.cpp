#include "net/rtt.hpp"

#include <cmath>
#include <stdexcept>

namespace haptic::net {

void RttConfig::validate() const {
  if (!(margin_fraction >= 0.0 && margin_fraction <= 10.0))
    throw std::invalid_argument("net.rtt_margin_fraction must be in [0, 10]");
  if (!(margin_s >= 0.0 && margin_s <= 10.0)) throw std::invalid_argument("net.rtt_margin_s must be in [0, 10] s");
  if (min_probe_samples < 1) throw std::invalid_argument("net.rtt_min_probe_samples must be >= 1");
}

RttEstimator::RttEstimator(const RttConfig& cfg) : cfg_(cfg) { cfg_.validate(); }

void RttEstimator::begin_probing() {
  probing_ = true;
  probe_samples_ = 0;
  probe_max_s_ = 0.0;
}

bool RttEstimator::finish_probing() {
  if (!probing_ || probe_samples_ < cfg_.min_probe_samples) return false;
  probing_ = false;
  has_bound_ = true;
  bound_s_ = with_margin(probe_max_s_);
  probe_bound_s_ = bound_s_;
  ++generation_;
  return true;
}

bool RttEstimator::add_sample(double rtt_s) {
  if (!std::isfinite(rtt_s) || rtt_s < 0.0) return false;  // clock misuse: ignore, never poison
  if (samples_ == 0 || rtt_s < min_s_) min_s_ = rtt_s;
  if (rtt_s > max_s_) max_s_ = rtt_s;
  ++samples_;
  sum_s_ += rtt_s;
  last_s_ = rtt_s;
  if (probing_) {
    ++probe_samples_;
    if (rtt_s > probe_max_s_) probe_max_s_ = rtt_s;
    return false;
  }
  if (has_bound_ && rtt_s > bound_s_) {
    ++over_bound_;
    bound_s_ = with_margin(rtt_s);
    ++generation_;
    return true;
  }
  return false;
}

std::uint32_t bound_ticks(double bound_s, double period_s) {
  if (!(period_s > 0.0)) return 0;
  return static_cast<std::uint32_t>(std::ceil(bound_s / period_s - 1e-9));
}

std::uint32_t RttEstimator::bound_ticks(double period_s) const { return net::bound_ticks(bound_s_, period_s); }

}  // namespace haptic::net
