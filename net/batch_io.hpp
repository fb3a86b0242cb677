#pragma once
// The batch system calls of the datagram transports (transport_udp.cpp, transport_raw.cpp):
// sendmmsg in rounds of Transport::kBatch, recvmmsg of one batch. The address of each datagram is
// the transport's (a UDP peer's sockaddr, a peer's link-layer address). No allocation: the message
// headers live on the stack. Any thread may send; one receives.
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>

#include "net/transport.hpp"

namespace haptic::net::batch_io {

// Sends d[0..n) in order (MSG_DONTWAIT): how many went out; error = the errno that stopped it (0: all
// went; EINVAL: a station address_of does not know). address_of(dest, sockaddr_storage&, socklen_t&) -> bool.
template <class AddressOf>
std::size_t send(int fd, const TxDatagram* d, std::size_t n, int& error, AddressOf&& address_of) {
  error = 0;
  std::size_t done = 0;
  while (done < n) {
    mmsghdr m[Transport::kBatch];
    iovec io[Transport::kBatch];
    sockaddr_storage to[Transport::kBatch];
    std::size_t k = 0;
    for (; k < Transport::kBatch && done + k < n; ++k) {
      const TxDatagram& t = d[done + k];
      socklen_t len = 0;
      if (!address_of(t.dest, to[k], len)) break;  // unknown station: send what comes before it, then fail
      io[k] = iovec{const_cast<std::uint8_t*>(t.data), t.len};
      m[k] = mmsghdr{};
      m[k].msg_hdr.msg_name = &to[k];
      m[k].msg_hdr.msg_namelen = len;
      m[k].msg_hdr.msg_iov = &io[k];
      m[k].msg_hdr.msg_iovlen = 1;
    }
    if (k == 0) {
      error = EINVAL;
      return done;
    }
    const int sent = ::sendmmsg(fd, m, static_cast<unsigned>(k), MSG_DONTWAIT);
    if (sent < 0) {
      error = errno;
      return done;
    }
    // Fewer than k: the next round starts at the one the kernel did not take, and sendmmsg says why (-1).
    done += static_cast<std::size_t>(sent);
  }
  return done;
}

// Receives up to n (at most kBatch) datagrams (MSG_DONTWAIT | MSG_TRUNC: each len is the real size):
// how many were kept, 0 when none is waiting, -1 on error. source_of(const sockaddr_storage& from, int&
// source) -> bool: false drops the datagram (e.g. our own frame looped back); later ones move down.
template <class SourceOf>
long receive(int fd, RxDatagram* d, std::size_t n, SourceOf&& source_of) {
  mmsghdr m[Transport::kBatch];
  iovec io[Transport::kBatch];
  sockaddr_storage from[Transport::kBatch];
  const std::size_t k = std::min(n, Transport::kBatch);
  for (std::size_t i = 0; i < k; ++i) {
    io[i] = iovec{d[i].buf, d[i].cap};
    m[i] = mmsghdr{};
    m[i].msg_hdr.msg_name = &from[i];
    m[i].msg_hdr.msg_namelen = sizeof from[i];
    m[i].msg_hdr.msg_iov = &io[i];
    m[i].msg_hdr.msg_iovlen = 1;
  }
  const int got = ::recvmmsg(fd, m, static_cast<unsigned>(k), MSG_DONTWAIT | MSG_TRUNC, nullptr);
  if (got < 0) return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
  std::size_t kept = 0;
  for (int i = 0; i < got; ++i) {
    int source = -1;
    if (!source_of(from[i], source)) continue;
    if (kept != static_cast<std::size_t>(i)) std::copy_n(d[i].buf, std::min<std::size_t>(m[i].msg_len, d[i].cap), d[kept].buf);
    d[kept].len = m[i].msg_len;
    d[kept].source = source;
    ++kept;
  }
  return static_cast<long>(kept);
}

}  // namespace haptic::net::batch_io
