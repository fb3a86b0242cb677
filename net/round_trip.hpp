#pragma once
// Round trips and clock offset to one neighbour, from this station's own send records
// (net/README.md): the neighbour echoes the newest of our sequences it received and how long it
// held it; the round trip is our receipt time minus OUR send stamp of that sequence (a peer
// cannot make a round trip look shorter than it was), and with the holding time the echo gives
// the clock offset NTP-style. The other direction: the newest packets we received from the
// neighbour, for the echo in our own packets.
//
// All of this is owned by the I/O thread; RoundTrip publishes the current bound for the RT thread
// in two atomics (bound_ns(), generation()). RT-safe methods are marked.
#include <atomic>
#include <cstdint>
#include <vector>

#include "net/peer_stats.hpp"
#include "net/rtt.hpp"

namespace haptic::net {

// This station's own send records: sequence -> our send stamp (CLOCK_MONOTONIC ns), for the last
// kCapacity sequences. Allocates in the constructor only.
class SendRecords {
 public:
  static constexpr std::size_t kCapacity = 1024;  // 2 s of 2 ms ticks
  SendRecords() : records_(kCapacity) {}
  void record(std::uint64_t seq, std::int64_t send_ns) { records_[seq % kCapacity] = Record{true, seq, send_ns}; }  // RT-safe
  // Our send stamp of seq, or nullptr when seq was never sent or its record was overwritten. RT-safe.
  const std::int64_t* send_ns(std::uint64_t seq) const {
    const Record& r = records_[seq % kCapacity];
    return r.valid && r.seq == seq ? &r.send_ns : nullptr;
  }

 private:
  struct Record {
    bool valid = false;
    std::uint64_t seq = 0;
    std::int64_t send_ns = 0;
  };
  std::vector<Record> records_;
};

// Clock offset (peer clock - our clock) from echoes: t1 our send stamp, t2 = t3 - hold the peer's
// receipt, t3 its send stamp, t4 our receipt (seconds):
//   offset = ((t2 - t1) + (t3 - t4)) / 2, error at most path / 2 with path = (t4 - t1) - hold.
// The estimate is the lowest-path sample of a window of kWindow samples: the first window
// publishes as it goes, later ones when complete. RT-safe.
class ClockOffsetFilter {
 public:
  static constexpr std::uint64_t kWindow = 128;
  void add(double t1, double t3, double hold, double t4);
  void restart_window() { window_n_ = 0; }  // the neighbour restarted: a new window, same estimate until it fills
  std::uint64_t samples() const { return samples_; }
  double offset_s() const { return offset_s_; }
  double path_s() const { return path_s_; }  // round trip (minus hold) of the sample offset_s() came from

 private:
  std::uint64_t samples_ = 0, window_n_ = 0;
  double window_best_path_ = 0.0, window_best_ = 0.0;
  double offset_s_ = 0.0, path_s_ = 0.0;
};

// One received packet of the neighbour that we may echo back (wire echo_seq, echo_hold_ns).
struct EchoSlot {
  bool valid = false;
  std::uint64_t seq = 0;
  std::int64_t send_time_ns = 0;     // the neighbour's stamp
  std::int64_t receive_time_ns = 0;  // ours
};

// Of the newest two received packets, the newest one received by stamp_ns (nullptr: none). RT-safe.
inline const EchoSlot* newest_echo_by(const EchoSlot& newest, const EchoSlot& previous, std::int64_t stamp_ns) {
  if (newest.valid && newest.receive_time_ns <= stamp_ns) return &newest;
  if (previous.valid && previous.receive_time_ns <= stamp_ns) return &previous;
  return nullptr;
}

class RoundTrip {
 public:
  explicit RoundTrip(const RttConfig& cfg = {}) : rtt_(cfg) {}

  // ---- what we echo (our packets to the neighbour) ----
  // A state packet of the neighbour received at now_ns: the newest one is kept to echo, with the one before it. RT-safe.
  void note_received(std::uint64_t seq, std::int64_t send_time_ns, std::int64_t now_ns);
  // The newest packet received by stamp_ns (the send stamp of the packet that echoes it), so the
  // neighbour's age bound (now - its own send time of the echo) never understates the age; nullptr: none. RT-safe.
  const EchoSlot* echo_as_of(std::int64_t stamp_ns) const { return newest_echo_by(echo_, previous_echo_, stamp_ns); }
  // The newest two, as echo_as_of() chooses from them (for the tick's direct TX, tx_direct.hpp).
  const EchoSlot& newest_echo() const { return echo_; }
  const EchoSlot& previous_echo() const { return previous_echo_; }

  // ---- what the neighbour echoes (its packets to us) ----
  // The echo of one of our sequences, held hold_ns by the neighbour, in its packet stamped
  // peer_send_ns (its clock) and received at now_ns: the first time this echo is seen, a round-trip
  // sample from our send record and a clock-offset sample; an echo naming a sequence we have no
  // record of is counted (echoes_unmatched). An over-bound sample publishes the raised bound.
  // An echo of a packet we sent before echo_floor_ns (the end of a planned pause of our sending:
  // the gap between probing and the run) is no sample: the neighbour held it through our pause, so
  // now - send stamp measures the pause, not the link; counted (echoes_before_pause). RT-safe.
  void on_echo(std::uint64_t echo_seq, std::int64_t hold_ns, std::int64_t peer_send_ns, std::int64_t now_ns,
               const SendRecords& records, std::int64_t echo_floor_ns = 0);
  // A new incarnation of the neighbour: its echoes and the offset window start afresh.
  void restart();

  // ---- probing (the I/O thread, on the station's command) ----
  void begin_probing() { rtt_.begin_probing(); }
  // Ends probing when enough samples were taken (publishing the bound); true when a bound is fixed.
  bool finish_probing();
  const RttEstimator& estimator() const { return rtt_; }

  // ---- the RT thread's view (atomics) ----
  std::uint64_t bound_ns() const { return bound_ns_.load(std::memory_order_acquire); }
  std::uint64_t generation() const { return bound_generation_.load(std::memory_order_acquire); }

  const ClockOffsetFilter& clock_offset() const { return offset_; }
  std::uint64_t echoes_unmatched() const { return echoes_unmatched_; }
  // The rtt_*, echoes_unmatched and clock_offset_* fields of the neighbour's statistics.
  void fill(PeerStats& s) const;

 private:
  void publish_bound();
  RttEstimator rtt_;
  ClockOffsetFilter offset_;
  EchoSlot echo_, previous_echo_;
  std::uint64_t last_sampled_echo_ = 0;
  bool sampled_any_ = false;
  std::uint64_t echoes_unmatched_ = 0, echoes_before_pause_ = 0;
  std::atomic<std::uint64_t> bound_ns_{0};
  std::atomic<std::uint64_t> bound_generation_{0};
};

}  // namespace haptic::net
