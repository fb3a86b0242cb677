// The simulator's way into a receive link: a finite payload read in place, a non-finite one refused,
// counted and never held (the sender marks it; no run of the simulator reaches a NaN copy, so this is
// where the branch is tested).
#include <CppUTest/TestHarness.h>

#include <limits>
#include <memory>
#include <vector>

#include "firmware/sim/in_place_slots.hpp"

using namespace haptic;
using namespace haptic::firmware;

namespace {

constexpr int kDofs = 6;

std::shared_ptr<const std::vector<double>> payload(double value) {
  return std::make_shared<const std::vector<double>>(2 * kDofs, value);
}

struct Link {
  rt::RxLink rx;
  rt::RxVerdict last = rt::RxVerdict::kAccepted;
  Link() {
    const std::vector<double> zero(kDofs, 0.0);
    rx.init(kDofs, zero.data(), zero.data());
  }
  auto offer() {
    return [this](const rt::ReceivedState& p) {
      last = p.slot != rt::RxLink::kNoSlot ? rx.take(p.seq, p.send_time_s, p.x_hat, p.v_hat, p.slot, *p.released)
                                           : rx.offer(p.seq, p.send_time_s, p.x_hat, p.v_hat, p.count);
      return last;
    };
  }
};

}  // namespace

TEST_GROUP(InPlaceSlots){};

TEST(InPlaceSlots, AFinitePayloadIsReadInPlaceAndKeptAliveUntilTheLinkGivesItBack) {
  Link l;
  InPlaceSlots slots;
  const auto first = payload(1.0), second = payload(2.0);
  slots.hand_in(0, SimPacket{1, 0.002, first, true}, kDofs, l.offer());
  CHECK(l.last == rt::RxVerdict::kAccepted);
  CHECK(slots.held[slots.held_slot] == first);
  CHECK_EQUAL(first->data(), l.rx.newest_x_hat());  // read where it is, not copied
  slots.hand_in(0, SimPacket{2, 0.004, second, true}, kDofs, l.offer());
  CHECK(slots.held[slots.held_slot] == second);
  CHECK_EQUAL(1L, first.use_count());  // the first slot given back and let go
  CHECK_EQUAL(0u, l.rx.counters().non_finite);
}

TEST(InPlaceSlots, ANonFinitePayloadIsRefusedCountedAndNeverHeld) {
  Link l;
  InPlaceSlots slots;
  const auto good = payload(1.0);
  slots.hand_in(0, SimPacket{1, 0.002, good, true}, kDofs, l.offer());
  const std::uint32_t held = slots.held_slot;
  auto bad = std::make_shared<std::vector<double>>(2 * kDofs, 3.0);
  (*bad)[kDofs + 2] = std::numeric_limits<double>::quiet_NaN();  // one velocity
  slots.hand_in(0, SimPacket{2, 0.004, bad, false}, kDofs, l.offer());
  CHECK(l.last == rt::RxVerdict::kNonFinite);
  CHECK_EQUAL(1u, l.rx.counters().non_finite);
  CHECK_EQUAL(held, slots.held_slot);           // the link still reads the good packet...
  CHECK(slots.held[held] == good);
  CHECK(slots.held[1 - held] == nullptr);       // ...and the bad one is not kept
  CHECK_EQUAL(1L, bad.use_count());
  CHECK_EQUAL(1L, l.rx.newest_sequence());
  CHECK_EQUAL(1.0, l.rx.newest_x_hat()[0]);
}
