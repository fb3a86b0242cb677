// Fig. 4 of the paper through the receive-side bookkeeping: varying delay, loss (sustainment),
// data swapping and duplication give the indexing delay N_ij^k and duplication avoidance (17).
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <vector>

#include "rt/rx_link.hpp"

using namespace haptic::rt;

namespace {
struct Harness {
  RxLink rx;
  std::vector<double> x0 = {0, 0, 0}, v0 = {0, 0, 0};
  explicit Harness(RxRule rule = RxRule::kNewestBySequence) { rx.init(3, x0.data(), v0.data(), -1, rule); }
  RxVerdict send(std::int64_t seq) {
    const double x[3] = {double(seq), 0, 0}, v[3] = {double(seq) * 10, 0, 0};
    return rx.offer(seq, seq * 0.002, x, v, 3);
  }
};
}  // namespace

TEST_GROUP(RxLinkFig4){};

TEST(RxLinkFig4, varying_delay_gives_index_delay_of_the_newest_packet) {
  Harness h;
  h.send(0);
  auto v = h.rx.begin_tick(1);  // sent at 0, used at 1
  CHECK_EQUAL(1, v.index_delay);
  CHECK_TRUE(v.fresh);
  DOUBLES_EQUAL(0.0, v.x_hat[0], 0);
  h.send(1);
  h.send(2);  // two arrive together: the newest wins
  v = h.rx.begin_tick(4);
  CHECK_EQUAL(2, v.index_delay);
  DOUBLES_EQUAL(2.0, v.x_hat[0], 0);
  DOUBLES_EQUAL(20.0, v.v_hat[0], 0);
  CHECK_TRUE(v.fresh);
}

TEST(RxLinkFig4, loss_sustains_the_previous_packet_and_index_delay_grows_with_delta_zero) {
  Harness h;
  h.send(0);
  CHECK_TRUE(h.rx.begin_tick(1).fresh);
  // packets 1 and 2 lost
  auto v = h.rx.begin_tick(2);
  CHECK_EQUAL(2, v.index_delay);
  CHECK_FALSE(v.fresh);  // artificial duplication: velocity already used
  DOUBLES_EQUAL(0.0, v.x_hat[0], 0);  // position held (packet sustainment)
  v = h.rx.begin_tick(3);
  CHECK_EQUAL(3, v.index_delay);
  CHECK_FALSE(v.fresh);
  CHECK_EQUAL(2u, h.rx.counters().sustained_ticks);
  CHECK_EQUAL(3, h.rx.counters().max_index_delay);
}

TEST(RxLinkFig4, swapped_packet_arriving_late_is_dropped) {
  Harness h;
  CHECK_TRUE(h.send(5) == RxVerdict::kAccepted);
  CHECK_TRUE(h.send(4) == RxVerdict::kStale);  // data swapping: 4 overtaken by 5
  auto v = h.rx.begin_tick(6);
  CHECK_EQUAL(1, v.index_delay);
  DOUBLES_EQUAL(5.0, v.x_hat[0], 0);
  CHECK_EQUAL(1u, h.rx.counters().stale);
}

TEST(RxLinkFig4, duplicated_packet_is_not_used_twice) {
  Harness h;
  h.send(3);
  CHECK_TRUE(h.rx.begin_tick(4).fresh);
  CHECK_TRUE(h.send(3) == RxVerdict::kDuplicate);  // real duplication from the network
  auto v = h.rx.begin_tick(5);
  CHECK_FALSE(v.fresh);  // delta = 0 (eq. 17)
  CHECK_EQUAL(2, v.index_delay);
  CHECK_EQUAL(1u, h.rx.counters().duplicate);
}

TEST(RxLinkFig4, duplicate_arriving_before_use_still_counts_once) {
  Harness h;
  h.send(7);
  CHECK_TRUE(h.send(7) == RxVerdict::kDuplicate);
  CHECK_TRUE(h.rx.begin_tick(8).fresh);
  CHECK_FALSE(h.rx.begin_tick(9).fresh);
}

TEST(RxLinkFig4, wrong_payload_size_is_rejected_without_touching_state) {
  Harness h;
  h.send(1);
  const double x[2] = {99, 99}, v[2] = {99, 99};
  CHECK_TRUE(h.rx.offer(2, 0.0, x, v, 2) == RxVerdict::kBadSize);
  auto view = h.rx.begin_tick(2);
  DOUBLES_EQUAL(1.0, view.x_hat[0], 0);
  CHECK_EQUAL(1u, h.rx.counters().bad_size);
}

TEST(RxLinkFig4, before_any_packet_the_shared_initial_state_is_held) {
  Harness h;
  auto v = h.rx.begin_tick(0);
  CHECK_EQUAL(1, v.index_delay);  // initial sequence -1
  CHECK_FALSE(v.fresh);
  DOUBLES_EQUAL(0.0, v.x_hat[0], 0);
}

// The paper's rule (Fig. 4: N_ij^k from the most recently RECEIVED packet) on the same cases, side
// by side with newest-by-sequence.
TEST_GROUP(RxLinkPaperRule){};

