#include "rt/return_ramp.hpp"

#include <algorithm>
#include <cmath>

namespace haptic::rt {

void ReturnRamp::init(int edges, int dofs, std::int64_t ramp_ticks, std::int64_t after_ticks) {
  dofs_ = dofs;
  ramp_ticks_ = std::max<std::int64_t>(ramp_ticks, 0);
  after_ticks_ = std::max<std::int64_t>(after_ticks, 1);
  edges_.assign(static_cast<std::size_t>(edges), Edge{});
  if (!on()) return;
  for (auto& e : edges_) {
    e.offset.assign(static_cast<std::size_t>(dofs), 0.0);
    e.target.assign(static_cast<std::size_t>(dofs), 0.0);
  }
}

void ReturnRamp::arm_all() {
  for (auto& e : edges_) e.armed = true;
}

void ReturnRamp::start(Edge& e, std::int64_t k, const double* x_hat, const double* x) {
  double m = 0;
  for (int i = 0; i < dofs_; ++i) {
    e.offset[static_cast<std::size_t>(i)] = x_hat[i] - x[i];
    m = std::max(m, std::abs(x_hat[i] - x[i]));
  }
  e.offset_max_m = m;
  e.start_k = k;
  ++e.ramps;
}

const double* ReturnRamp::target(int j, std::int64_t k, bool present, const double* x_hat, const double* x, const double* faded) {
  if (!on()) return x_hat;
  Edge& e = edges_[static_cast<std::size_t>(j)];
  if (!present) {
    if (e.down_since < 0) e.down_since = k;
    return x_hat;
  }
  if (faded) {
    start(e, k, x_hat, faded);
  } else if (e.armed || (e.down_since >= 0 && k - e.down_since >= after_ticks_)) {
    start(e, k, x_hat, x);
  }
  e.down_since = -1;
  e.armed = false;
  if (e.start_k < 0) return x_hat;
  const double s = static_cast<double>(k - e.start_k) / static_cast<double>(ramp_ticks_);
  if (s >= 1.0) {
    e.start_k = -1;
    return x_hat;
  }
  const double w = 1.0 - s;
  double* t = e.target.data();
  const double* o = e.offset.data();
  for (int i = 0; i < dofs_; ++i) t[i] = x_hat[i] - w * o[i];
  return t;
}

}  // namespace haptic::rt
