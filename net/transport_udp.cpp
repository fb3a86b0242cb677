#include "net/transport_udp.hpp"

#include "net/batch_io.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace haptic::net {

sockaddr_storage parse_udp_address(const std::string& text, const std::string& config_key, socklen_t& len) {
  sockaddr_storage ss{};
  auto bad = [&] {
    return std::invalid_argument(config_key + " = \"" + text +
                                 "\": expected a numeric \"a.b.c.d:port\" or \"[ipv6]:port\" with port in [0, 65535]");
  };
  std::string host, port;
  if (!text.empty() && text[0] == '[') {
    const auto close = text.find(']');
    if (close == std::string::npos || close + 1 >= text.size() || text[close + 1] != ':') throw bad();
    host = text.substr(1, close - 1);
    port = text.substr(close + 2);
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos) throw bad();
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos) throw bad();
  const unsigned long p = std::stoul(port);
  if (p > 65535) throw bad();
  auto* v4 = reinterpret_cast<sockaddr_in*>(&ss);
  auto* v6 = reinterpret_cast<sockaddr_in6*>(&ss);
  if (inet_pton(AF_INET, host.c_str(), &v4->sin_addr) == 1) {
    v4->sin_family = AF_INET;
    v4->sin_port = htons(static_cast<std::uint16_t>(p));
    len = sizeof(sockaddr_in);
  } else if (inet_pton(AF_INET6, host.c_str(), &v6->sin6_addr) == 1) {
    v6->sin6_family = AF_INET6;
    v6->sin6_port = htons(static_cast<std::uint16_t>(p));
    len = sizeof(sockaddr_in6);
  } else {
    throw bad();
  }
  return ss;
}

namespace {
bool is_wildcard(const sockaddr_storage& a) {
  if (a.ss_family == AF_INET) return reinterpret_cast<const sockaddr_in*>(&a)->sin_addr.s_addr == htonl(INADDR_ANY);
  const in6_addr& v6 = reinterpret_cast<const sockaddr_in6*>(&a)->sin6_addr;
  return IN6_IS_ADDR_UNSPECIFIED(&v6);
}
// Same address and port (the source of a datagram against a peer's configured address).
bool same_endpoint(const sockaddr_storage& a, const sockaddr_storage& b) {
  if (a.ss_family != b.ss_family) return false;
  if (a.ss_family == AF_INET) {
    const auto* x = reinterpret_cast<const sockaddr_in*>(&a);
    const auto* y = reinterpret_cast<const sockaddr_in*>(&b);
    return x->sin_port == y->sin_port && x->sin_addr.s_addr == y->sin_addr.s_addr;
  }
  const auto* x = reinterpret_cast<const sockaddr_in6*>(&a);
  const auto* y = reinterpret_cast<const sockaddr_in6*>(&b);
  return x->sin6_port == y->sin6_port && std::memcmp(&x->sin6_addr, &y->sin6_addr, sizeof(in6_addr)) == 0;
}
}  // namespace

UdpTransport::UdpTransport(const std::string& bind_address, const std::vector<UdpPeer>& peers, bool listen_any) {
  socklen_t blen = 0;
  const sockaddr_storage local = parse_udp_address(bind_address, "net.bind", blen);
  if (is_wildcard(local) && !listen_any)
    throw std::invalid_argument("net.bind = \"" + bind_address +
                                "\" listens on every interface: name this station's own address, or set "
                                "net.listen_any = true to accept that (neighbours are still only accepted from "
                                "their configured addresses)");
  family_ = local.ss_family;
  for (const auto& p : peers) {
    Peer q{};
    q.id = p.station_id;
    q.addr = parse_udp_address(p.address, "net.peers[" + std::to_string(p.station_id) + "].address", q.len);
    if (q.addr.ss_family != family_)
      throw std::invalid_argument("net.peers[" + std::to_string(p.station_id) + "].address \"" + p.address +
                                  "\" is not the same address family as net.bind \"" + bind_address + "\"");
    peers_.push_back(q);
  }
  fd_ = ::socket(family_, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, IPPROTO_UDP);
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "net: socket(UDP)");
  if (family_ == AF_INET6) {
    int one = 1;
    ::setsockopt(fd_, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof one);
  }
  int buf = 4 << 20;
  // Root may exceed net.core.rmem_max (needed for fragmented large scenes); else best effort.
  if (::setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &buf, sizeof buf) != 0)
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &buf, sizeof buf);
  ::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &buf, sizeof buf);
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&local), blen) != 0) {
    const int e = errno;
    ::close(fd_);
    throw std::system_error(e, std::generic_category(), "net: bind(" + bind_address + ") (net.bind)");
  }
}