TEST(RxLinkPaperRule, two_packets_in_one_tick_the_last_received_is_used_even_if_older) {
  Harness paper(RxRule::kMostRecentlyReceived), newest;
  for (Harness* h : {&paper, &newest}) {
    h->send(2);
    h->send(1);  // 1 overtaken by 2 inside the same tick
  }
  auto p = paper.rx.begin_tick(4), n = newest.rx.begin_tick(4);
  CHECK_EQUAL(3, p.index_delay);
  DOUBLES_EQUAL(1.0, p.x_hat[0], 0);
  CHECK_TRUE(p.fresh);
  CHECK_EQUAL(2, n.index_delay);
  DOUBLES_EQUAL(2.0, n.x_hat[0], 0);
}

TEST(RxLinkPaperRule, swapped_packet_arriving_late_is_used_with_its_larger_index_delay) {
  Harness paper(RxRule::kMostRecentlyReceived), newest;
  for (Harness* h : {&paper, &newest}) {
    h->send(5);
    CHECK_TRUE(h->rx.begin_tick(6).fresh);
  }
  CHECK_TRUE(paper.send(4) == RxVerdict::kAccepted);  // data swapping: late data used
  CHECK_TRUE(newest.send(4) == RxVerdict::kStale);
  auto p = paper.rx.begin_tick(7), n = newest.rx.begin_tick(7);
  CHECK_EQUAL(3, p.index_delay);
  DOUBLES_EQUAL(4.0, p.x_hat[0], 0);
  CHECK_TRUE(p.fresh);  // 4's velocity had not been used
  CHECK_EQUAL(2, n.index_delay);
  CHECK_FALSE(n.fresh);
  CHECK_EQUAL(1u, paper.rx.counters().stale);
  CHECK_EQUAL(6, paper.rx.max_sequence_seen() + 1);
}

TEST(RxLinkPaperRule, loss_sustains_and_duplicates_are_never_used_twice) {
  Harness h(RxRule::kMostRecentlyReceived);
  h.send(3);
  CHECK_TRUE(h.rx.begin_tick(4).fresh);
  auto v = h.rx.begin_tick(5);  // lost: sustained
  CHECK_FALSE(v.fresh);
  CHECK_EQUAL(2, v.index_delay);
  CHECK_TRUE(h.send(3) == RxVerdict::kDuplicate);  // repeat of the held packet
  CHECK_FALSE(h.rx.begin_tick(6).fresh);
  h.send(4);
  CHECK_TRUE(h.rx.begin_tick(7).fresh);
  h.send(3);  // a duplicate of 3 arriving after 4: held (most recently received), velocity not reused
  v = h.rx.begin_tick(8);
  CHECK_EQUAL(5, v.index_delay);
  DOUBLES_EQUAL(3.0, v.x_hat[0], 0);
  CHECK_FALSE(v.fresh);
}

TEST(RxLinkPaperRule, samples_older_than_the_window_count_as_used) {
  Harness h(RxRule::kMostRecentlyReceived);
  h.send(10);
  CHECK_TRUE(h.rx.begin_tick(11).fresh);
  const std::int64_t far = 10 + RxLink::kUsedWindow + 5;
  h.send(far);
  CHECK_TRUE(h.rx.begin_tick(far + 1).fresh);
  h.send(12);  // never used, but older than the window: delta = 0 (the passive choice)
  CHECK_FALSE(h.rx.begin_tick(far + 2).fresh);
  h.send(far - 3);  // inside the window, never used
  CHECK_TRUE(h.rx.begin_tick(far + 3).fresh);
  CHECK_THROWS(std::invalid_argument, parse_rx_rule("latest", "--receive-rule"));
  CHECK_TRUE(parse_rx_rule("paper", "x") == RxRule::kMostRecentlyReceived);
}

// take(): a packet an endpoint has judged is read where it lies (no copy): the link holds the
// caller's buffer and gives back the one it held before; a packet it does not use is given back at once.
TEST_GROUP(RxLinkTake){};

TEST(RxLinkTake, the_used_packet_is_read_in_its_buffer_and_the_replaced_buffer_is_given_back) {
  Harness h;
  const double a[6] = {1, 2, 3, 10, 20, 30}, b[6] = {4, 5, 6, 40, 50, 60}, c[6] = {7, 8, 9, 70, 80, 90};
  std::uint32_t released = 99;
  CHECK_TRUE(h.rx.take(5, 0.0, a, a + 3, 11, released) == RxVerdict::kAccepted);
  CHECK_EQUAL(RxLink::kNoSlot, released);  // held nothing before (its own initial state)
  auto v = h.rx.begin_tick(6);
  POINTERS_EQUAL(a, v.x_hat);  // in place
  POINTERS_EQUAL(a + 3, v.v_hat);
  POINTERS_EQUAL(a, h.rx.newest_x_hat());
  CHECK_TRUE(h.rx.take(4, 0.0, c, c + 3, 13, released) == RxVerdict::kStale);
  CHECK_EQUAL(13u, released);  // not used: the caller's at once
  CHECK_TRUE(h.rx.take(5, 0.0, c, c + 3, 14, released) == RxVerdict::kDuplicate);
  CHECK_EQUAL(14u, released);
  CHECK_TRUE(h.rx.take(7, 0.0, b, b + 3, 12, released) == RxVerdict::kAccepted);
  CHECK_EQUAL(11u, released);  // the buffer of packet 5 goes back
  v = h.rx.begin_tick(8);
  POINTERS_EQUAL(b, v.x_hat);
  DOUBLES_EQUAL(40.0, v.v_hat[0], 0);
  CHECK_EQUAL(1, v.index_delay);
  CHECK_TRUE(v.fresh);
  CHECK_EQUAL(2u, h.rx.counters().accepted);
}
