#include "rt/tx_deadband.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace haptic::rt {

void TxDeadbandConfig::validate() const {
  if (!(position_deadband_m >= 0 && position_deadband_m < 0.1))
    throw std::invalid_argument("tx_deadband.position_m must be in [0, 0.1) m");
  if (max_interval_ticks < 1 || max_interval_ticks > 1000)
    throw std::invalid_argument("tx_deadband.max_interval_ticks must be in [1, 1000]");
}

TxDeadband::TxDeadband(const TxDeadbandConfig& config, int dofs, double period_s)
    : cfg_(config), period_s_(period_s), last_x_(static_cast<std::size_t>(dofs), 0.0), last_v_(static_cast<std::size_t>(dofs), 0.0),
      every_(config.max_interval_ticks) {
  cfg_.validate();
  if (!(period_s > 0)) throw std::invalid_argument("TxDeadband: period_s must be > 0");
}

bool TxDeadband::should_send(std::int64_t k, const double* x_hat, const double* v_hat) {
  const bool predictive = cfg_.predictive && v_hat;
  bool send = !cfg_.enabled() || every_.due(k);
  const std::size_t n = last_x_.size();
  if (!send) {
    const double band = cfg_.position_deadband_m;
    // the receiver's value: the last sent x_hat, extrapolated by its velocity when predictive
    const double h = predictive ? static_cast<double>(k - every_.last_sent()) * period_s_ : 0.0, lim = cfg_.prediction_limit_m();
    for (std::size_t i = 0; i < n; ++i)
      if (!(std::abs(x_hat[i] - extrapolated_position(last_x_[i], last_v_[i], h, lim)) <= band)) {  // also sends a non-finite state
        send = true;
        break;
      }
  }
  if (!send) {
    ++skipped_;
    return false;
  }
  if (cfg_.enabled())
    for (std::size_t i = 0; i < n; ++i) {
      last_x_[i] = x_hat[i];
      last_v_[i] = predictive ? v_hat[i] : 0.0;
    }
  every_.sent(k);
  ++sent_;
  return true;
}

}  // namespace haptic::rt
