#pragma once
// The simulator's way into a receive link (rt::RxLink): a packet's payload is handed in place when it
// is finite and offered (checked, refused and counted) when it is not.

#include <cstdint>
#include <memory>
#include <vector>

#include "rt/rx_link.hpp"
#include "rt/tick_driver.hpp"

namespace haptic::firmware {

// One packet as the simulator's network delivers it: x_hat then v_hat (dofs values each), and whether
// every value is finite (checked once, by the sender's copy).
struct SimPacket {
  std::int64_t seq = 0;
  double send_s = 0;
  std::shared_ptr<const std::vector<double>> payload;
  bool finite = true;
};

// The payloads one receive link may read in place (RxLink::take): slot 0 or 1, the one it holds is
// held_slot (kNoSlot: none); each kept alive here until the link gives its slot back.
struct InPlaceSlots {
  std::shared_ptr<const std::vector<double>> held[2];
  std::uint32_t held_slot = rt::RxLink::kNoSlot;

  // A finite payload handed in place in the free slot (the tick rules: the same verdicts and values as
  // offer() for a finite payload of the scene's size, without the copy); a non-finite one offered
  // (checked: refused and counted, nothing held). offer: rt::offer_to's callable (or one like it).
  template <class Offer>
  void hand_in(int rx_index, const SimPacket& p, int dofs, Offer&& offer) {
    const double* x = p.payload->data();
    if (!p.finite) {
      offer(rt::ReceivedState{rx_index, p.seq, p.send_s, x, x + dofs, dofs});
      return;
    }
    const std::uint32_t slot = held_slot == 0 ? 1u : 0u;
    held[slot] = p.payload;
    std::uint32_t released = rt::RxLink::kNoSlot;
    offer(rt::ReceivedState{rx_index, p.seq, p.send_s, x, x + dofs, dofs, slot, &released});
    if (released == slot) {  // not used: the link keeps the packet it held
      held[slot].reset();
      return;
    }
    if (released != rt::RxLink::kNoSlot) held[released].reset();
    held_slot = slot;
  }
};

}  // namespace haptic::firmware
