#include "net/transport_raw.hpp"

#include "net/batch_io.hpp"

#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace haptic::net {

MacAddress parse_mac(const std::string& text, const std::string& config_key) {
  MacAddress m{};
  unsigned v[6];
  char tail = 0;
  if (std::sscanf(text.c_str(), "%2x:%2x:%2x:%2x:%2x:%2x%c", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &tail) != 6)
    throw std::invalid_argument(config_key + " = \"" + text + "\": expected a MAC address aa:bb:cc:dd:ee:ff");
  for (int i = 0; i < 6; ++i) m[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v[i]);
  return m;
}

std::string format_mac(const MacAddress& m) {
  char s[18];
  std::snprintf(s, sizeof s, "%02x:%02x:%02x:%02x:%02x:%02x", m[0], m[1], m[2], m[3], m[4], m[5]);
  return s;
}

namespace {
struct Ifr {
  int fd;
  ifreq ifr{};
  explicit Ifr(const std::string& ifname) {
    if (ifname.empty() || ifname.size() >= IFNAMSIZ)
      throw std::invalid_argument("net.interface = \"" + ifname + "\": expected an interface name of 1-15 characters");
    fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0) throw std::system_error(errno, std::generic_category(), "net: socket for ioctl");
    std::memcpy(ifr.ifr_name, ifname.c_str(), ifname.size() + 1);
  }
  ~Ifr() { ::close(fd); }
  void io(unsigned long req, const std::string& what) {
    if (::ioctl(fd, req, &ifr) != 0)
      throw std::system_error(errno, std::generic_category(),
                              "net: " + what + " of interface " + std::string(ifr.ifr_name) + " (net.interface)");
  }
};
}  // namespace

MacAddress interface_mac(const std::string& ifname) {
  Ifr r(ifname);
  r.io(SIOCGIFHWADDR, "hardware address");
  MacAddress m{};
  std::memcpy(m.data(), r.ifr.ifr_hwaddr.sa_data, 6);
  return m;
}

RawEthernetTransport::RawEthernetTransport(const std::string& ifname, const std::vector<RawPeer>& peers,
                                           std::uint16_t ethertype)
    : ethertype_(ethertype), peers_(peers) {
  {
    Ifr r(ifname);
    r.io(SIOCGIFINDEX, "index");
    ifindex_ = r.ifr.ifr_ifindex;
    r.io(SIOCGIFMTU, "MTU");
    mtu_ = static_cast<std::size_t>(r.ifr.ifr_mtu);
    r.io(SIOCGIFHWADDR, "hardware address");
    std::memcpy(local_mac_.data(), r.ifr.ifr_hwaddr.sa_data, 6);
  }
  fd_ = ::socket(AF_PACKET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, htons(ethertype_));
  if (fd_ < 0)
    throw std::system_error(errno, std::generic_category(),
                            "net: socket(AF_PACKET) needs CAP_NET_RAW (run as root) for transport = \"raw\"");
  sockaddr_ll sll{};
  sll.sll_family = AF_PACKET;
  sll.sll_protocol = htons(ethertype_);
  sll.sll_ifindex = ifindex_;
  if (::bind(fd_, reinterpret_cast<sockaddr*>(&sll), sizeof sll) != 0) {
    const int e = errno;
    ::close(fd_);
    throw std::system_error(e, std::generic_category(), "net: bind(AF_PACKET) to " + ifname + " (net.interface)");
  }
  int buf = 4 << 20;
  // Root may exceed net.core.rmem_max (needed for fragmented large scenes); else best effort.
  if (::setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &buf, sizeof buf) != 0)
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &buf, sizeof buf);
}

RawEthernetTransport::~RawEthernetTransport() {
  if (fd_ >= 0) ::close(fd_);
}

bool RawEthernetTransport::address_of(std::uint16_t dest, sockaddr_ll& sll) const {
  for (const auto& p : peers_) {
    if (p.station_id != dest) continue;
    sll = sockaddr_ll{};
    sll.sll_family = AF_PACKET;
    sll.sll_protocol = htons(ethertype_);
    sll.sll_ifindex = ifindex_;
    sll.sll_halen = 6;
    std::memcpy(sll.sll_addr, p.mac.data(), 6);
    return true;
  }
  return false;
}

int RawEthernetTransport::source_of(const sockaddr_ll& from) const {
  for (const auto& p : peers_)
    if (from.sll_halen == 6 && std::memcmp(from.sll_addr, p.mac.data(), 6) == 0) return p.station_id;
  return -1;
}

bool RawEthernetTransport::send_to(std::uint16_t dest, const std::uint8_t* data, std::size_t len) {
  sockaddr_ll sll{};
  if (!address_of(dest, sll)) return false;
  const ssize_t n = ::sendto(fd_, data, len, 0, reinterpret_cast<sockaddr*>(&sll), sizeof sll);
  return n == static_cast<ssize_t>(len);
}

std::size_t RawEthernetTransport::send_batch(const TxDatagram* d, std::size_t n, int& error) {
  return batch_io::send(fd_, d, n, error, [this](std::uint16_t dest, sockaddr_storage& to, socklen_t& len) {
    sockaddr_ll sll{};
    if (!address_of(dest, sll)) return false;
    std::memcpy(&to, &sll, sizeof sll);
    len = sizeof sll;
    return true;
  });
}

long RawEthernetTransport::receive_batch(RxDatagram* d, std::size_t n) {
  return batch_io::receive(fd_, d, n, [this](const sockaddr_storage& from, int& source) {
    sockaddr_ll sll{};
    std::memcpy(&sll, &from, sizeof sll);
    if (sll.sll_pkttype == PACKET_OUTGOING) return false;  // our own frames looped back to us
    source = source_of(sll);
    return true;
  });
}

long RawEthernetTransport::receive(std::uint8_t* buf, std::size_t cap) {
  for (;;) {
    sockaddr_ll from{};
    socklen_t flen = sizeof from;
    const ssize_t n = ::recvfrom(fd_, buf, cap, MSG_TRUNC, reinterpret_cast<sockaddr*>(&from), &flen);
    if (n < 0) return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
    if (from.sll_pkttype == PACKET_OUTGOING) continue;  // our own frames looped back to us
    return static_cast<long>(n);
  }
}

long RawEthernetTransport::receive_from(std::uint8_t* buf, std::size_t cap, int& source) {
  for (;;) {
    sockaddr_ll from{};
    socklen_t flen = sizeof from;
    const ssize_t n = ::recvfrom(fd_, buf, cap, MSG_TRUNC, reinterpret_cast<sockaddr*>(&from), &flen);
    if (n < 0) return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? kNoDatagram : -1;
    if (from.sll_pkttype == PACKET_OUTGOING) continue;
    source = source_of(from);
    return static_cast<long>(n);
  }
}

}  // namespace haptic::net
