#pragma once
// Latest-value mailbox between exactly one writer thread and one reader thread (a triple
// buffer). The writer never waits for the reader and the reader never waits for the writer;
// the reader always gets the newest complete value, older unread values are overwritten.
// One atomic byte carries the index of the shared slot plus a "fresh" bit; acquire/release
// ordering publishes the slot contents. publish() and take() are wait-free, allocation-free
// and lock-free: RT-safe on both sides.
#include <array>
#include <atomic>
#include <cstdint>
#include <type_traits>

namespace haptic::drivers {

template <class T>
class LatestMailbox {
  static_assert(std::is_trivially_copyable_v<T>, "LatestMailbox holds trivially copyable records");
  static_assert(std::atomic<std::uint8_t>::is_always_lock_free, "needs a lock-free atomic byte");

 public:
  // Writer side. RT-safe.
  void publish(const T& value) {
    slots_[write_index_] = value;
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(write_index_ | kFresh), std::memory_order_acq_rel);
    write_index_ = static_cast<std::uint8_t>(previous & kIndexMask);
  }

  // Reader side: true and the newest value when something was published since the last
  // take(), false (out untouched) otherwise. RT-safe.
  bool take(T& out) {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t previous = middle_.exchange(read_index_, std::memory_order_acq_rel);
    read_index_ = static_cast<std::uint8_t>(previous & kIndexMask);
    out = slots_[read_index_];
    return true;
  }

  // Reader side: whether a value is waiting. RT-safe.
  bool has_fresh() const { return (middle_.load(std::memory_order_acquire) & kFresh) != 0; }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  std::array<T, 3> slots_{};
  alignas(64) std::atomic<std::uint8_t> middle_{1};
  alignas(64) std::uint8_t write_index_ = 0;  // writer-owned
  alignas(64) std::uint8_t read_index_ = 2;   // reader-owned
};

}  // namespace haptic::drivers
