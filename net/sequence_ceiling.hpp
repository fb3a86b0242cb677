#pragma once
// The highest sequence number a neighbour may send now (net.max_sequence_ahead_ticks): our own tick
// plus that slack. Our tick is what the station last told us (note_tick, from the RT thread), or,
// before that, the session's tick by the clock when the station was given a common epoch
// (station.start_at); without either there is no ceiling yet. note_tick is RT-safe (one relaxed
// atomic store); ceiling() is read by the I/O thread.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>

namespace haptic::net {

class SequenceCeiling {
 public:
  static constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
  // ahead_ticks: the slack; epoch_ns: CLOCK_MONOTONIC ns of sequence 0 (< 0: none); period_ns: the tick (<= 0: none).
  SequenceCeiling(std::uint64_t ahead_ticks, std::int64_t epoch_ns, std::int64_t period_ns)
      : ahead_(ahead_ticks), epoch_ns_(epoch_ns), period_ns_(period_ns) {}
  void note_tick(std::int64_t k) { own_tick_.store(k, std::memory_order_relaxed); }
  // The ceiling at now_ns; kNone while our tick is unknown.
  std::uint64_t ceiling(std::int64_t now_ns) const {
    std::int64_t own = own_tick_.load(std::memory_order_relaxed);
    if (own < 0 && epoch_ns_ >= 0 && period_ns_ > 0)  // a common epoch: the session's tick by the clock
      own = std::max<std::int64_t>(0, (now_ns - epoch_ns_) / period_ns_);
    return own >= 0 ? static_cast<std::uint64_t>(own) + ahead_ : kNone;
  }

 private:
  std::uint64_t ahead_;
  std::int64_t epoch_ns_, period_ns_;
  std::atomic<std::int64_t> own_tick_{-1};  // -1: not yet known
};

}  // namespace haptic::net
