#pragma once
// The edges' safeguards as they act, from the tick to the log: the neighbour state check isolating
// or re-admitting a neighbour (rt/edge_monitor.hpp) and the energy gate tripping or releasing an
// edge (rt/edge_energy.hpp). The tick must not do I/O: after each step it compares the core's
// per-edge counters with the ones it saw last and pushes one fixed-size EdgeEvent per change into a
// lock-free ring (platform/spsc_ring.hpp; a full ring drops the event and counts it); the non-RT
// side (the run loop's serve(), every <= 100 ms) drains it into log lines with the run time. The
// end-of-run lines and station-<id>.json (state_check.hpp, neighbours.hpp) still say the totals.
#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "platform/spsc_ring.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

enum class EdgeEventKind : std::uint8_t { kIsolated, kReadmitted, kGateTripped, kGateReleased };

struct EdgeEvent {
  std::int64_t kr = 0;  // run tick
  std::int32_t edge = 0;
  EdgeEventKind kind = EdgeEventKind::kIsolated;
  rt::EdgeLie reason = rt::EdgeLie::kNone;  // isolations
  std::int32_t node = -1;                   // isolations: the node that tripped
  double value = 0;                         // isolations: its value, m; gate: the account, J
  std::uint64_t count = 0;                  // the isolation's / trip's / release's number on this edge
  bool timed = false;                       // a gate release: by the timed release (not the release level)
  double forgiven_J = 0;                    // a gate release: the account excess forgiven so far on this edge
};

class EdgeEventWatch {
 public:
  // The tick, after the core's step: one event per counter that moved since the last call. RT-safe.
  void after_tick(const rt::StationCore& core, std::int64_t kr);
  // The non-RT side: the events since the last call, oldest first.
  std::vector<EdgeEvent> drain();
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  void push(const EdgeEvent& e);
  platform::SpscRing<EdgeEvent, 64> ring_;
  std::array<std::uint64_t, rt::kMaxNeighbors> isolations_{}, readmissions_{}, trips_{}, releases_{}, timed_{};
  std::atomic<std::uint64_t> dropped_{0};
};

// The log line of one event: "run time 1.008 s: isolated station 1 (neighbour state check, 1st
// time): ..." naming the key that sets the threshold. `station` is the neighbour's id (1-based).
std::string edge_event_line(const EdgeEvent& e, int station, const rt::StationCore& core);

}  // namespace haptic::firmware
