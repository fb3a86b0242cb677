// Fig. 4 of the paper through the receive-side bookkeeping: varying delay, loss (sustainment),
// data swapping and duplication give the indexing delay N_ij^k and duplication avoidance (17).
#include <CppUTest/TestHarness.h>

#include <vector>

#include "rt/rx_link.hpp"

using namespace haptic::rt;

namespace {
struct Harness {
  RxLink rx;
  std::vector<double> x0 = {0, 0, 0}, v0 = {0, 0, 0};
  Harness() { rx.init(3, x0.data(), v0.data()); }
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
