#pragma once
// Snapshot box (a seqlock): one writer thread publishes a trivially copyable record, any
// number of reader threads copy the newest complete one. The writer never waits and takes no
// lock (it bumps a sequence counter, stores the record word by word, bumps it again); a reader
// retries while a write is in progress, so it is for non-RT readers (statistics, monitoring)
// of an RT writer (e.g. the network I/O thread). The record is held in relaxed atomic words,
// so concurrent access is race-free in the C++ memory model (and under ThreadSanitizer).
// Reader cost grows with sizeof(T): fine for statistics records of a few hundred bytes.
// Methods are named after the side that calls them (writer_*, reader_*), like the other
// hand-off primitives here (spsc_ring.hpp, latest_mailbox.hpp).
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace haptic::platform {

template <class T>
class SnapshotBox {
  static_assert(std::is_trivially_copyable_v<T>, "SnapshotBox holds trivially copyable records");
  static constexpr std::size_t kWords = (sizeof(T) + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);

 public:
  // Writer side (one thread). RT-safe: wait-free, no allocation, no syscall.
  void writer_publish(const T& value) {
    std::array<std::uint64_t, kWords> w{};
    std::memcpy(w.data(), &value, sizeof(T));
    const std::uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);  // odd: write in progress
    // Release stores (no fences, so ThreadSanitizer can check it): a reader that sees any new
    // word also sees the odd sequence number on its re-check (Boehm, "Can seqlocks get along
    // with programming language memory models?", 2012). Plain moves on x86.
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(w[i], std::memory_order_release);
    seq_.store(s + 2, std::memory_order_release);
  }

  // Reader side (any thread): the newest complete record (a default-constructed T before the
  // first publication). Retries while the writer is inside writer_publish(): not RT-safe.
  T reader_snapshot() const {
    std::array<std::uint64_t, kWords> w{};
    for (;;) {
      const std::uint64_t s0 = seq_.load(std::memory_order_acquire);
      if (s0 & 1u) continue;
      for (std::size_t i = 0; i < kWords; ++i) w[i] = words_[i].load(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s0) break;
    }
    T out{};
    std::memcpy(static_cast<void*>(&out), w.data(), sizeof(T));  // trivially copyable (asserted)
    return out;
  }

  // Reader side, once: copies the newest complete record into out and returns true, or returns
  // false (out unspecified) when a write was in progress or overlapped the copy. Wait-free: for an
  // RT reader that takes another path when the record is being written.
  bool reader_try_snapshot(T& out) const {
    std::array<std::uint64_t, kWords> w{};
    const std::uint64_t s0 = seq_.load(std::memory_order_acquire);
    if (s0 & 1u) return false;
    for (std::size_t i = 0; i < kWords; ++i) w[i] = words_[i].load(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) != s0) return false;
    std::memcpy(static_cast<void*>(&out), w.data(), sizeof(T));
    return true;
  }

  // How many times writer_publish() ran (readers can tell whether anything changed). Any thread.
  std::uint64_t publications() const { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  alignas(64) std::atomic<std::uint64_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace haptic::platform
