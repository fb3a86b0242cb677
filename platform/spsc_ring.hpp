#pragma once
// Fixed-capacity single-writer/single-reader lock-free ring (FIFO). Exactly one thread calls the
// writer_* methods and exactly one thread calls the reader_* methods; the names say which side
// may call what (as ros2_control's realtime_tools names its methods after the calling side).
// Both sides are wait-free (a bounded number of steps, no retry loop), lock-free and
// allocation-free, so either side may be the real-time thread: in the station the RT tick is the
// writer of the TX ring and the telemetry ring and the reader of the RX ring (net/endpoint.hpp,
// platform/telemetry.hpp); the other side is a non-RT thread.
//
// Memory orders: each side owns one index and stores it with release after touching a slot; it
// reads the other side's index with acquire. So the reader sees a slot's contents once it sees
// the writer's head (release/acquire on head_), and the writer never overwrites a slot before the
// reader's tail store says the reader is done with it (release/acquire on tail_). Each side keeps
// a cached copy of the other's index to avoid touching the other's cache line on every call.
#include <array>
#include <atomic>
#include <cstddef>
#include <type_traits>

namespace haptic::platform {

inline constexpr std::size_t kCacheLine = 64;

template <class T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "Capacity must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>, "SpscRing holds trivially copyable records");

 public:
  static constexpr std::size_t capacity() { return Capacity; }

  // Writer side only. Appends a copy of item; returns false (and overwrites nothing already
  // queued) when the ring is full. Wait-free, RT-safe.
  bool writer_try_push(const T& item) {
    const std::size_t head = head_.load(std::memory_order_relaxed);  // own index
    const std::size_t next = head + 1;
    if (next - cached_tail_ > Capacity) {
      cached_tail_ = tail_.load(std::memory_order_acquire);  // the reader's last pop is complete
      if (next - cached_tail_ > Capacity) return false;
    }
    slots_[head & (Capacity - 1)] = item;
    head_.store(next, std::memory_order_release);  // publishes the slot
    return true;
  }

  // Reader side only. Moves the oldest item into out; returns false (out untouched) when the
  // ring is empty. Wait-free, RT-safe.
  bool reader_try_pop(T& out) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);  // own index
    if (tail == cached_head_) {
      cached_head_ = head_.load(std::memory_order_acquire);  // the writer's slot contents are visible
      if (tail == cached_head_) return false;
    }
    out = slots_[tail & (Capacity - 1)];
    tail_.store(tail + 1, std::memory_order_release);  // hands the slot back to the writer
    return true;
  }

  // Either side (or a monitor): approximate fill level, exact when the other side is idle.
  // Wait-free, RT-safe.
  std::size_t size() const {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }

 private:
  alignas(kCacheLine) std::atomic<std::size_t> head_{0};  // written by the writer only
  std::size_t cached_tail_ = 0;                            // writer's copy of tail_
  alignas(kCacheLine) std::atomic<std::size_t> tail_{0};  // written by the reader only
  std::size_t cached_head_ = 0;                            // reader's copy of head_
  alignas(kCacheLine) std::array<T, Capacity> slots_{};
};

}  // namespace haptic::platform
