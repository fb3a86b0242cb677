#pragma once
// Fixed-capacity single-producer/single-consumer lock-free ring. One thread pushes, one
// thread pops; head and tail live on their own cache lines; acquire/release ordering.
// try_push/try_pop never block and never allocate: RT-safe on both sides.
#include <array>
#include <atomic>
#include <cstddef>
#include <type_traits>

namespace haptic::rt {

inline constexpr std::size_t kCacheLine = 64;

template <class T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "Capacity must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>, "SpscRing holds trivially copyable records");

 public:
  static constexpr std::size_t capacity() { return Capacity; }

  // Producer side. Returns false (and drops nothing already queued) when full.
  bool try_push(const T& item) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    const std::size_t next = head + 1;
    if (next - cached_tail_ > Capacity) {
      cached_tail_ = tail_.load(std::memory_order_acquire);
      if (next - cached_tail_ > Capacity) return false;
    }
    slots_[head & (Capacity - 1)] = item;
    head_.store(next, std::memory_order_release);
    return true;
  }

  // Consumer side. Returns false when empty.
  bool try_pop(T& out) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == cached_head_) {
      cached_head_ = head_.load(std::memory_order_acquire);
      if (tail == cached_head_) return false;
    }
    out = slots_[tail & (Capacity - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Approximate fill level (exact when called from either side while the other is idle).
  std::size_t size() const {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }

 private:
  alignas(kCacheLine) std::atomic<std::size_t> head_{0};
  std::size_t cached_tail_ = 0;  // producer's copy of tail_
  alignas(kCacheLine) std::atomic<std::size_t> tail_{0};
  std::size_t cached_head_ = 0;  // consumer's copy of head_
  alignas(kCacheLine) std::array<T, Capacity> slots_{};
};

}  // namespace haptic::rt
