#pragma once
// The loss allowance a station measures while probing (the station's part of "a
// bound that holds", rt/README.md): per neighbour, which probe packets (sequence numbers) arrived, and at the
// freeze of the round-trip bounds the allowance of Nbar for that incoming direction from the loss
// measured over the packets that must have arrived by then (model::loss_allowance_from_measured_loss,
// the scenario's own rule with the probability's upper confidence bound). Non-RT (probing phase).
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace haptic::firmware {

// Lost (or later than the round-trip bound) / expected probe packets of one incoming direction,
// and the longest run of consecutive ones (a burst, or sender ticks skipped by an overrun).
struct ProbeLoss {
  long long lost = 0, expected = 0, longest_gap = 0;
};

class ProbeLossCounter {
 public:
  // send_interval_ticks: the neighbours send a state at least every this many ticks (the deadband's
  // pace, probing included; 1: every tick). A silence of g ticks between two packets that arrived
  // then holds ceil(g / interval) - 1 lost ones (every one of them, when the sender keeps exactly that
  // pace as while probing; at least that many when it sends more often on a change, as a running
  // station does; a send its loaded host delayed past the pace counts as one), and packets, gaps and
  // the loss's expected count are in packets.
  explicit ProbeLossCounter(std::size_t neighbours = 0, std::int64_t send_interval_ticks = 1)
      : seen_(neighbours), first_(neighbours, -1), newest_(neighbours, -1), interval_(std::max<std::int64_t>(1, send_interval_ticks)) {}
  // One drained packet of neighbour n (n < 0: not a neighbour, ignored). Sequence numbers more than
  // kMaxSpan after the first one seen are ignored (a bounded record). Not RT-safe (may allocate).
  void add(int n, std::uint64_t seq);
  // The packets from the first one seen to (newest seen - late_ticks): each of them, unless lost,
  // has arrived by now when every packet arrives within late_ticks of the newest one (the caller
  // passes the round-trip bound in ticks, which covers any one-way spread). expected 0: too few.
  ProbeLoss loss(std::size_t n, std::int64_t late_ticks) const;
  static constexpr std::int64_t kMaxSpan = 1 << 22;

 private:
  std::vector<std::vector<bool>> seen_;           // per neighbour, seq - first
  std::vector<std::int64_t> first_, newest_;      // -1: nothing yet
  std::int64_t interval_ = 1;
};

// The round-trip loss allowance (ticks added to R_ij = Nbar_ij + Nbar_ji) from the loss measured on
// the incoming direction: 2 L, L = model::loss_allowance_from_measured_loss(lost, expected, run
// ticks, directed links), so each direction's Nbar gets L as the scenario's model gives it (both
// ends then take the larger of their two values). The model assumes independent losses; a longer
// run of consecutive losses seen while probing raises L to it. expected == 0 (nothing measured): -1.
int round_trip_loss_allowance(const ProbeLoss& loss, double run_ticks, int directed_links);

}  // namespace haptic::firmware
