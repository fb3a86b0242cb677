#pragma once
// Silence detection for one neighbour: up at its first authentic datagram, down after `silence`
// without one, up again at the next (each change counted and stamped). I/O thread only; RT-safe.
#include <cstdint>

#include "net/peer_stats.hpp"

namespace haptic::net {

class PeerLiveness {
 public:
  // An authentic datagram of the neighbour at now_ns; true when it marked the neighbour up.
  bool on_receive(std::int64_t now_ns) {
    last_receive_ns_ = now_ns;
    if (up_) return false;
    up_ = true;
    ++up_events_;
    last_up_ns_ = last_change_ns_ = now_ns;
    return true;
  }
  // true when the neighbour, up until now, has been silent for more than silence_ns: marked down.
  bool check(std::int64_t now_ns, std::int64_t silence_ns) {
    if (!up_ || now_ns - last_receive_ns_ <= silence_ns) return false;
    up_ = false;
    ++down_events_;
    last_down_ns_ = last_change_ns_ = now_ns;
    return true;
  }
  bool up() const { return up_; }
  // up, up_events, down_events, last_change_s, last_up_s, last_down_s, last_receive_s.
  void fill(PeerStats& s) const {
    s.up = up_;
    s.up_events = up_events_;
    s.down_events = down_events_;
    s.last_change_s = seconds(last_change_ns_);
    s.last_up_s = seconds(last_up_ns_);
    s.last_down_s = seconds(last_down_ns_);
    s.last_receive_s = seconds(last_receive_ns_);
  }

 private:
  static double seconds(std::int64_t ns) { return static_cast<double>(ns) * 1e-9; }
  bool up_ = false;
  std::uint64_t up_events_ = 0, down_events_ = 0;
  std::int64_t last_receive_ns_ = 0, last_up_ns_ = 0, last_down_ns_ = 0, last_change_ns_ = 0;
};

}  // namespace haptic::net