void UdpTransport::set_peer(const UdpPeer& p) {
  Peer q{};
  q.id = p.station_id;
  q.addr = parse_udp_address(p.address, "net.peers[" + std::to_string(p.station_id) + "].address", q.len);
  if (q.addr.ss_family != family_)
    throw std::invalid_argument("net.peers[" + std::to_string(p.station_id) + "].address \"" + p.address +
                                "\" is not the same address family as net.bind");
  for (auto& e : peers_)
    if (e.id == q.id) {
      e = q;
      return;
    }
  peers_.push_back(q);
}

UdpTransport::~UdpTransport() {
  if (fd_ >= 0) ::close(fd_);
}

std::uint16_t UdpTransport::local_port() const {
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&ss), &len) != 0) return 0;
  if (ss.ss_family == AF_INET) return ntohs(reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
  return ntohs(reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port);
}

const UdpTransport::Peer* UdpTransport::find(std::uint16_t id) const {
  for (const auto& p : peers_)
    if (p.id == id) return &p;
  return nullptr;
}

int UdpTransport::source_of(const sockaddr_storage& from) const {
  for (const auto& p : peers_)
    if (same_endpoint(from, p.addr)) return p.id;
  return -1;
}

bool UdpTransport::send_to(std::uint16_t dest, const std::uint8_t* data, std::size_t len) {
  const Peer* p = find(dest);
  if (p == nullptr) return false;
  const ssize_t n = ::sendto(fd_, data, len, 0, reinterpret_cast<const sockaddr*>(&p->addr), p->len);
  return n == static_cast<ssize_t>(len);
}

std::size_t UdpTransport::send_batch(const TxDatagram* d, std::size_t n, int& error) {
  return batch_io::send(fd_, d, n, error, [this](std::uint16_t dest, sockaddr_storage& to, socklen_t& len) {
    const Peer* p = find(dest);
    if (p == nullptr) return false;
    to = p->addr;
    len = p->len;
    return true;
  });
}

long UdpTransport::receive_batch(RxDatagram* d, std::size_t n) {
  return batch_io::receive(fd_, d, n, [this](const sockaddr_storage& from, int& source) {
    source = source_of(from);
    return true;
  });
}

long UdpTransport::receive(std::uint8_t* buf, std::size_t cap) {
  const ssize_t n = ::recv(fd_, buf, cap, MSG_TRUNC);
  if (n < 0) return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
  // MSG_TRUNC: n is the real size; a datagram larger than cap comes back as its real size so
  // the decoder drops it as oversized without reading past buf.
  return static_cast<long>(n);
}

long UdpTransport::receive_from(std::uint8_t* buf, std::size_t cap, int& source) {
  sockaddr_storage from{};
  socklen_t flen = sizeof from;
  const ssize_t n = ::recvfrom(fd_, buf, cap, MSG_TRUNC, reinterpret_cast<sockaddr*>(&from), &flen);
  if (n < 0) return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? kNoDatagram : -1;
  source = source_of(from);
  return static_cast<long>(n);  // MSG_TRUNC: the real size (see receive())
}

}  // namespace haptic::net
