#pragma once
// Datagram transport seen by the I/O thread: non-blocking send to a station id, non-blocking
// receive, and a file descriptor to poll. Implementations: UdpTransport (transport_udp.hpp),
// RawEthernetTransport (transport_raw.hpp). Only the I/O thread calls these; never the RT thread.
#include <cstddef>
#include <cstdint>

namespace haptic::net {

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
  // Largest datagram this transport carries (MTU-derived).
  virtual std::size_t max_datagram_bytes() const = 0;
  virtual const char* name() const = 0;
};

}  // namespace haptic::net
