#pragma once
// The impairment emulator's delay queue: datagrams encoded now and sent at a later release time,
// in release order (equal times: queue order). Fixed capacity, allocated in the constructor; full
// means the caller drops (and counts) the datagram. I/O thread only; RT-safe after construction.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

namespace haptic::net {

class DelayQueue {
 public:
  DelayQueue(std::size_t capacity_datagrams, std::size_t max_datagram_bytes);
  // A free slot of max_datagram_bytes() to encode the next datagram into; nullptr when full.
  // Nothing is queued until commit().
  std::uint8_t* slot() { return free_.empty() ? nullptr : store_.data() + std::size_t{free_.back()} * max_bytes_; }
  // Queues the datagram of len bytes just written into slot(), to `dest` at release_ns.
  void commit(std::int64_t release_ns, std::uint16_t dest, std::size_t len);
  // Calls send(dest, data, len) for every datagram due by now_ns, in release order, and frees its slot.
  template <class Send>
  void release_due(std::int64_t now_ns, Send&& send) {
    while (!heap_.empty() && heap_.front().release_ns <= now_ns) {
      std::pop_heap(heap_.begin(), heap_.end(), later);
      const Entry e = heap_.back();
      heap_.pop_back();
      send(e.dest, store_.data() + std::size_t{e.slot} * max_bytes_, std::size_t{e.len});
      free_.push_back(e.slot);
    }
  }
  bool empty() const { return heap_.empty(); }
  std::size_t size() const { return heap_.size(); }
  std::size_t max_datagram_bytes() const { return max_bytes_; }
  // Release time of the next datagram (INT64_MAX when empty).
  std::int64_t next_release_ns() const {
    return heap_.empty() ? std::numeric_limits<std::int64_t>::max() : heap_.front().release_ns;
  }

 private:
  struct Entry {
    std::int64_t release_ns;
    std::uint64_t order;
    std::uint16_t dest;
    std::uint32_t len;
    std::uint32_t slot;
  };
  static bool later(const Entry& a, const Entry& b) {
    return a.release_ns != b.release_ns ? a.release_ns > b.release_ns : a.order > b.order;
  }
  std::size_t max_bytes_;
  std::vector<std::uint8_t> store_;
  std::vector<Entry> heap_;
  std::vector<std::uint32_t> free_;
  std::uint64_t order_ = 0;
};

}  // namespace haptic::net
