#include "net/round_trip.hpp"

#include <algorithm>

namespace haptic::net {

void ClockOffsetFilter::add(double t1, double t3, double hold, double t4) {
  const double t2 = t3 - hold;
  const double offset = ((t2 - t1) + (t3 - t4)) / 2.0;
  const double path = (t4 - t1) - hold;  // the offset's error is at most path / 2
  if (window_n_ == 0 || path < window_best_path_) {
    window_best_path_ = path;
    window_best_ = offset;
  }
  ++samples_;
  // The first window publishes as it goes; later ones when complete (min-RTT filter).
  if (samples_ <= kWindow || ++window_n_ >= kWindow) {
    offset_s_ = window_best_;
    path_s_ = window_best_path_;
  }
  if (samples_ <= kWindow) ++window_n_;
  if (window_n_ >= kWindow) window_n_ = 0;
}

void RoundTrip::note_received(std::uint64_t seq, std::int64_t send_time_ns, std::int64_t now_ns) {
  if (!echo_.valid || seq > echo_.seq) {
    previous_echo_ = echo_;
    echo_ = EchoSlot{true, seq, send_time_ns, now_ns};
  }
}

void RoundTrip::on_echo(std::uint64_t echo_seq, std::int64_t hold_ns, std::int64_t peer_send_ns, std::int64_t now_ns,
                        const SendRecords& records, std::int64_t echo_floor_ns) {
  if (sampled_any_ && echo_seq <= last_sampled_echo_) return;  // seen before
  const std::int64_t* sent = records.send_ns(echo_seq);
  if (sent == nullptr) {
    ++echoes_unmatched_;
    return;
  }
  sampled_any_ = true;
  last_sampled_echo_ = echo_seq;
  if (*sent < echo_floor_ns) {  // held through our own pause: not the link's round trip
    ++echoes_before_pause_;
    return;
  }
  if (rtt_.add_sample(static_cast<double>(now_ns - *sent) * 1e-9)) publish_bound();
  offset_.add(static_cast<double>(*sent) * 1e-9, static_cast<double>(peer_send_ns) * 1e-9,
              static_cast<double>(std::max<std::int64_t>(0, hold_ns)) * 1e-9, static_cast<double>(now_ns) * 1e-9);
}

void RoundTrip::restart() {
  echo_ = {};
  previous_echo_ = {};
  offset_.restart_window();
}

bool RoundTrip::finish_probing() {
  if (!rtt_.probing() && rtt_.has_bound()) return true;
  if (!rtt_.finish_probing()) return false;
  publish_bound();
  return true;
}

void RoundTrip::publish_bound() {
  bound_ns_.store(static_cast<std::uint64_t>(rtt_.bound_s() * 1e9), std::memory_order_relaxed);
  bound_generation_.store(rtt_.generation(), std::memory_order_release);
}

void RoundTrip::fill(PeerStats& s) const {
  s.rtt_samples = rtt_.samples();
  s.rtt_last_s = rtt_.last_s();
  s.rtt_mean_s = rtt_.mean_s();
  s.rtt_min_s = rtt_.min_s();
  s.rtt_max_s = rtt_.max_s();
  s.rtt_bound_s = rtt_.bound_s();
  s.rtt_probe_bound_s = rtt_.probe_bound_s();
  s.rtt_probing = rtt_.probing();
  s.rtt_has_bound = rtt_.has_bound();
  s.rtt_over_bound_events = rtt_.over_bound_events();
  s.rtt_bound_generation = rtt_.generation();
  s.echoes_unmatched = echoes_unmatched_;
  s.echoes_before_pause = echoes_before_pause_;
  s.clock_offset_samples = offset_.samples();
  s.clock_offset_s = offset_.offset_s();
  s.clock_offset_rtt_s = offset_.path_s();
}

}  // namespace haptic::net
