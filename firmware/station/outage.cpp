#include "firmware/station/outage.hpp"

#include <algorithm>

namespace haptic::firmware {

std::uint64_t link_packets(const rt::StationCore& core, int n) {
  const rt::RxCounters& c = core.rx(n).counters();
  return c.accepted + c.stale + c.duplicate;
}

void OutageTracker::open(const rt::StationCore& core, std::int64_t kr) {
  open_ = OutageSpan{};
  open_.first_kr = kr;
  open_.links = std::min(core.neighbor_count(), rt::kMaxNeighbors);
  for (int n = 0; n < open_.links; ++n) packets_at_open_[n] = packets_before_[n];  // before this tick's packets
  is_open_ = true;
}

// `info` is the tick after the span's last (or the last tick, at finish): its counts include the
// overruns and skipped periods of the span's ticks.
void OutageTracker::close(const platform::TickInfo& info) {
  open_.overruns = info.overruns - overruns_before_;
  open_.missed_cycles = info.missed_cycles - missed_before_;
  if (spans_ == 0) first_ = open_;
  if (longest_.empty() || open_.ticks > longest_.ticks) longest_ = open_;
  ++spans_;
  is_open_ = false;
}

void OutageTracker::on_tick(const rt::StationCore& core, std::int64_t kr, bool usable, const platform::TickInfo& info) {
  if (have_last_ && info.missed_cycles - last_info_.missed_cycles > largest_skip_) {  // the stall that ended before this tick
    largest_skip_ = info.missed_cycles - last_info_.missed_cycles;
    largest_skip_kr_ = kr;
  }
  if (!usable) {
    if (!is_open_) {
      open(core, kr);
      overruns_before_ = have_last_ ? last_info_.overruns : info.overruns;  // a stall just before it counts in it
      missed_before_ = have_last_ ? last_info_.missed_cycles : info.missed_cycles;
    }
    open_.last_kr = kr;
    ++open_.ticks;
    open_.wake_max_ns = std::max(open_.wake_max_ns, info.wake_latency_ns);
    for (int n = 0; n < open_.links; ++n) {  // as of the span's last tick
      open_.packets[n] = link_packets(core, n) - packets_at_open_[n];
      open_.age_ticks[n] = kr - core.rx(n).newest_sequence();
      open_.bound_ticks[n] = core.neighbor(n).index_delay_bound_ticks;
    }
  } else if (is_open_) {
    close(info);
  }
  const int links = std::min(core.neighbor_count(), rt::kMaxNeighbors);
  for (int n = 0; n < links; ++n) packets_before_[n] = link_packets(core, n);
  last_info_ = info;
  have_last_ = true;
}

void OutageTracker::finish() {
  if (is_open_) close(last_info_);
}

}  // namespace haptic::firmware
