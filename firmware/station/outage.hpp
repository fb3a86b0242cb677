#pragma once
// What the run tick measures so that a failed run can say why (firmware/README.md, "Why a run
// failed"): the spans of run ticks in which no neighbour's data was within its index-delay bound
// (each with this host's own timing in it and, per link, how many packets arrived and how old the
// newest was against N̄), and the longest stall of the host (periods the loop skipped at once).
// Fixed-size, filled by the tick: nothing allocates, locks or blocks.
#include <cstdint>

#include "platform/periodic_loop.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

// One span of consecutive run ticks with no usable neighbour.
struct OutageSpan {
  std::int64_t first_kr = -1, last_kr = -1;        // run ticks, inclusive (-1: no span)
  std::int64_t ticks = 0;                          // ticks in it (fewer than last - first + 1 when cycles were skipped)
  std::int64_t wake_max_ns = 0;                    // this host: the latest wake-up of a tick in it
  std::uint64_t overruns = 0, missed_cycles = 0;   // this host: deadlines missed in it
  int links = 0;
  std::uint64_t packets[rt::kMaxNeighbors] = {};   // run packets that arrived from each link in it
  std::int64_t age_ticks[rt::kMaxNeighbors] = {};  // N at its last tick: kr - the newest sequence held
  std::int64_t bound_ticks[rt::kMaxNeighbors] = {};  // N̄ (the link's index-delay guard)
  bool empty() const { return first_kr < 0; }
};

// The tick's record of outages and stalls. on_tick is RT-safe (no allocation, lock or call that
// blocks); finish() and the accessors are for the non-RT side after the loop ended.
class OutageTracker {
 public:
  // After the core's tick kr: `usable` = some neighbour's data is within its bound.
  void on_tick(const rt::StationCore& core, std::int64_t kr, bool usable, const platform::TickInfo& info);
  // Closes a span still open at the end of the run (after the loop ended). Not RT-safe.
  void finish();

  int spans() const { return spans_; }
  const OutageSpan& first() const { return first_; }
  const OutageSpan& longest() const { return longest_; }
  // The largest number of periods the loop skipped at once, and the run tick that followed the stall.
  std::uint64_t largest_skip_cycles() const { return largest_skip_; }
  std::int64_t largest_skip_end_kr() const { return largest_skip_kr_; }

 private:
  void open(const rt::StationCore& core, std::int64_t kr);
  void close(const platform::TickInfo& info);

  OutageSpan open_{};
  bool is_open_ = false;
  std::uint64_t packets_at_open_[rt::kMaxNeighbors] = {};
  std::uint64_t packets_before_[rt::kMaxNeighbors] = {};  // each link's count after the previous tick
  std::uint64_t overruns_before_ = 0, missed_before_ = 0;  // the loop's counts before this tick
  OutageSpan first_{}, longest_{};
  int spans_ = 0;
  std::uint64_t largest_skip_ = 0;
  std::int64_t largest_skip_kr_ = -1;
  platform::TickInfo last_info_{};
  bool have_last_ = false;
};

// Run packets the core's link n has been offered so far (used, stale or duplicate). RT-safe.
std::uint64_t link_packets(const rt::StationCore& core, int n);

}  // namespace haptic::firmware
