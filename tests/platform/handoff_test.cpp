// The lock-free hand-off primitives of platform/: the SPSC ring (FIFO, a full ring refuses and
// overwrites nothing, an empty ring says so, wrap-around) and the latest-value mailbox (the reader
// gets the newest value once, never a torn or older one). Both with a concurrent writer thread.
// The same primitives under ThreadSanitizer: tests/platform/tsan (test_platform_tsan).
#include <cstdint>
#include <thread>

#include "platform/latest_mailbox.hpp"
#include "platform/spsc_ring.hpp"
#include "tests/support/alloc_counter.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

using haptic::platform::LatestMailbox;
using haptic::platform::SpscRing;

namespace {
struct Record {
  std::uint64_t seq;
  std::uint64_t check[7];
  static Record make(std::uint64_t i) {
    Record r{i, {}};
    for (auto& c : r.check) c = i * 2654435761u;
    return r;
  }
  bool intact() const {
    for (auto c : check)
      if (c != seq * 2654435761u) return false;
    return true;
  }
};
}  // namespace

TEST_GROUP(SpscRing) {};

TEST(SpscRing, full_ring_refuses_the_push_and_keeps_every_queued_item) {
  SpscRing<int, 8> ring;
  for (int i = 0; i < 8; ++i) CHECK_TEXT(ring.writer_try_push(i), "push into a ring with room failed");
  LONGS_EQUAL(8, ring.size());
  CHECK_FALSE(ring.writer_try_push(99));  // full: refused
  CHECK_FALSE(ring.writer_try_push(100));
  LONGS_EQUAL(8, ring.size());
  int v = -1;
  for (int i = 0; i < 8; ++i) {
    CHECK(ring.reader_try_pop(v));
    LONGS_EQUAL(i, v);  // nothing overwritten, first in first out
  }
  v = -1;
  CHECK_FALSE(ring.reader_try_pop(v));  // empty
  LONGS_EQUAL(-1, v);                   // out untouched
}

TEST(SpscRing, keeps_fifo_order_across_many_wrap_arounds) {
  SpscRing<int, 4> ring;
  int next_in = 0, next_out = 0;
  for (int round = 0; round < 50; ++round) {
    const int n = 1 + round % 4;  // 1..4 items per round, so the indices wrap at every phase
    for (int k = 0; k < n; ++k) CHECK(ring.writer_try_push(next_in++));
    for (int k = 0; k < n; ++k) {
      int v = -1;
      CHECK(ring.reader_try_pop(v));
      LONGS_EQUAL(next_out++, v);
    }
  }
  LONGS_EQUAL(0, ring.size());
}

TEST(SpscRing, push_and_pop_do_not_allocate) {
  CHECK_TEXT(haptic::test::allocation_counter_works(), "allocation counter is not interposed in this binary");
  static SpscRing<Record, 16> ring;
  std::uint64_t allocations = 0;
  {
    haptic::test::AllocationCounter counter;
    Record r{};
    for (std::uint64_t i = 0; i < 1000; ++i) {
      ring.writer_try_push(Record::make(i));
      ring.reader_try_pop(r);
    }
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
}

TEST(SpscRing, concurrent_reader_gets_every_item_once_in_order_and_intact) {
  static SpscRing<Record, 64> ring;  // small, so the writer often finds it full
  constexpr std::uint64_t kN = 200000;
  std::thread writer([] {
    for (std::uint64_t i = 0; i < kN;) {
      if (ring.writer_try_push(Record::make(i))) ++i;
      else std::this_thread::yield();
    }
  });
  std::uint64_t expect = 0, wrong = 0;
  while (expect < kN) {
    Record r{};
    if (!ring.reader_try_pop(r)) {
      std::this_thread::yield();
      continue;
    }
    wrong += (r.seq != expect || !r.intact());
    expect = r.seq + 1;
  }
  writer.join();
  LONGS_EQUAL(0, wrong);
}

TEST_GROUP(LatestMailbox) {};

TEST(LatestMailbox, reader_gets_the_newest_value_once) {
  LatestMailbox<int> box;
  int v = 0;
  CHECK_FALSE(box.reader_has_fresh());
  CHECK_FALSE(box.reader_take(v));
  box.writer_publish(1);
  box.writer_publish(2);
  box.writer_publish(3);
  CHECK(box.reader_has_fresh());
  CHECK(box.reader_take(v));
  LONGS_EQUAL(3, v);
  CHECK_FALSE(box.reader_has_fresh());
  CHECK_FALSE(box.reader_take(v));
  box.writer_publish(4);
  CHECK(box.reader_take(v));
  LONGS_EQUAL(4, v);
}

TEST(LatestMailbox, concurrent_reader_never_sees_a_torn_or_older_record) {
  LatestMailbox<Record> box;
  constexpr std::uint64_t kN = 200000;
  std::thread writer([&box] {
    for (std::uint64_t i = 1; i <= kN; ++i) box.writer_publish(Record::make(i));
  });
  std::uint64_t last = 0, torn = 0, backwards = 0;
  while (last < kN) {
    Record r{};
    if (!box.reader_take(r)) continue;
    torn += !r.intact();
    backwards += (r.seq <= last);
    last = r.seq;
  }
  writer.join();
  LONGS_EQUAL(0, torn);
  LONGS_EQUAL(0, backwards);
}
