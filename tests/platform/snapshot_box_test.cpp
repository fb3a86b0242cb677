// SnapshotBox (seqlock): a reader never sees a torn record while one writer publishes as fast
// as it can, and sees the newest record once the writer stops.
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "platform/snapshot_box.hpp"

using haptic::platform::SnapshotBox;

namespace {
struct Record {  // 40 words, all equal in every published record
  std::uint64_t w[40];
};
}  // namespace

TEST_GROUP(SnapshotBox) {};

TEST(SnapshotBox, ReaderNeverSeesATornRecordAndEndsWithTheNewest) {
  SnapshotBox<Record> box;
  CHECK_EQUAL(0u, box.reader_snapshot().w[0]);  // before the first publish: a value-initialised record
  std::atomic<bool> done{false};
  std::uint64_t torn = 0, reads = 0, went_back = 0;
  std::thread reader([&] {
    std::uint64_t last = 0;
    while (!done.load(std::memory_order_acquire)) {
      const Record r = box.reader_snapshot();
      for (std::uint64_t v : r.w)
        if (v != r.w[0]) ++torn;
      if (r.w[0] < last) ++went_back;
      last = r.w[0];
      ++reads;
    }
  });
  constexpr std::uint64_t kWrites = 2'000'000;
  Record r{};
  for (std::uint64_t i = 1; i <= kWrites; ++i) {
    for (auto& v : r.w) v = i;
    box.writer_publish(r);
  }
  done.store(true, std::memory_order_release);
  reader.join();
  CHECK(reads > 0);
  CHECK_EQUAL(0u, torn);
  CHECK_EQUAL(0u, went_back);
  CHECK_EQUAL(kWrites, box.reader_snapshot().w[39]);
  CHECK_EQUAL(kWrites, box.publications());
}
