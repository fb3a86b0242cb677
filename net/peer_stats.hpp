#pragma once
// The endpoint's statistics: per neighbour (PeerStats) and for the I/O thread (EndpointCounters),
// as copies the non-RT side reads (Endpoint::stats()). Each part of the endpoint fills its own
// fields (RoundTrip, PeerLiveness, PairAgreement, ReceiveAccount).
#include <cstdint>
#include <vector>

#include "net/wire.hpp"

namespace haptic::net {

// Statistics of one neighbor (a copy; read from any non-RT thread).
struct PeerStats {
  std::uint16_t station_id = 0;
  std::uint64_t packets_received = 0;     // complete state packets delivered
  std::uint64_t newest_seq = 0;           // of the current incarnation
  double newest_send_time_s = 0.0;        // the neighbour's send stamp of newest_seq (its clock)
  std::uint64_t lowest_seq = 0;
  double loss_fraction = 0.0;             // 1 - distinct received / (newest - lowest + 1), current incarnation
  std::uint64_t packets_received_incarnation = 0;
  double one_way_mean_s = 0.0;            // receive time - sender stamp (same-host clocks only)
  double one_way_max_s = 0.0;
  std::uint64_t packets_sent = 0, datagrams_sent = 0, impair_lost = 0, impair_duplicated = 0,
                send_errors = 0, delay_queue_full = 0;
  std::uint64_t bytes_sent = 0;           // UDP payload bytes of the datagrams sent (every kind)
  std::uint64_t rtt_samples = 0;
  std::uint64_t echoes_unmatched = 0;     // echoes naming a sequence we have no send record of
  std::uint64_t echoes_before_pause = 0;  // echoes of packets sent before our sending paused (no round-trip sample)
  double rtt_last_s = 0.0, rtt_mean_s = 0.0, rtt_min_s = 0.0, rtt_max_s = 0.0, rtt_bound_s = 0.0;
  bool rtt_probing = false, rtt_has_bound = false;
  std::uint64_t rtt_over_bound_events = 0, rtt_bound_generation = 0;
  // The round-trip bound our probing fixed (0 before; over-bound events do not change it) and the
  // one the neighbour's probing fixed for the same link, from its fingerprint messages (0: none
  // received yet): the station uses the larger, so both ends assume the same bound.
  double rtt_probe_bound_s = 0.0, peer_rtt_probe_bound_s = 0.0;
  // The neighbour's loss allowance for the link, from the same fingerprint messages (-1: none yet;
  // set_loss_allowance() is ours).
  int peer_loss_allowance_ticks = -1;
  // The neighbour's step bound T^max (s), from the same messages (0: none yet; set_step_max() is ours).
  double peer_step_max_s = 0.0;
  // Incarnation of the neighbour (0 before its first packet) and how often it changed.
  std::uint64_t incarnation = 0, incarnation_changes = 0;
  // The incarnation rule (net/README.md "Incarnations and restarts", Decoder::incarnations): the
  // newest newer incarnation refused because the current one still spoke (0: none) and its datagrams;
  // key_compromise: two live incarnations of this neighbour were seen, or (key_compromise_conflict)
  // two different authentic state datagrams with one sequence (key_compromise_seq) and fragment in one
  // incarnation (at key_compromise_s, monotonic_s()), and every datagram of it is dropped for the
  // rest of the run.
  std::uint64_t refused_incarnation = 0, refused_incarnation_datagrams = 0;
  bool key_compromise = false;
  double key_compromise_s = 0.0;
  bool key_compromise_conflict = false;
  std::uint64_t key_compromise_seq = 0;
  // The neighbour's virtual proxy position (m) from the newest state packet that carried one (wire
  // flag kFlagProxy; has_proxy false before) and that packet's sequence: for the live view only.
  bool has_proxy = false;
  std::uint64_t proxy_seq = 0;
  double proxy_m[3] = {0, 0, 0};
  // Up/down: up after its first packet, down after peer_silence_s without one.
  bool up = false;
  std::uint64_t up_events = 0, down_events = 0;
  double last_change_s = 0.0;             // monotonic_s() of the newest up/down change
  double last_down_s = 0.0, last_up_s = 0.0;  // monotonic_s() of the newest down / up change
  double last_receive_s = 0.0;
  // Clock offset (peer clock - our clock), NTP-style from the echo (our send record t1, the
  // peer's receipt t2 = t3 - hold, its send stamp t3, our receipt t4):
  //   offset = ((t2 - t1) + (t3 - t4)) / 2, taken from the lowest-round-trip sample of a window
  // of 128 samples; its error is at most half that round trip minus the hold.
  std::uint64_t clock_offset_samples = 0;
  double clock_offset_s = 0.0;
  double clock_offset_rtt_s = 0.0;        // round trip (minus hold) of the sample it came from
  bool has_fingerprint = false;
  Fingerprint fingerprint{};              // newest received from this neighbour
  // Safe-state packets (kFlagSafeState) received: the neighbour said it is in its safe state;
  // never handed to the tick. peer_safe_state: the newest state packet had the flag.
  std::uint64_t safe_state_packets = 0;
  bool peer_safe_state = false;
  std::uint64_t rate_limited = 0;         // datagrams from this neighbour's address over the rate limit
  // Pairwise keys: this run's traffic keys with the neighbour are agreed; how often they were
  // (re)agreed (a restarted neighbour brings a new nonce); hellos sent / received; state packets
  // not sent to it because no keys were agreed yet.
  bool keys_agreed = false;
  std::uint64_t key_agreements = 0, hellos_sent = 0, hellos_received = 0, tx_without_keys = 0;
};

// Totals of the I/O thread (a copy).
struct EndpointCounters {
  DropCounters drops{};
  std::uint64_t datagrams_received = 0, receive_errors = 0, rx_ring_full = 0;
  std::uint64_t wrong_scene_size = 0;  // authentic packets whose 3n differs from ours (dropped)
  std::uint64_t tx_safe_state = 0;     // packets sent with kFlagSafeState (safe state, or a non-finite state pushed)
  std::uint64_t fingerprints_received = 0;
  // Push -> first datagram handed to the transport (I/O thread), per state packet; caught
  // inside a spin window; spin windows opened (net.tx_spin).
  std::uint64_t tx_packets = 0, tx_caught_spinning = 0, tx_spin_windows = 0;
  double tx_handoff_sum_s = 0.0, tx_handoff_max_s = 0.0;
  // Direct TX (net.tx_direct), per push: sent whole by the tick; started by the tick and finished
  // by the I/O thread (of which: the socket would block); sent by the I/O thread because a
  // neighbour was not ready or an earlier push was still owed.
  std::uint64_t tx_direct = 0, tx_direct_unfinished = 0, tx_direct_would_block = 0, tx_direct_declined = 0;
};

// The totals (EndpointCounters) plus what only the caller's side knows.
struct EndpointStats : EndpointCounters {
  std::uint64_t tx_overruns = 0;
  std::uint64_t incarnation = 0;  // ours
  double io_thread_cpu_s = 0.0;   // CPU time the I/O thread has used (spinning included)
  double tx_handoff_mean_s = 0.0; // push -> first datagram handed to the transport, per packet
  std::vector<PeerStats> peers;
};

}  // namespace haptic::net
