#include "net/transport.hpp"

#include <cerrno>

namespace haptic::net {

std::size_t Transport::send_batch(const TxDatagram* d, std::size_t n, int& error) {
  error = 0;
  for (std::size_t i = 0; i < n; ++i) {
    errno = 0;
    if (!send_to(d[i].dest, d[i].data, d[i].len)) {
      error = errno != 0 ? errno : EIO;
      return i;
    }
  }
  return n;
}

long Transport::receive_batch(RxDatagram* d, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const long len = receive_from(d[i].buf, d[i].cap, d[i].source);
    if (len == kNoDatagram) return static_cast<long>(i);
    if (len < 0) return i > 0 ? static_cast<long>(i) : -1;
    d[i].len = static_cast<std::size_t>(len);
  }
  return static_cast<long>(n);
}

}  // namespace haptic::net
