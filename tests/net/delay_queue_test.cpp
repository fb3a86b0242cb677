// The impairment emulator's delay queue (net/delay_queue.hpp), alone: release order by time then
// queue order, nothing before its time, fixed capacity, slots reused.
#include <CppUTest/TestHarness.h>

#include <cstring>
#include <string>
#include <vector>

#include "net/delay_queue.hpp"

using namespace haptic::net;

namespace {
bool queue(DelayQueue& q, std::int64_t release_ns, std::uint16_t dest, const std::string& text) {
  std::uint8_t* s = q.slot();
  if (s == nullptr) return false;
  std::memcpy(s, text.data(), text.size());
  q.commit(release_ns, dest, text.size());
  return true;
}
std::vector<std::string> release(DelayQueue& q, std::int64_t now_ns) {
  std::vector<std::string> out;
  q.release_due(now_ns, [&](std::uint16_t dest, const std::uint8_t* d, std::size_t len) {
    out.push_back(std::to_string(dest) + ":" + std::string(reinterpret_cast<const char*>(d), len));
  });
  return out;
}
}  // namespace

TEST_GROUP(DelayQueue){};

TEST(DelayQueue, ReleasesByTimeThenQueueOrderAndNothingEarly) {
  DelayQueue q(8, 16);
  CHECK(queue(q, 30, 1, "c"));
  CHECK(queue(q, 10, 2, "a"));
  CHECK(queue(q, 20, 1, "b1"));
  CHECK(queue(q, 20, 3, "b2"));  // same time as b1, queued later: after it
  CHECK_EQUAL(10, q.next_release_ns());
  CHECK(release(q, 9).empty());
  const auto first = release(q, 20);
  CHECK_EQUAL(3u, first.size());
  STRCMP_EQUAL("2:a", first[0].c_str());
  STRCMP_EQUAL("1:b1", first[1].c_str());
  STRCMP_EQUAL("3:b2", first[2].c_str());
  CHECK_EQUAL(1u, q.size());
  STRCMP_EQUAL("1:c", release(q, 1000)[0].c_str());
  CHECK(q.empty());
}

TEST(DelayQueue, DatagramsDueTogetherLeaveInQueueOrder) {
  // A packet's fragments share one release time: they must leave in the order they were queued.
  DelayQueue q(64, 16);
  for (int i = 0; i < 40; ++i) CHECK(queue(q, i % 2 == 0 ? 50 : 60, 1, std::to_string(i)));
  const auto out = release(q, 100);
  CHECK_EQUAL(40u, out.size());
  for (int i = 0; i < 20; ++i) {
    STRCMP_EQUAL(("1:" + std::to_string(2 * i)).c_str(), out[static_cast<std::size_t>(i)].c_str());
    STRCMP_EQUAL(("1:" + std::to_string(2 * i + 1)).c_str(), out[static_cast<std::size_t>(20 + i)].c_str());
  }
}

TEST(DelayQueue, FullQueueRefusesAndFreedSlotsAreReused) {
  DelayQueue q(2, 16);
  CHECK(queue(q, 5, 1, "x"));
  CHECK(queue(q, 6, 1, "y"));
  POINTERS_EQUAL(nullptr, q.slot());
  CHECK_EQUAL(1u, release(q, 5).size());
  CHECK(queue(q, 7, 1, "z"));  // the freed slot
  const auto out = release(q, 100);
  CHECK_EQUAL(2u, out.size());
  STRCMP_EQUAL("1:y", out[0].c_str());
  STRCMP_EQUAL("1:z", out[1].c_str());
}
