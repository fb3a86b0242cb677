// The per-neighbour bookkeeping parts of the endpoint, alone: silence detection
// (net/peer_liveness.hpp), incarnations and the receive account (net/receive_account.hpp), the
// per-source rate limit (net/rate_limit.hpp) and the sequence ceiling (net/sequence_ceiling.hpp).
#include <CppUTest/TestHarness.h>

#include "net/peer_liveness.hpp"
#include "net/rate_limit.hpp"
#include "net/receive_account.hpp"
#include "net/sequence_ceiling.hpp"

using namespace haptic::net;

namespace {
constexpr std::int64_t kMs = 1'000'000;
}

TEST_GROUP(PeerLiveness){};

TEST(PeerLiveness, DownAfterSilenceAndUpAtTheNextPacket) {
  PeerLiveness l;
  CHECK_FALSE(l.check(1000 * kMs, 250 * kMs));  // never heard: not "down"
  CHECK(l.on_receive(10 * kMs));
  CHECK_FALSE(l.on_receive(20 * kMs));
  CHECK_FALSE(l.check(270 * kMs, 250 * kMs));  // exactly the silence: still up
  CHECK(l.check(271 * kMs, 250 * kMs));
  CHECK_FALSE(l.check(400 * kMs, 250 * kMs));  // counted once
  CHECK(l.on_receive(500 * kMs));
  PeerStats s;
  l.fill(s);
  CHECK(s.up);
  CHECK_EQUAL(2u, s.up_events);
  CHECK_EQUAL(1u, s.down_events);
  DOUBLES_EQUAL(0.271, s.last_down_s, 1e-12);
  DOUBLES_EQUAL(0.5, s.last_up_s, 1e-12);
  DOUBLES_EQUAL(0.5, s.last_change_s, 1e-12);
  DOUBLES_EQUAL(0.5, s.last_receive_s, 1e-12);
}

TEST_GROUP(ReceiveAccount){};

TEST(ReceiveAccount, LossIsOverTheCurrentIncarnationsSequenceSpan) {
  ReceiveAccount r;
  CHECK_FALSE(r.on_incarnation(7));  // the first incarnation is no restart
  CHECK_FALSE(r.on_incarnation(7));
  for (std::uint64_t s : {10u, 11u, 13u, 14u}) r.on_state(s, 0, 0);  // 12 missing: 1 of 5
  DOUBLES_EQUAL(0.2, r.loss_fraction(), 1e-12);
  CHECK(r.on_incarnation(8));  // restarted: a new span
  DOUBLES_EQUAL(0.0, r.loss_fraction(), 1e-12);
  r.on_state(0, 0, 0);
  r.on_state(1, 0, 0);
  DOUBLES_EQUAL(0.0, r.loss_fraction(), 1e-12);
  PeerStats s;
  r.fill(s);
  CHECK_EQUAL(8u, s.incarnation);
  CHECK_EQUAL(1u, s.incarnation_changes);
  CHECK_EQUAL(6u, s.packets_received);
  CHECK_EQUAL(2u, s.packets_received_incarnation);
  CHECK_EQUAL(1u, s.newest_seq);
}

TEST(ReceiveAccount, OneWayTimeIsReceiptMinusTheSendersStamp) {
  ReceiveAccount r;
  r.on_state(1, 100 * kMs, 104 * kMs);
  r.on_state(2, 102 * kMs, 110 * kMs);
  PeerStats s;
  r.fill(s);
  DOUBLES_EQUAL(0.006, s.one_way_mean_s, 1e-12);
  DOUBLES_EQUAL(0.008, s.one_way_max_s, 1e-12);
  DOUBLES_EQUAL(0.102, s.newest_send_time_s, 1e-12);
}

TEST_GROUP(SourceRateLimit){};

TEST(SourceRateLimit, BurstThenRateEachSourceOnItsOwn) {
  SourceRateLimit r(1000.0, 4.0, 2);  // 1000/s, burst 4; two neighbours and the unknown addresses
  for (int i = 0; i < 4; ++i) CHECK(r.take(0, 0));
  CHECK_FALSE(r.take(0, 0));
  CHECK(r.take(1, 0));   // another neighbour has its own bucket
  CHECK(r.take(-1, 0));  // and so do the unknown addresses together
  CHECK_FALSE(r.take(0, 999'000));  // 0.999 tokens refilled after 0.999 ms
  CHECK(r.take(0, 2 * kMs));  // 0.999 + 1.001 = 2 tokens
  CHECK(r.take(0, 2 * kMs));
  CHECK_FALSE(r.take(0, 2 * kMs));
}

TEST_GROUP(SequenceCeiling){};

TEST(SequenceCeiling, NoneUntilTheTickIsKnownThenTickPlusSlack) {
  SequenceCeiling c(50, -1, 2 * kMs);
  CHECK_EQUAL(SequenceCeiling::kNone, c.ceiling(1000 * kMs));
  c.note_tick(100);
  CHECK_EQUAL(150u, c.ceiling(1000 * kMs));
}

TEST(SequenceCeiling, ACommonEpochGivesTheCeilingBeforeTheFirstTick) {
  SequenceCeiling c(50, 1000 * kMs, 2 * kMs);
  CHECK_EQUAL(50u, c.ceiling(900 * kMs));   // before the epoch: tick 0
  CHECK_EQUAL(100u, c.ceiling(1100 * kMs)); // 100 ms after it: tick 50
  c.note_tick(10);                          // the station's own word wins
  CHECK_EQUAL(60u, c.ceiling(1100 * kMs));
}
