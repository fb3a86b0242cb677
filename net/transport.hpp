#pragma once
// Datagram transport seen by the I/O thread: non-blocking send to a station id, non-blocking
// receive, and a file descriptor to poll. Implementations: UdpTransport (transport_udp.hpp),
// RawEthernetTransport (transport_raw.hpp). Only the I/O thread calls these, except send_batch(),
// which the RT tick may call too (direct TX, net.tx_direct): it never blocks, never allocates and
// touches nothing the I/O thread writes (the kernel orders two threads' sends on one socket).
#include <cstddef>
#include <cstdint>

namespace haptic::net {

// One datagram of a batch send: to station `dest`, bytes data[0, len).
struct TxDatagram {
  std::uint16_t dest = 0;
  const std::uint8_t* data = nullptr;
  std::size_t len = 0;
};
// One datagram of a batch receive: the caller's buffer (buf, cap); the transport fills len (the
// datagram's real size, larger than cap when it was truncated: MSG_TRUNC) and source (as receive_from()).
struct RxDatagram {
  std::uint8_t* buf = nullptr;
  std::size_t cap = 0;
  std::size_t len = 0;
  int source = -2;
};

class Transport {
 public:
  virtual ~Transport() = default;
  virtual int fd() const = 0;
  // Sends one datagram to station `dest`. false on error or unknown station (counted by caller).
  virtual bool send_to(std::uint16_t dest, const std::uint8_t* data, std::size_t len) = 0;
  // Receives one datagram into buf: its size, 0 when none is waiting, -1 on error.
  virtual long receive(std::uint8_t* buf, std::size_t cap) = 0;
  // Receives one datagram and says who sent it: its size (0 for an empty datagram),
  // kNoDatagram when none is waiting, -1 on error. `source` = the station id configured at
  // the datagram's source address (UDP address and port, source MAC), kSourceUnknown (-1) for
  // any other address, or kSourceUnchecked (-2) when the transport cannot tell (this default,
  // for in-process test transports). I/O thread only.
  static constexpr long kNoDatagram = -2;
  virtual long receive_from(std::uint8_t* buf, std::size_t cap, int& source) {
    source = -2;
    const long n = receive(buf, cap);
    return n == 0 ? kNoDatagram : n;
  }
  // Sends d[0..n) in order without blocking (one sendmmsg where the transport has it) and returns
  // how many went out: n, or fewer when the socket would block or a send failed, with the errno in
  // `error` (EAGAIN / EWOULDBLOCK / ENOBUFS: would block; 0 when all went). Any thread; RT-safe
  // (no allocation; at most ceil(n / kBatch) system calls).
  static constexpr std::size_t kBatch = 16;
  virtual std::size_t send_batch(const TxDatagram* d, std::size_t n, int& error);
  // Receives up to n datagrams (one recvmmsg where the transport has it): how many (0 when none is
  // waiting), -1 on an error before the first. I/O thread only.
  virtual long receive_batch(RxDatagram* d, std::size_t n);
  // Largest datagram this transport carries (MTU-derived).
  virtual std::size_t max_datagram_bytes() const = 0;
  virtual const char* name() const = 0;
};

}  // namespace haptic::net
