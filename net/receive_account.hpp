#pragma once
// What arrived from one neighbour: incarnations (its process; a restart changes it), and the state
// packets of the current incarnation (sequence span, loss fraction, one-way time by the sender's
// stamp). I/O thread only; RT-safe.
#include <algorithm>
#include <cstdint>

#include "net/peer_stats.hpp"

namespace haptic::net {

class ReceiveAccount {
 public:
  // The incarnation of an authentic datagram; true when it is a new one of a neighbour already
  // seen (a restarted process: the caller forgets what belonged to the old one).
  bool on_incarnation(std::uint64_t incarnation) {
    if (has_incarnation_ && incarnation == incarnation_) return false;
    const bool restarted = has_incarnation_;
    if (restarted) {
      ++incarnation_changes_;
      received_incarnation_ = 0;
    }
    has_incarnation_ = true;
    incarnation_ = incarnation;
    return restarted;
  }
  // A state packet (seq, the neighbour's send stamp) received at now_ns.
  void on_state(std::uint64_t seq, std::int64_t send_time_ns, std::int64_t now_ns) {
    if (received_incarnation_ == 0) lowest_seq_ = newest_seq_ = seq;
    lowest_seq_ = std::min(lowest_seq_, seq);
    if (seq >= newest_seq_) {
      newest_seq_ = seq;
      newest_send_time_s_ = static_cast<double>(send_time_ns) * 1e-9;
    }
    ++received_;
    ++received_incarnation_;
    const double one_way = static_cast<double>(now_ns - send_time_ns) * 1e-9;
    one_way_mean_s_ += (one_way - one_way_mean_s_) / static_cast<double>(received_);
    one_way_max_s_ = std::max(one_way_max_s_, one_way);
  }
  // 1 - distinct received / (newest - lowest + 1) of the current incarnation (0 before any).
  double loss_fraction() const {
    if (received_incarnation_ == 0) return 0.0;
    const double span = static_cast<double>(newest_seq_ - lowest_seq_ + 1);
    return std::max(0.0, 1.0 - static_cast<double>(received_incarnation_) / span);
  }
  // incarnation, incarnation_changes, packets_received*, newest/lowest seq, loss, one-way.
  void fill(PeerStats& s) const {
    s.incarnation = incarnation_;
    s.incarnation_changes = incarnation_changes_;
    s.packets_received = received_;
    s.packets_received_incarnation = received_incarnation_;
    s.newest_seq = newest_seq_;
    s.newest_send_time_s = newest_send_time_s_;
    s.lowest_seq = lowest_seq_;
    s.loss_fraction = loss_fraction();
    s.one_way_mean_s = one_way_mean_s_;
    s.one_way_max_s = one_way_max_s_;
  }

 private:
  bool has_incarnation_ = false;
  std::uint64_t incarnation_ = 0, incarnation_changes_ = 0;
  std::uint64_t received_ = 0, received_incarnation_ = 0, newest_seq_ = 0, lowest_seq_ = 0;
  double newest_send_time_s_ = 0.0, one_way_mean_s_ = 0.0, one_way_max_s_ = 0.0;
};

}  // namespace haptic::net
