#include "firmware/model/step_bounds.hpp"

#include <algorithm>

namespace haptic::model {

StepBounds step_bounds(double T, double rate, double jitter, double J) {
  StepBounds b;
  b.t_min_s = std::min(T, T * rate * (1 - jitter) - J);
  b.t_max_s = std::max(T, T * rate * (1 + jitter) + J);
  return b;
}

StepBounds measured_step_bounds(double T, double max_wake_latency_s, double cap) {
  const double wanted = kWakeHeadroom * std::max(0.0, max_wake_latency_s) + kWakeFloor_s;
  StepBounds b = step_bounds(T, 1.0, 0.0, std::min(wanted, cap));
  b.capped = wanted > cap;
  return b;
}

double announced_step_min(double T, double t_max) { return std::min(T, std::max(2 * T - t_max, 0.5 * T)); }

}  // namespace haptic::model
