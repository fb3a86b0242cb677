#pragma once
// Direct TX (EndpointConfig::tx_direct, net.tx_direct): the RT tick encodes its push and hands it
// to the kernel itself, one non-blocking sendmmsg for every neighbour's datagrams, instead of
// waking the I/O thread to do it. No thread wake-up and no spinning core on the send path.
//
// What the tick needs per neighbour and the I/O thread owns (the pair's traffic key, the newest
// packets we received from it, for the echo) the I/O thread publishes as a DirectTicket in a
// seqlock box after each of its steps; the tick reads it once, wait-free, and takes the I/O
// thread's path when a ticket is being written or a neighbour is not ready (keys not agreed, an
// impaired link). The tick still publishes the push on the TX ring: the I/O thread does the rest
// of the push's work from it later (send records, statistics, fingerprints, hellos) and sends the
// datagrams the kernel would not take (EAGAIN, ENOBUFS: counted, never lost).
// Bounded: only while one push is at most kDirectMaxDatagrams datagrams over all neighbours
// (encode + MAC of each on the tick: measured in net/README.md), else always the I/O thread.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "net/round_trip.hpp"
#include "net/transport.hpp"
#include "net/wire.hpp"

namespace haptic::net {

inline constexpr std::size_t kDirectMaxDatagrams = 16;

// Published by the I/O thread per neighbour (platform::SnapshotBox), read by the tick.
struct DirectTicket {
  bool ready = false;            // keys agreed (or the shared key) and the link is not impaired
  std::uint16_t station_id = 0;
  SessionKey key{};              // the traffic key of our direction (pairwise), else the shared key
  EchoSlot echo{}, previous{};   // RoundTrip's newest two received packets of the neighbour
};

// What the tick did with one push, per neighbour (index as in the endpoint's peers), carried to
// the I/O thread in the push's TX record.
struct DirectPeerSend {
  bool has_echo = false;
  std::uint64_t echo_seq = 0;
  std::int64_t echo_hold_ns = 0;
  std::uint16_t datagrams_sent = 0;  // the first datagrams_sent fragments went out
  std::uint32_t bytes_sent = 0;
};
struct DirectPush {
  bool attempted = false;   // the tick encoded this push and tried to send it
  bool complete = false;    // every datagram went out
  int error = 0;            // errno that stopped it (EAGAIN / ENOBUFS: the socket would block)
  std::int64_t stamp_ns = 0;
  std::int64_t done_ns = 0; // CLOCK_MONOTONIC after the send (push -> kernel: the hand-off)
  DirectPeerSend peer[kDirectMaxDatagrams];
};

// The tick's encoder and batch: buffers for kDirectMaxDatagrams datagrams, allocated here.
class DirectSender {
 public:
  // peers x fragments above kDirectMaxDatagrams: enabled() is false (the push is too large).
  DirectSender(const Encoder& encoder, Transport& transport, std::size_t peers, std::uint32_t value_count,
               std::size_t max_datagram_bytes);
  bool enabled() const { return enabled_; }
  // Encodes state s (its dest and echo are set here, per ticket) for tickets[0..n) and sends every
  // datagram in one batch; fills rec. RT-safe: no allocation, no lock, one or two non-blocking
  // system calls. Every ticket must be ready.
  void send(OutgoingState s, const DirectTicket* tickets, std::size_t n, DirectPush& rec);

 private:
  const Encoder& encoder_;
  Transport& transport_;
  std::size_t frags_;
  std::size_t cap_;
  bool enabled_;
  std::vector<std::uint8_t> store_;
  TxDatagram batch_[kDirectMaxDatagrams];
  std::uint8_t owner_[kDirectMaxDatagrams] = {};
};

}  // namespace haptic::net
