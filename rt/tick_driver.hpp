#pragma once
// One tick of a StationCore from its inputs (DESIGN.md, "One tick of station i"): every state
// packet received for the tick is offered to its receive link at index seq - k0, then the core
// steps at index k with the device sample and the step T_k. The one way a StationCore is driven:
// the station's run tick, the simulator, replay, the jitter workload, the solver choice and the
// benchmark all call drive_tick(). Where the packets come from (the endpoint's ring, a simulated
// channel, a session log, a synthetic source) and what happens to each verdict (counted, recorded)
// stay with the caller: `packets` hands them over, `observer` hears each verdict.
// RT-safe when the caller's callables are (templates, no std::function: nothing is allocated here).
#include <cstdint>

#include "rt/rx_link.hpp"
#include "rt/station.hpp"

namespace haptic::rt {

// One received state packet, as its sender sent it.
struct ReceivedState {
  int link = 0;                   // the receiving core's neighbour index (its receive link)
  std::int64_t seq = 0;           // the sender's sequence number (its tick index)
  double send_time_s = 0;         // the sender's send stamp
  const double* x_hat = nullptr;  // count doubles each
  const double* v_hat = nullptr;
  int count = 0;
  // A real station's packet in an RX buffer of its endpoint (RxLink::take: the tick rules only, the
  // link reads the buffer in place): its slot, and where the buffer the link gives back goes
  // (RxLink::kNoSlot: none). kNoSlot (default): offer(), which checks size and finiteness and copies.
  std::uint32_t slot = RxLink::kNoSlot;
  std::uint32_t* released = nullptr;
};

// The inputs of one tick besides its packets.
struct TickDrive {
  std::int64_t k = 0;   // the core's tick index, the index its receive links count in
  std::int64_t k0 = 0;  // the sequence number of index 0: a packet's index is seq - k0
  Vec3 device_position_m = Vec3::Zero();  // the device sample, object frame (NaN: none; the core's safe state)
  double step_s = 0;    // the step T_k asked for (StationCore::tick clamps it and rounds it to a level)
};

// Hears nothing: the observer of a caller that neither counts nor records.
struct NoTickObserver {
  void offered(const ReceivedState&, std::int64_t /*index*/, RxVerdict) {}
  void stepping() {}
};

// One packet into core.rx(p.link) at index seq - k0: taken in place when it names an RX buffer
// (RxLink::take), else offered (RxLink::offer). Returns the link's verdict. RT-safe.
inline RxVerdict hand_in(StationCore& core, std::int64_t k0, const ReceivedState& p) {
  const std::int64_t index = p.seq - k0;
  return p.slot != RxLink::kNoSlot ? core.rx(p.link).take(index, p.send_time_s, p.x_hat, p.v_hat, p.slot, *p.released)
                                   : core.rx(p.link).offer(index, p.send_time_s, p.x_hat, p.v_hat, p.count);
}

// The offer a tick's packet source calls: hand_in at index seq - k0, then observer.offered(packet,
// index, verdict); returns the verdict. drive_tick and a caller that drains packets without
// stepping (the station's receive stage) use the same one. RT-safe.
template <class Observer>
auto offer_to(StationCore& core, std::int64_t k0, Observer& observer) {
  return [&core, k0, &observer](const ReceivedState& p) {
    const RxVerdict v = hand_in(core, k0, p);
    observer.offered(p, p.seq - k0, v);
    return v;
  };
}

// The tick: packets(offer) calls offer(const ReceivedState&) once per packet received for this tick
// (offer returns the link's verdict); each is handed to its link (hand_in) and then
// observer.offered(packet, index, verdict) is called; after the last, observer.stepping(); then
// core.tick(k, device_position_m, step_s). Returns the tick's output. Always inlined into its caller
// (the driver adds no call of its own around the packets' loop). RT-safe as above.
template <class Packets, class Observer = NoTickObserver>
[[gnu::always_inline]] inline StationCore::TickOutput drive_tick(StationCore& core, const TickDrive& in, Packets&& packets, Observer&& observer = Observer{}) {
  packets(offer_to(core, in.k0, observer));
  observer.stepping();
  return core.tick(in.k, in.device_position_m, in.step_s);
}

}  // namespace haptic::rt
