#pragma once
// When the I/O thread spins for the RT tick's push (tick-synchronous TX, net/endpoint.hpp): the
// next push is due one period after the previous push's stamp (so a late wake-up does not shift
// the window); the window opens `lead` before it and closes `tail` after it. The thread's own
// timer wake-up is late by tens of us on some machines: the schedule learns by how much (the
// largest lateness of each 64 windows, at most a quarter period) and wakes that much earlier.
// After kMaxMissedWindows windows without a push it stops spinning until the next push re-arms it.
// I/O thread only; RT-safe (pure arithmetic).
#include <algorithm>
#include <cstdint>
#include <limits>

namespace haptic::net {

class TxSpinSchedule {
 public:
  static constexpr int kMaxMissedWindows = 4;
  // period_ns <= 0: off (never spins).
  TxSpinSchedule(std::int64_t period_ns, std::int64_t lead_ns, std::int64_t tail_ns)
      : period_ns_(period_ns), lead_ns_(lead_ns), tail_ns_(tail_ns) {}
  bool enabled() const { return period_ns_ > 0; }
  // A push stamped push_ns was taken from the ring: the next window follows from it.
  void on_push(std::int64_t push_ns) {
    last_push_ns_ = std::max(last_push_ns_, push_ns);
    missed_ = 0;
  }
  // A window ended; caught: a push arrived in it.
  void on_window_end(bool caught) { missed_ = caught ? 0 : missed_ + 1; }

  struct Plan {
    bool spin = false;    // a window is open now: spin until until_ns
    std::int64_t until_ns = 0;
    std::int64_t wake_ns = std::numeric_limits<std::int64_t>::max();  // else: sleep no later than this
  };
  // What to do at now_ns. Opening a window counts it (windows()) and learns the wake-up lateness.
  Plan plan(std::int64_t now_ns) {
    Plan p;
    if (period_ns_ <= 0 || last_push_ns_ < 0 || missed_ >= kMaxMissedWindows) return p;
    std::int64_t due = last_push_ns_ + period_ns_;
    while (due + tail_ns_ < now_ns) due += period_ns_;  // missed pushes: next slot
    const std::int64_t open = due - lead_ns_;
    if (now_ns < open - wake_late_ns_) {
      p.wake_ns = open - wake_late_ns_;
      return p;
    }
    const std::int64_t late = std::max<std::int64_t>(0, now_ns - (open - wake_late_ns_));
    window_late_max_ = std::max(window_late_max_, late);
    if (++windows_ % 64 == 0) {
      wake_late_ns_ = std::min<std::int64_t>(window_late_max_, period_ns_ / 4);
      window_late_max_ = 0;
    }
    p.spin = true;
    p.until_ns = due + tail_ns_;
    return p;
  }
  std::uint64_t windows() const { return windows_; }
  std::int64_t wake_late_ns() const { return wake_late_ns_; }

 private:
  std::int64_t period_ns_, lead_ns_, tail_ns_;
  std::int64_t last_push_ns_ = -1;
  int missed_ = 0;
  std::uint64_t windows_ = 0;
  std::int64_t wake_late_ns_ = 0, window_late_max_ = 0;
};

}  // namespace haptic::net
