#include "rt/drop_fade.hpp"

#include <algorithm>

namespace haptic::rt {

void DropFade::init(int edges, int dofs, std::int64_t fade_ticks) {
  dofs_ = dofs;
  fade_ticks_ = std::max<std::int64_t>(fade_ticks, 0);
  edges_.assign(static_cast<std::size_t>(edges), Edge{});
  if (!on()) return;
  for (auto& e : edges_) {
    e.anchor.assign(static_cast<std::size_t>(dofs), 0.0);
    e.target.assign(static_cast<std::size_t>(dofs), 0.0);
  }
}

void DropFade::start(int j, std::int64_t k, const double* last) {
  if (!on()) return;
  Edge& e = edges_[static_cast<std::size_t>(j)];
  std::copy(last, last + dofs_, e.anchor.begin());
  e.start_k = k;
  ++e.fades;
}

const double* DropFade::target(int j, std::int64_t k, const double* x) {
  Edge& e = edges_[static_cast<std::size_t>(j)];
  if (e.start_k < 0) return nullptr;
  const std::int64_t h = k - e.start_k;
  if (h >= fade_ticks_) {
    e.start_k = -1;
    return nullptr;
  }
  const double u = 1.0 - static_cast<double>(h) / static_cast<double>(fade_ticks_);
  const double w = u * u;  // (1 - h/H)^2: the stiffness falls slowest where the copy lets go fastest
  double* t = e.target.data();
  const double* a = e.anchor.data();
  for (int i = 0; i < dofs_; ++i) t[i] = x[i] + w * (a[i] - x[i]);
  return t;
}

const double* DropFade::handover(int j, std::int64_t k, const double* x) {
  const double* t = target(j, k, x);
  stop(j);
  return t;
}

}  // namespace haptic::rt
