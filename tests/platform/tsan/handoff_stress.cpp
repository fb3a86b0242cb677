// ThreadSanitizer stress of platform/'s lock-free hand-off primitives: the SPSC ring
// (platform/spsc_ring.hpp) and the latest-value mailbox (platform/latest_mailbox.hpp), each with
// one writer and one reader thread. Bounded: fixed item counts.
// Exit code 0 = every ring item arrived once, in order, intact; every mailbox value the reader
// took was intact and newer than the last; and TSan reported no race (halt_on_error).
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <thread>

#include "platform/latest_mailbox.hpp"
#include "platform/spsc_ring.hpp"

namespace {

struct Item {
  std::uint64_t seq;
  std::uint64_t payload[6];
  std::uint64_t check;
  static Item make(std::uint64_t i) {
    Item it{};
    it.seq = i;
    for (int k = 0; k < 6; ++k) it.payload[k] = i * 31 + static_cast<std::uint64_t>(k);
    it.check = i ^ 0xA5A5A5A5A5A5A5A5ull;
    return it;
  }
  bool intact(std::uint64_t expect) const {
    bool ok = seq == expect && check == (expect ^ 0xA5A5A5A5A5A5A5A5ull);
    for (int k = 0; k < 6 && ok; ++k) ok = payload[k] == expect * 31 + static_cast<std::uint64_t>(k);
    return ok;
  }
};

int ring_stress(std::uint64_t count) {
  static haptic::platform::SpscRing<Item, 64> ring;
  bool failed = false;
  std::thread writer([&] {
    for (std::uint64_t i = 0; i < count;) {
      if (ring.writer_try_push(Item::make(i))) ++i;
      else std::this_thread::yield();
    }
  });
  std::uint64_t expect = 0;
  while (expect < count) {
    Item it{};
    if (!ring.reader_try_pop(it)) {
      std::this_thread::yield();
      continue;
    }
    if (!it.intact(expect)) {
      std::fprintf(stderr, "ring: item %llu corrupt or out of order\n", static_cast<unsigned long long>(expect));
      failed = true;
      break;
    }
    ++expect;
  }
  if (failed) std::_Exit(1);  // the writer may be blocked on a full ring: do not join
  writer.join();
  std::printf("ring stress: %llu items through a 64-slot ring: ok\n", static_cast<unsigned long long>(count));
  return 0;
}

int mailbox_stress(std::uint64_t count) {
  static haptic::platform::LatestMailbox<Item> box;
  std::atomic<bool> writer_done{false};
  std::thread writer([&] {
    for (std::uint64_t i = 1; i <= count; ++i) {
      box.writer_publish(Item::make(i));
      std::this_thread::yield();  // lets the reader in between publications (2 shared cores)
    }
    writer_done.store(true, std::memory_order_release);
  });
  std::uint64_t last = 0, taken = 0, bad = 0;
  for (;;) {
    const bool done = writer_done.load(std::memory_order_acquire);
    Item it{};
    if (box.reader_take(it)) {
      ++taken;
      bad += !it.intact(it.seq) || it.seq <= last;
      last = it.seq;
    } else if (done) {
      break;  // nothing fresh after the writer finished: the last value was taken
    } else {
      std::this_thread::yield();
    }
  }
  writer.join();
  const bool ok = bad == 0 && last == count;
  std::printf("mailbox stress: %llu published, %llu taken, newest %llu, %llu torn or older: %s\n",
              static_cast<unsigned long long>(count), static_cast<unsigned long long>(taken),
              static_cast<unsigned long long>(last), static_cast<unsigned long long>(bad), ok ? "ok" : "FAIL");
  return ok ? 0 : 1;
}

}  // namespace

int main() {
  int rc = ring_stress(2'000'000);
  rc |= mailbox_stress(200'000);
  return rc;
}
