#include "rt/rx_link.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace haptic::rt {

void RxLink::init(int dofs, const double* x0, const double* v0, std::int64_t initial_sequence) {
  if (dofs <= 0) throw std::invalid_argument("RxLink: dofs must be > 0");
  dofs_ = dofs;
  x_hat_.assign(x0, x0 + dofs);
  if (v0) v_hat_.assign(v0, v0 + dofs);
  else v_hat_.assign(static_cast<std::size_t>(dofs), 0.0);
  newest_seq_ = initial_sequence;
  unused_ = false;  // the assumed initial state carries no velocity sample to use
  counters_ = RxCounters{};
  last_tick_ = INT64_MIN;
}

RxVerdict RxLink::offer(std::int64_t seq, double send_time_s, const double* x_hat, const double* v_hat, int dofs) {
  if (dofs != dofs_ || !x_hat || !v_hat) {
    ++counters_.bad_size;
    return RxVerdict::kBadSize;
  }
  if (seq == newest_seq_) {
    ++counters_.duplicate;
    return RxVerdict::kDuplicate;
  }
  if (seq < newest_seq_) {
    ++counters_.stale;
    return RxVerdict::kStale;
  }
  std::memcpy(x_hat_.data(), x_hat, sizeof(double) * static_cast<std::size_t>(dofs_));
  std::memcpy(v_hat_.data(), v_hat, sizeof(double) * static_cast<std::size_t>(dofs_));
  newest_seq_ = seq;
  newest_send_time_ = send_time_s;
  unused_ = true;
  ++counters_.accepted;
  return RxVerdict::kAccepted;
}

RxLink::TickView RxLink::begin_tick(std::int64_t k) {
  TickView v;
  v.index_delay = k - newest_seq_;
  v.fresh = unused_;
  if (!unused_ && k != last_tick_) ++counters_.sustained_ticks;
  unused_ = false;
  last_tick_ = k;
  v.x_hat = x_hat_.data();
  v.v_hat = v_hat_.data();
  v.send_time_s = newest_send_time_;
  counters_.max_index_delay = std::max(counters_.max_index_delay, v.index_delay);
  return v;
}

}  // namespace haptic::rt
