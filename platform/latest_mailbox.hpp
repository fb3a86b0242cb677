#pragma once
// Latest-value mailbox between exactly one writer thread and exactly one reader thread (a triple
// buffer). The writer never waits for the reader and the reader never waits for the writer; the
// reader always gets the newest complete value, older unread values are overwritten. Methods are
// named after the side that may call them (writer_*, reader_*), as ros2_control's realtime_tools
// names its methods after the calling side. Both sides are wait-free, lock-free and
// allocation-free, so either may be the real-time thread: the device driver's I/O thread writes
// samples the RT tick reads, the RT tick writes forces the driver reads (drivers/device.hpp), and
// the RT loop writes LoopReports a non-RT thread reads (platform/periodic_loop.hpp).
//
// Memory orders: one atomic byte `middle_` holds the index of the shared slot plus a "fresh" bit.
// The writer fills its private slot, then swaps it in with an acq_rel exchange: the release half
// publishes the slot contents, the acquire half makes the reader's earlier reads of the slot it
// gets back complete before the writer reuses it. The reader swaps its private slot in the same
// way, so it reads the newest slot only after acquiring it.
#include <array>
#include <atomic>
#include <cstdint>
#include <type_traits>

namespace haptic::platform {

template <class T>
class LatestMailbox {
  static_assert(std::is_trivially_copyable_v<T>, "LatestMailbox holds trivially copyable records");
  static_assert(std::atomic<std::uint8_t>::is_always_lock_free, "needs a lock-free atomic byte");

 public:
  // Writer side only: makes value the newest (an unread older value is dropped). Wait-free,
  // RT-safe.
  void writer_publish(const T& value) {
    slots_[write_index_] = value;
    writer_publish_slot();
  }

  // Writer side only: the private slot, to fill in place (large records: no second copy), then
  // writer_publish_slot() makes it the newest. Wait-free, RT-safe.
  T& writer_slot() { return slots_[write_index_]; }
  void writer_publish_slot() {
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(write_index_ | kFresh), std::memory_order_acq_rel);
    write_index_ = static_cast<std::uint8_t>(previous & kIndexMask);
  }

  // Reader side only: true and the newest value when something was published since the last
  // reader_take(), false (out untouched) otherwise. Wait-free, RT-safe.
  bool reader_take(T& out) {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t previous = middle_.exchange(read_index_, std::memory_order_acq_rel);
    read_index_ = static_cast<std::uint8_t>(previous & kIndexMask);
    out = slots_[read_index_];
    return true;
  }

  // Reader side only: whether a value is waiting. Wait-free, RT-safe.
  bool reader_has_fresh() const { return (middle_.load(std::memory_order_acquire) & kFresh) != 0; }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  std::array<T, 3> slots_{};
  alignas(64) std::atomic<std::uint8_t> middle_{1};
  alignas(64) std::uint8_t write_index_ = 0;  // writer-owned
  alignas(64) std::uint8_t read_index_ = 2;   // reader-owned
};

}  // namespace haptic::platform
