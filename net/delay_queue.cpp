#include "net/delay_queue.hpp"

namespace haptic::net {

DelayQueue::DelayQueue(std::size_t capacity_datagrams, std::size_t max_datagram_bytes)
    : max_bytes_(max_datagram_bytes), store_(capacity_datagrams * max_datagram_bytes) {
  heap_.reserve(capacity_datagrams);
  free_.reserve(capacity_datagrams);
  for (std::size_t i = capacity_datagrams; i-- > 0;) free_.push_back(static_cast<std::uint32_t>(i));
}

void DelayQueue::commit(std::int64_t release_ns, std::uint16_t dest, std::size_t len) {
  const std::uint32_t slot = free_.back();
  free_.pop_back();
  heap_.push_back(Entry{release_ns, order_++, dest, static_cast<std::uint32_t>(len), slot});
  std::push_heap(heap_.begin(), heap_.end(), later);
}

}  // namespace haptic::net
