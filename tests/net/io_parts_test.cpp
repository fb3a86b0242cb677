// The I/O-thread parts of the endpoint, alone: the state hand-off channel between two threads
// (net/state_channel.hpp), the tick-synchronous TX spin schedule (net/tx_spin.hpp), the I/O thread
// host and the delivery waiter (net/io_thread.hpp).
#include <CppUTest/TestHarness.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <time.h>

#include "net/io_thread.hpp"
#include "net/state_channel.hpp"
#include "net/tx_spin.hpp"

using namespace haptic::net;

namespace {
constexpr std::int64_t kUs = 1'000;
struct Meta {
  std::uint64_t seq;
};
}  // namespace

TEST_GROUP(StateChannel){};

TEST(StateChannel, BuffersGoRoundInOrderAndRunOutWhenAllAreHeld) {
  StateChannel<Meta, 4> ch(3);
  std::uint32_t idx[5];
  for (std::uint32_t i = 0; i < 4; ++i) {
    CHECK(ch.producer_acquire(idx[i]));
    ch.values(idx[i])[0] = i;
    ch.values(idx[i])[5] = 10.0 + i;  // v_hat[2]
    ch.meta(idx[i]).seq = 100 + i;
    ch.producer_publish(idx[i]);
  }
  CHECK_FALSE(ch.producer_acquire(idx[4]));  // every buffer in flight
  CHECK_EQUAL(4u, ch.ready_size());
  for (std::uint32_t i = 0; i < 4; ++i) {
    std::uint32_t got = 0;
    CHECK(ch.consumer_pop(got));
    CHECK_EQUAL(100u + i, ch.meta(got).seq);
    DOUBLES_EQUAL(i, ch.values(got)[0], 0.0);
    DOUBLES_EQUAL(10.0 + i, ch.values(got)[5], 0.0);
    ch.consumer_release(got);
  }
  std::uint32_t none = 0;
  CHECK_FALSE(ch.consumer_pop(none));
  CHECK(ch.producer_acquire(idx[4]));  // released buffers come back
}

TEST(StateChannel, TwoThreadsHandOverEveryBufferIntact) {
  StateChannel<Meta, 8> ch(64);
  constexpr std::uint64_t kCount = 20000;
  std::thread producer([&] {
    for (std::uint64_t s = 0; s < kCount;) {
      std::uint32_t i = 0;
      if (!ch.producer_acquire(i)) continue;
      for (std::uint32_t v = 0; v < 128; ++v) ch.values(i)[v] = static_cast<double>(s);
      ch.meta(i).seq = s++;
      ch.producer_publish(i);
    }
  });
  std::uint64_t expect = 0, bad = 0;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (expect < kCount && std::chrono::steady_clock::now() < give_up) {
    std::uint32_t i = 0;
    if (!ch.consumer_pop(i)) continue;
    if (ch.meta(i).seq != expect) ++bad;
    for (std::uint32_t v = 0; v < 128; ++v) bad += ch.values(i)[v] != static_cast<double>(expect);
    ++expect;
    ch.consumer_release(i);
  }
  producer.join();
  CHECK_EQUAL(kCount, expect);
  CHECK_EQUAL(0u, bad);
}

TEST_GROUP(TxSpinSchedule){};

TEST(TxSpinSchedule, OpensLeadBeforeTheNextPushAndClosesTailAfter) {
  TxSpinSchedule s(2000 * kUs, 100 * kUs, 300 * kUs);
  CHECK_FALSE(s.plan(0).spin);  // no push yet: nothing to predict
  s.on_push(10'000 * kUs);
  TxSpinSchedule::Plan p = s.plan(10'500 * kUs);
  CHECK_FALSE(p.spin);
  CHECK_EQUAL(11'900 * kUs, p.wake_ns);  // 2 ms after the push, 100 us early
  p = s.plan(11'900 * kUs);
  CHECK(p.spin);
  CHECK_EQUAL(12'300 * kUs, p.until_ns);
  CHECK_EQUAL(1u, s.windows());
  // A missed push: the next window is the next slot (14 ms), not the missed one.
  s.on_window_end(false);
  p = s.plan(12'400 * kUs);
  CHECK_FALSE(p.spin);
  CHECK_EQUAL(13'900 * kUs, p.wake_ns);
}

TEST(TxSpinSchedule, StopsAfterMissedWindowsUntilTheNextPush) {
  TxSpinSchedule s(2000 * kUs, 100 * kUs, 300 * kUs);
  s.on_push(0);
  for (int i = 0; i < TxSpinSchedule::kMaxMissedWindows; ++i) s.on_window_end(false);
  CHECK_FALSE(s.plan(1'950 * kUs).spin);
  s.on_push(4'000 * kUs);
  CHECK(s.plan(5'950 * kUs).spin);
}

TEST(TxSpinSchedule, LearnsItsWakeUpLatenessEvery64Windows) {
  TxSpinSchedule s(2000 * kUs, 100 * kUs, 300 * kUs);
  for (int w = 0; w < 64; ++w) {
    const std::int64_t push = static_cast<std::int64_t>(w) * 2000 * kUs;
    s.on_push(push);
    CHECK(s.plan(push + 1900 * kUs + 40 * kUs).spin);  // woke 40 us after the window opened
  }
  CHECK_EQUAL(40 * kUs, s.wake_late_ns());
  s.on_push(200'000 * kUs);
  CHECK_EQUAL(201'860 * kUs, s.plan(200'100 * kUs).wake_ns);  // now sleeps 40 us less
}

TEST(TxSpinSchedule, OffNeverSpins) {
  TxSpinSchedule s(0, 100 * kUs, 300 * kUs);
  s.on_push(0);
  CHECK_FALSE(s.enabled());
  CHECK_FALSE(s.plan(1'950 * kUs).spin);
}

TEST_GROUP(IoThread){};

TEST(IoThread, RunsTheBodyUntilStopAndKeepsItsCpuTime) {
  IoThread t(-1, 0);
  std::atomic<int> loops{0};
  t.start([&] {
    t.body_started();
    // 20 ms of this thread's CPU time (bounded by 10 s of wall time on a loaded machine).
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    timespec cpu{};
    do clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu);
    while (cpu.tv_sec == 0 && cpu.tv_nsec < 20'000'000 && std::chrono::steady_clock::now() < give_up);
    for (int i = 0; i < 100000 && t.running(); ++i) {
      ++loops;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    t.body_stopping();
  });
  CHECK(t.started());
  STRCMP_EQUAL("SCHED_OTHER", t.scheduling().c_str());
  t.stop();
  CHECK_FALSE(t.started());
  CHECK(t.cpu_s() > 0.01);
  CHECK(loops.load() < 100000);
}

TEST(IoThread, DeliveryWaiterWakesOnADeliveryAndTimesOutWithout) {
  DeliveryWaiter w;
  std::atomic<bool> ready{false};
  const auto t0 = std::chrono::steady_clock::now();
  CHECK_FALSE(w.wait(0.02, [&] { return ready.load(); }));
  CHECK(std::chrono::steady_clock::now() - t0 >= std::chrono::milliseconds(15));
  std::thread producer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ready.store(true);
    w.delivered();
  });
  const auto t1 = std::chrono::steady_clock::now();
  CHECK(w.wait(20.0, [&] { return ready.load(); }));
  CHECK(std::chrono::steady_clock::now() - t1 < std::chrono::seconds(10));
  producer.join();
}
