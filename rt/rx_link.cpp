#include "rt/rx_link.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace haptic::rt {

RxRule parse_rx_rule(const std::string& text, const std::string& key) {
  if (text == "newest") return RxRule::kNewestBySequence;
  if (text == "paper") return RxRule::kMostRecentlyReceived;
  throw std::invalid_argument(key + " must be newest or paper, not '" + text + "'");
}

const char* rx_rule_name(RxRule rule) { return rule == RxRule::kNewestBySequence ? "newest" : "paper"; }

// One branch-free pass that vectorizes: a payload (3n doubles) is read once. Integer work only (the
// same result at any vector width): an AVX2 build (4 values a step) where the CPU has it.
#if defined(__x86_64__)
__attribute__((target_clones("avx2", "default")))
#endif
std::uint64_t copy_non_finite(const double* from, double* to, int n) {
  std::uint64_t bad = 0;
  for (int i = 0; i < n; ++i) {
    std::uint64_t bits;
    std::memcpy(&bits, from + i, sizeof bits);
    std::memcpy(to + i, &bits, sizeof bits);
    bad |= ((bits >> 52) & 0x7ffu) + 1u;  // 0x800 exactly when the exponent is 0x7ff
  }
  return bad & 0x800u;
}

bool RxLink::was_used(std::int64_t seq) const {
  if (seq < 0 || seq > max_used_) return false;
  if (seq <= max_used_ - kUsedWindow) return true;  // beyond the window: treated as used (delta = 0)
  const auto bit = static_cast<std::uint64_t>(seq) % kUsedWindow;
  return (used_[bit / 64] >> (bit % 64)) & 1u;
}

void RxLink::mark_used(std::int64_t seq) {
  if (seq < 0) return;
  while (max_used_ < seq) {  // clear the bits the window slides over (at most kUsedWindow of them)
    ++max_used_;
    if (seq - max_used_ >= kUsedWindow) max_used_ = seq - kUsedWindow + 1;
    const auto bit = static_cast<std::uint64_t>(max_used_) % kUsedWindow;
    used_[bit / 64] &= ~(std::uint64_t{1} << (bit % 64));
  }
  if (seq <= max_used_ - kUsedWindow) return;
  const auto bit = static_cast<std::uint64_t>(seq) % kUsedWindow;
  used_[bit / 64] |= std::uint64_t{1} << (bit % 64);
}

void RxLink::init(int dofs, const double* x0, const double* v0, std::int64_t initial_sequence, RxRule rule) {
  if (dofs <= 0) throw std::invalid_argument("RxLink: dofs must be > 0");
  dofs_ = dofs;
  x_hat_.assign(x0, x0 + dofs);
  if (v0) v_hat_.assign(v0, v0 + dofs);
  else v_hat_.assign(static_cast<std::size_t>(dofs), 0.0);
  x_in_.assign(static_cast<std::size_t>(dofs), 0.0);
  v_in_.assign(static_cast<std::size_t>(dofs), 0.0);
  newest_seq_ = initial_sequence;
  max_seen_ = initial_sequence;
  rule_ = rule;
  used_.fill(0);
  max_used_ = -1;
  unused_ = false;  // the assumed initial state carries no velocity sample to use
  counters_ = RxCounters{};
  last_tick_ = INT64_MIN;
  slot_ = kNoSlot;
}

RxVerdict RxLink::judge(std::int64_t seq) {
  if (seq == newest_seq_) {
    ++counters_.duplicate;
    return RxVerdict::kDuplicate;
  }
  if (seq < max_seen_) {
    ++counters_.stale;
    if (rule_ == RxRule::kNewestBySequence) return RxVerdict::kStale;
  }
  return RxVerdict::kAccepted;
}

void RxLink::hold(std::int64_t seq, double send_time_s) {
  newest_seq_ = seq;
  max_seen_ = std::max(max_seen_, seq);
  newest_send_time_ = send_time_s;
  // Newest rule: a newer sequence was never used. Paper's rule: a late packet may repeat a
  // sample already used (a duplicate arriving after a newer packet): delta = 0 then.
  unused_ = rule_ == RxRule::kNewestBySequence || !was_used(seq);
  ++counters_.accepted;
}

RxVerdict RxLink::take(std::int64_t seq, double send_time_s, const double* x_hat, const double* v_hat, std::uint32_t slot,
                       std::uint32_t& released) {
  released = slot;
  const RxVerdict v = judge(seq);
  if (v != RxVerdict::kAccepted) return v;
  released = slot_;  // the buffer held until now goes back; the new one is read in place
  slot_ = slot;
  x_ext_ = x_hat;
  v_ext_ = v_hat;
  hold(seq, send_time_s);
  return RxVerdict::kAccepted;
}

RxVerdict RxLink::offer(std::int64_t seq, double send_time_s, const double* x_hat, const double* v_hat, int dofs) {
  if (dofs != dofs_ || !x_hat || !v_hat) {
    ++counters_.bad_size;
    return RxVerdict::kBadSize;
  }
  const RxVerdict v = judge(seq);
  if (v != RxVerdict::kAccepted) return v;
  // Into the landing buffers (the held packet stays intact if this one is refused), then swapped in.
  if ((copy_non_finite(x_hat, x_in_.data(), dofs_) | copy_non_finite(v_hat, v_in_.data(), dofs_)) != 0) {
    ++counters_.non_finite;
    return RxVerdict::kNonFinite;
  }
  x_hat_.swap(x_in_);  // swaps the buffers: no allocation
  v_hat_.swap(v_in_);
  hold(seq, send_time_s);
  return RxVerdict::kAccepted;
}

RxLink::TickView RxLink::begin_tick(std::int64_t k) {
  TickView v;
  v.index_delay = k - newest_seq_;
  if (v.index_delay < 0) {  // data stamped ahead of our tick (within the sender's slack): never a negative delay
    v.index_delay = 0;
    ++counters_.ahead_ticks;
  }
  v.fresh = unused_;
  if (unused_ && rule_ == RxRule::kMostRecentlyReceived) mark_used(newest_seq_);
  if (!unused_ && k != last_tick_) ++counters_.sustained_ticks;
  unused_ = false;
  last_tick_ = k;
  v.x_hat = held_x();
  v.v_hat = held_v();
  v.send_time_s = newest_send_time_;
  counters_.max_index_delay = std::max(counters_.max_index_delay, v.index_delay);
  return v;
}

}  // namespace haptic::rt
