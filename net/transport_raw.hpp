#pragma once
// Raw Ethernet transport (AF_PACKET, SOCK_DGRAM) for a lab LAN: our datagram is the whole
// Ethernet payload, with the project's own EtherType 0x88B5, which is IEEE 802 "Local
// Experimental EtherType 1" (reserved by IEEE Std 802 for local experiments; never assigned to
// a product protocol). Needs CAP_NET_RAW (root). Non-blocking socket bound to one interface.
#include <linux/if_packet.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "net/transport.hpp"

namespace haptic::net {

inline constexpr std::uint16_t kEtherTypeLocalExperimental1 = 0x88B5;

using MacAddress = std::array<std::uint8_t, 6>;
// "aa:bb:cc:dd:ee:ff"; throws std::invalid_argument naming config_key.
MacAddress parse_mac(const std::string& text, const std::string& config_key);
std::string format_mac(const MacAddress& mac);
// The hardware address of a local interface; throws std::system_error if it does not exist.
MacAddress interface_mac(const std::string& ifname);

struct RawPeer {
  std::uint16_t station_id = 0;
  MacAddress mac{};
};

class RawEthernetTransport final : public Transport {
 public:
  // Throws std::system_error (e.g. EPERM without CAP_NET_RAW, ENODEV for a bad net.interface).
  RawEthernetTransport(const std::string& ifname, const std::vector<RawPeer>& peers,
                       std::uint16_t ethertype = kEtherTypeLocalExperimental1);
  ~RawEthernetTransport() override;
  RawEthernetTransport(const RawEthernetTransport&) = delete;
  RawEthernetTransport& operator=(const RawEthernetTransport&) = delete;

  int fd() const override { return fd_; }
  bool send_to(std::uint16_t dest, const std::uint8_t* data, std::size_t len) override;
  long receive(std::uint8_t* buf, std::size_t cap) override;
  // The source is the peer whose configured MAC sent the frame.
  long receive_from(std::uint8_t* buf, std::size_t cap, int& source) override;
  // One sendmmsg per kBatch frames (MSG_DONTWAIT), one recvmmsg per batch received.
  std::size_t send_batch(const TxDatagram* d, std::size_t n, int& error) override;
  long receive_batch(RxDatagram* d, std::size_t n) override;
  std::size_t max_datagram_bytes() const override { return mtu_; }
  const char* name() const override { return "raw-ethernet"; }
  const MacAddress& local_mac() const { return local_mac_; }

 private:
  // The link-layer address of station dest (false: not a configured peer).
  bool address_of(std::uint16_t dest, sockaddr_ll& sll) const;
  int source_of(const sockaddr_ll& from) const;
  int fd_ = -1;
  int ifindex_ = 0;
  std::uint16_t ethertype_;
  std::size_t mtu_ = 1500;
  MacAddress local_mac_{};
  std::vector<RawPeer> peers_;
};

}  // namespace haptic::net
