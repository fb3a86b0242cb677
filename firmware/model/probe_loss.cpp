#include "firmware/model/probe_loss.hpp"

#include <algorithm>

#include "firmware/model/delay_model.hpp"

namespace haptic::firmware {

void ProbeLossCounter::add(int n, std::uint64_t seq) {
  if (n < 0 || static_cast<std::size_t>(n) >= seen_.size()) return;
  const auto i = static_cast<std::size_t>(n);
  const auto s = static_cast<std::int64_t>(seq);
  if (first_[i] < 0) first_[i] = s;
  const std::int64_t off = s - first_[i];
  if (off < 0 || off >= kMaxSpan) return;  // before the first one seen (reordered) or beyond the record
  auto& bits = seen_[i];
  if (static_cast<std::size_t>(off) >= bits.size()) bits.resize(static_cast<std::size_t>(off) + 1, false);
  bits[static_cast<std::size_t>(off)] = true;
  newest_[i] = std::max(newest_[i], s);
}

ProbeLoss ProbeLossCounter::loss(std::size_t n, std::int64_t late_ticks) const {
  ProbeLoss r;
  if (n >= seen_.size() || first_[n] < 0) return r;
  const std::int64_t last = newest_[n] - std::max<std::int64_t>(0, late_ticks);
  if (last < first_[n]) return r;
  const auto& bits = seen_[n];
  const std::int64_t span = last - first_[n] + 1;
  long long received = 0;
  std::int64_t previous = -1;  // offset of the last packet seen
  auto silence = [&](long long lost) {  // `lost` packets in a row
    r.lost += lost;
    r.longest_gap = std::max(r.longest_gap, lost);
  };
  for (std::int64_t i = 0; i < span; ++i) {
    if (!bits[static_cast<std::size_t>(i)]) continue;
    ++received;
    if (previous >= 0) silence((i - previous + interval_ - 1) / interval_ - 1);  // ceil(gap / I) - 1
    previous = i;
  }
  silence((span - 1 - previous) / interval_);  // after the last one: those due by `last`
  r.expected = received + r.lost;
  return r;
}

int round_trip_loss_allowance(const ProbeLoss& loss, double run_ticks, int directed_links) {
  if (loss.expected <= 0) return -1;
  const int L = model::loss_allowance_from_measured_loss(loss.lost, loss.expected, run_ticks, directed_links);
  return 2 * static_cast<int>(std::max<long long>(L, loss.longest_gap));
}

}  // namespace haptic::firmware
