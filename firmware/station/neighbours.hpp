#pragma once
// What a station checks and logs about its neighbours (lifecycle), from the network
// endpoint's statistics snapshots (net/): fingerprints (scene, period, gains, protocol) compared
// field by field, the offset of each neighbour's tick grid (its epoch, mapped into our clock by
// the NTP-style clock offset) against ours, and neighbour down/up events, logged once each.
// Everything here runs on non-RT threads (it allocates and formats strings).
#include <cstdint>
#include <string>
#include <vector>

#include "firmware/station/plan.hpp"
#include "net/endpoint.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

// "" when every neighbour that sent a fingerprint agrees with ours; else one clause per
// differing neighbour: "station 2: scene nodes: 33 here, 27 at the peer; scene data (hash) differs".
std::string fingerprint_mismatches(const StationPlan& plan, const net::EndpointStats& stats);

// Per neighbour: the smallest (send stamp - seq T) seen, i.e. its epoch in its own clock plus its
// smallest push lag (filled from drained packets; preallocated, RT-safe to update).
struct NeighbourGrid {
  std::vector<double> epoch_own_clock_s;  // +inf until a packet arrived
  std::vector<double> newest_seq;         // newest sequence seen (as double), -1 before
  explicit NeighbourGrid(std::size_t neighbours = 0);
  // One drained packet of neighbour n. RT-safe (no allocation).
  void add(int n, std::uint64_t seq, double send_time_s, double period_s);
};

// The offset of each neighbour's tick grid against ours, in seconds on our clock:
//   offset_n = (epoch_n in its clock - clock_offset_n) - our epoch,
// with its uncertainty (half the round trip of the clock-offset sample, plus one period of push lag).
// Used up to station.clock_offset_limit_ms: the run maps neighbour n's sequence numbers onto our
// grid by shift_ticks[n] = round(offset_n / T) (its tick s happens at our tick s + shift), so a
// station whose clock (or start_at) is off couples on time; beyond the limit (less the uncertainty)
// the station refuses to couple, naming both stations and the offset.
struct ClockCheck {
  std::vector<double> grid_offset_s, uncertainty_s;  // per neighbour (NaN: no estimate)
  std::vector<std::int64_t> shift_ticks;             // per neighbour: added to its sequence numbers (0: no estimate)
  std::string message;  // "" when every known offset is within the bound beyond its uncertainty
  bool exceeded = false;
  std::string refusal;  // "" when every known offset is within station.clock_offset_limit_ms
};
ClockCheck check_clock_offsets(const StationPlan& plan, const net::EndpointStats& stats, const NeighbourGrid& grid, std::int64_t epoch_ns);

// Down/up events of the neighbours, each reported once: call poll() with fresh statistics;
// it returns the new events as log lines with the station id and the run time (since
// `run_epoch_ns`: "neighbour 2 went silent at run time 5.214 s (no packet for net.peer_silence_s)").
// Events before run_epoch_ns + quiet_s are counted silently: the first up of each neighbour
// (probing found it) and the pause between probing and the run (no packets are sent while the
// core is built) are not events. A restart says its new incarnation ("(restarted: new incarnation
// I)"); a newer incarnation refused while the current one spoke, and a key compromise
// (key_compromise_messages), are logged whenever they happen, probing included.
// The per-edge energy bound's trips (rt::EdgeEnergyGate, net/README.md "Bounded damage from an
// authenticated peer"), one line per neighbour that tripped: "neighbour 3: energy bound 0.1 J
// tripped 1 time(s) ...". Called after the run loop ended (reads the core). Not RT-safe.
std::vector<std::string> energy_bound_events(const StationPlan& plan, const rt::StationCore& core);
// The edges whose data came back after an outage (or a rejoin) and were ramped in
// (rt/return_ramp.hpp), one line per such neighbour: "neighbour 1: its data returned after an
// outage 1 time(s); the copies were pulled together over station.return_ramp_s = 2 s (last offset
// 7.2 mm)"; and those whose drop for age faded out (rt/drop_fade.hpp): "neighbour 1: its data aged
// out 1 time(s); the edge was released over station.drop_fade_s = 0.4 s". After the run loop. Not RT-safe.
std::vector<std::string> return_ramp_events(const StationPlan& plan, const rt::StationCore& core);

// The round trips net/ measured above the bound during the run, one line per neighbour that had
// any: "neighbour 2: 1 round trip(s) above the probing bound 30.0 ms (largest 33.9 ms; R_ij = 48.0 ms
// with the loss allowance, which B_i and the age guard use): B_i was not re-derived; ...".
// `bound_ticks`: the build's R_ij per neighbour. Not RT-safe.
std::vector<std::string> round_trip_over_bound_events(const StationPlan& plan, const net::EndpointStats& stats,
                                                      const std::vector<int>& bound_ticks);

// One line per neighbour found with two live incarnations (net/README.md "Incarnations and
// restarts": a second holder of its key; PeerStats::key_compromise): "key compromise suspected:
// station 2 has two live incarnations (I1 and I2); ...". Not RT-safe.
std::vector<std::string> key_compromise_messages(const StationPlan& plan, const net::EndpointStats& stats);

class PeerEventLog {
 public:
  PeerEventLog(const StationPlan& plan, std::int64_t run_epoch_ns, double quiet_s);
  std::vector<std::string> poll(const net::EndpointStats& stats);
  std::uint64_t events() const { return events_; }

 private:
  const StationPlan* plan_;
  double epoch_s_, quiet_until_s_;
  std::vector<std::uint64_t> downs_, ups_, incarnation_changes_, refused_;
  std::vector<bool> compromised_;
  std::uint64_t events_ = 0;
};

}  // namespace haptic::firmware
