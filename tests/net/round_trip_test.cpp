// Round trips and clock offset from this station's own send records (net/round_trip.hpp), alone:
// a round trip is our receipt minus OUR send stamp of the echoed sequence, never the peer's word;
// the clock offset is the lowest-path sample of its window; echoes we send are of packets
// received by the echoing packet's stamp.
#include <CppUTest/TestHarness.h>

#include "net/round_trip.hpp"

using namespace haptic::net;

namespace {
constexpr std::int64_t kMs = 1'000'000;
RttConfig probing_config() {
  RttConfig c;
  c.min_probe_samples = 2;
  c.margin_fraction = 0.0;
  c.margin_s = 0.0;
  return c;
}
}  // namespace

TEST_GROUP(SendRecords){};

TEST(SendRecords, FindsOnlyTheSequenceRecordedInItsSlot) {
  SendRecords r;
  POINTERS_EQUAL(nullptr, r.send_ns(5));
  r.record(5, 123);
  CHECK(r.send_ns(5) != nullptr);
  LONGLONGS_EQUAL(123, *r.send_ns(5));
  r.record(5 + SendRecords::kCapacity, 456);  // same slot, a newer sequence: the old record is gone
  POINTERS_EQUAL(nullptr, r.send_ns(5));
  LONGLONGS_EQUAL(456, *r.send_ns(5 + SendRecords::kCapacity));
}

TEST_GROUP(ClockOffsetFilter){};

TEST(ClockOffsetFilter, OffsetOfASymmetricPathIsExact) {
  ClockOffsetFilter f;
  // Peer clock 5 s ahead; 10 ms each way; held 2 ms: t1 = 0, t2 = 5.010, t3 = 5.012, t4 = 0.022.
  f.add(0.0, 5.012, 0.002, 0.022);
  DOUBLES_EQUAL(5.0, f.offset_s(), 1e-12);
  DOUBLES_EQUAL(0.020, f.path_s(), 1e-12);
  CHECK_EQUAL(1u, f.samples());
}

TEST(ClockOffsetFilter, KeepsTheLowestPathSampleOfTheFirstWindow) {
  ClockOffsetFilter f;
  f.add(0.0, 5.010, 0.0, 0.020);   // path 20 ms, offset 5.0
  f.add(1.0, 6.030, 0.0, 1.040);   // path 40 ms, asymmetric: offset 5.01 (worse)
  DOUBLES_EQUAL(5.0, f.offset_s(), 1e-12);
  f.add(2.0, 7.003, 0.0, 2.004);   // path 4 ms: offset 5.001
  DOUBLES_EQUAL(5.001, f.offset_s(), 1e-9);
  DOUBLES_EQUAL(0.004, f.path_s(), 1e-12);
}

TEST(ClockOffsetFilter, LaterWindowsPublishOnlyWhenComplete) {
  ClockOffsetFilter f;
  for (std::uint64_t i = 0; i < ClockOffsetFilter::kWindow; ++i) f.add(0.0, 5.001, 0.0, 0.002);  // offset 5.0
  DOUBLES_EQUAL(5.0, f.offset_s(), 1e-12);
  // The clock stepped: a new offset of 7 s, published only at the end of the second window.
  for (std::uint64_t i = 0; i + 1 < ClockOffsetFilter::kWindow; ++i) f.add(0.0, 7.001, 0.0, 0.002);
  DOUBLES_EQUAL(5.0, f.offset_s(), 1e-12);
  f.add(0.0, 7.001, 0.0, 0.002);
  DOUBLES_EQUAL(7.0, f.offset_s(), 1e-12);
}

TEST_GROUP(RoundTrip){};

TEST(RoundTrip, SampleComesFromOurSendRecordNotThePeersStamp) {
  SendRecords rec;
  rec.record(10, 100 * kMs);
  RoundTrip rt(probing_config());
  rt.begin_probing();
  // The peer's own stamp (999 ms) plays no part in the round trip: 130 ms - 100 ms.
  rt.on_echo(10, 0, 999 * kMs, 130 * kMs, rec);
  CHECK_EQUAL(1u, rt.estimator().samples());
  DOUBLES_EQUAL(0.030, rt.estimator().last_s(), 1e-12);
}

TEST(RoundTrip, EachEchoIsSampledOnceAndUnknownOnesAreCounted) {
  SendRecords rec;
  rec.record(10, 100 * kMs);
  rec.record(11, 102 * kMs);
  RoundTrip rt(probing_config());
  rt.on_echo(10, 0, 0, 130 * kMs, rec);
  rt.on_echo(10, 0, 0, 140 * kMs, rec);  // the same echo again (the peer had nothing newer)
  rt.on_echo(9, 0, 0, 141 * kMs, rec);   // an older one
  CHECK_EQUAL(1u, rt.estimator().samples());
  rt.on_echo(12, 0, 0, 150 * kMs, rec);  // never sent
  CHECK_EQUAL(1u, rt.echoes_unmatched());
  rt.on_echo(11, 0, 0, 150 * kMs, rec);
  CHECK_EQUAL(2u, rt.estimator().samples());
}

TEST(RoundTrip, FinishingProbingPublishesTheBoundForTheRtThread) {
  SendRecords rec;
  RoundTrip rt(probing_config());
  rt.begin_probing();
  CHECK_FALSE(rt.finish_probing());  // no samples yet
  rt.begin_probing();
  for (std::uint64_t s = 1; s <= 2; ++s) {
    rec.record(s, static_cast<std::int64_t>(s) * 100 * kMs);
    rt.on_echo(s, 0, 0, static_cast<std::int64_t>(s) * 100 * kMs + 20 * kMs, rec);
  }
  CHECK_EQUAL(0u, rt.bound_ns());
  CHECK(rt.finish_probing());
  CHECK_EQUAL(20u * kMs, rt.bound_ns());
  CHECK_EQUAL(1u, rt.generation());
  // An over-bound sample raises the published bound at once.
  rec.record(3, 300 * kMs);
  rt.on_echo(3, 0, 0, 330 * kMs, rec);
  CHECK_EQUAL(30u * kMs, rt.bound_ns());
  CHECK_EQUAL(2u, rt.generation());
}

TEST(RoundTrip, EchoesOnlyWhatWasReceivedByTheStamp) {
  RoundTrip rt;
  POINTERS_EQUAL(nullptr, rt.echo_as_of(1000 * kMs));
  rt.note_received(7, 0, 100 * kMs);
  rt.note_received(8, 0, 120 * kMs);
  rt.note_received(6, 0, 125 * kMs);  // older than the newest: not kept
  CHECK_EQUAL(8u, rt.echo_as_of(130 * kMs)->seq);
  CHECK_EQUAL(7u, rt.echo_as_of(110 * kMs)->seq);  // a packet stamped before 8 arrived echoes 7
  POINTERS_EQUAL(nullptr, rt.echo_as_of(90 * kMs));
  rt.restart();
  POINTERS_EQUAL(nullptr, rt.echo_as_of(130 * kMs));
}
