#pragma once
// UDP transport over IPv4 or IPv6 (the Internet case). Addresses are numeric only
// ("127.0.0.1:7001", "[::1]:7001"); no name resolution at run time. Non-blocking socket.
#include <netinet/in.h>
#include <sys/socket.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "net/transport.hpp"

namespace haptic::net {

struct UdpPeer {
  std::uint16_t station_id = 0;
  std::string address;  // "host:port", IPv6 as "[addr]:port"
};

// Parses "a.b.c.d:port" or "[v6]:port" into a sockaddr_storage; throws std::invalid_argument
// naming config_key on a bad address.
sockaddr_storage parse_udp_address(const std::string& text, const std::string& config_key, socklen_t& len);

class UdpTransport final : public Transport {
 public:
  // bind_address: this station's "host:port" (net.bind); peers must be of the same family.
  // The wildcard address (0.0.0.0, [::]) is refused unless listen_any (net.listen_any).
  // Throws std::system_error / std::invalid_argument at start-up.
  UdpTransport(const std::string& bind_address, const std::vector<UdpPeer>& peers, bool listen_any = false);
  ~UdpTransport() override;
  UdpTransport(const UdpTransport&) = delete;
  UdpTransport& operator=(const UdpTransport&) = delete;

  int fd() const override { return fd_; }
  bool send_to(std::uint16_t dest, const std::uint8_t* data, std::size_t len) override;
  long receive(std::uint8_t* buf, std::size_t cap) override;
  // The source is the peer whose configured address (address and port) sent it.
  long receive_from(std::uint8_t* buf, std::size_t cap, int& source) override;
  // One sendmmsg per kBatch datagrams (MSG_DONTWAIT), one recvmmsg per batch received.
  std::size_t send_batch(const TxDatagram* d, std::size_t n, int& error) override;
  long receive_batch(RxDatagram* d, std::size_t n) override;
  std::size_t max_datagram_bytes() const override { return max_datagram_bytes_for(family_); }
  // The largest UDP payload sent without IP fragmentation on a 1500-byte MTU, per address family.
  static constexpr std::size_t max_datagram_bytes_for(int family) { return family == AF_INET6 ? 1452 : 1472; }
  const char* name() const override { return family_ == AF_INET6 ? "udp6" : "udp4"; }
  std::uint16_t local_port() const;
  // Adds or replaces a peer's address (start-up only, before the I/O thread runs).
  void set_peer(const UdpPeer& peer);

 private:
  struct Peer {
    std::uint16_t id;
    sockaddr_storage addr;
    socklen_t len;
  };
  const Peer* find(std::uint16_t id) const;
  int source_of(const sockaddr_storage& from) const;
  int fd_ = -1;
  int family_ = AF_INET;
  std::vector<Peer> peers_;
};

}  // namespace haptic::net
