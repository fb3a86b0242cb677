#include "rt/edge_energy.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace haptic::rt {

void EdgeEnergyAccount::init(int edges, std::span<const double> damping_share) {
  if (edges < 0 || edges > kMaxEdgeAccounts)
    throw std::invalid_argument("edge energy account: edges must be in [0, " + std::to_string(kMaxEdgeAccounts) + "]");
  if (!damping_share.empty() && static_cast<int>(damping_share.size()) != edges)
    throw std::invalid_argument("edge energy account: one damping share per edge needed");
  *this = EdgeEnergyAccount{};
  edges_ = edges;
  double sum = 0;
  for (double s : damping_share) {
    if (!(s >= 0 && std::isfinite(s))) throw std::invalid_argument("edge energy account: damping shares must be finite and >= 0");
    sum += s;
  }
  for (int j = 0; j < edges; ++j)
    share_[idx(j)] = sum > 0 ? damping_share[idx(j)] / sum : 1.0 / static_cast<double>(edges);
}

void EdgeEnergyAccount::record_tick(std::span<const double> coupling_J, double damping_J) {
  ++ticks_;
  if (edges_ == 0) {
    unshared_ += damping_J;
    return;
  }
  const int n = std::min(edges_, static_cast<int>(coupling_J.size()));
  for (int j = 0; j < n; ++j) {
    const double d = share_[idx(j)] * damping_J;
    const double c = coupling_J[idx(j)];
    coupling_[idx(j)] += c;
    damping_[idx(j)] += d;
    last_[idx(j)] = c + d;
    peak_[idx(j)] = std::max(peak_[idx(j)], edge_J(j));
  }
}

void EdgeEnergyAccount::set_leak(std::span<const double> leak_W) {
  if (!leak_W.empty() && static_cast<int>(leak_W.size()) != edges_)
    throw std::invalid_argument("edge energy account: one leak power per edge needed");
  for (int j = 0; j < edges_; ++j) {
    const double w = leak_W.empty() ? 0.0 : leak_W[idx(j)];
    if (!(w >= 0 && std::isfinite(w))) throw std::invalid_argument("edge energy account: the leak power must be finite and >= 0 W");
    leak_W_[idx(j)] = w;
  }
}

void EdgeEnergyAccount::credit_outflow(double outflow_J, double T) {
  if (!(outflow_J > 0)) return;  // energy came in (or a NaN): nothing left the copy
  for (int j = 0; j < edges_; ++j) {
    const double c = std::min({leak_W_[idx(j)] * T, share_[idx(j)] * outflow_J, edge_J(j)});
    if (c > 0) credited_[idx(j)] += c;
  }
}

double EdgeEnergyAccount::total_J() const {
  double t = unshared_;
  for (int j = 0; j < edges_; ++j) t += coupling_[idx(j)] + damping_[idx(j)];
  return t;
}

void EdgeEnergyGate::init(int edges, std::span<const double> bound_J, std::span<const double> release_J, std::span<const std::int64_t> hold_ticks) {
  if (edges < 0 || edges > kMaxEdgeAccounts)
    throw std::invalid_argument("edge energy gate: edges must be in [0, " + std::to_string(kMaxEdgeAccounts) + "]");
  if (static_cast<int>(bound_J.size()) != edges || static_cast<int>(release_J.size()) != edges)
    throw std::invalid_argument("edge energy gate: one bound and one release level per edge needed");
  if (!hold_ticks.empty() && static_cast<int>(hold_ticks.size()) != edges)
    throw std::invalid_argument("edge energy gate: one hold per edge needed (or none)");
  *this = EdgeEnergyGate{};
  edges_ = edges;
  for (int j = 0; j < edges; ++j) {
    const double b = bound_J[idx(j)], r = release_J[idx(j)];
    if (!(b > 0)) throw std::invalid_argument("edge energy gate: the bound must be > 0 J (+inf: off)");
    if (std::isfinite(b) && !(std::isfinite(r) && r < b))
      throw std::invalid_argument("edge energy gate: the release level must be finite and below the bound");
    bound_[idx(j)] = b;
    release_[idx(j)] = r;
    hold_[idx(j)] = hold_ticks.empty() ? 0 : hold_ticks[idx(j)];
    if (hold_[idx(j)] < 0) throw std::invalid_argument("edge energy gate: the hold must be >= 0 ticks (0: no timed release)");
  }
}

bool EdgeEnergyGate::update(int j, double account_J) {
  const std::size_t i = idx(j);
  const double a = account_J - forgiven_[i];
  if (tripped_[i]) {
    const bool timed = hold_[i] > 0 && ++held_[i] >= hold_after_trip(j, trips_[i]);
    if (a <= release_[i] || timed) {
      if (a > release_[i]) forgiven_[i] += a - release_[i], ++timed_releases_[i];
      tripped_[i] = 0;
      ++releases_[i];
    }
  } else if (a > bound_[i]) {
    tripped_[i] = 1;
    held_[i] = 0;
    ++trips_[i];
  }
  if (tripped_[i]) ++gated_ticks_[i];
  return tripped_[i] != 0;
}

void EdgeEnergyGate::record_tick(int j, double coupling_J) {
  if (tripped_[idx(j)]) removed_[idx(j)] -= coupling_J;
}

double EdgeEnergyGate::removed_J() const {
  double r = 0;
  for (int j = 0; j < edges_; ++j) r += removed_[idx(j)];
  return r;
}

std::uint64_t EdgeEnergyGate::trips() const {
  std::uint64_t t = 0;
  for (int j = 0; j < edges_; ++j) t += trips_[idx(j)];
  return t;
}

}  // namespace haptic::rt
