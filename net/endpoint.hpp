#pragma once
// A station's network endpoint: one I/O thread that owns the socket (a Transport), the wire
// encoder/decoder, the per-link impairment emulator and the per-neighbor RTT estimators, and
// four fixed-capacity SPSC rings (platform/spsc_ring.hpp) that connect it to the RT thread.
//
//   RT thread                                  I/O thread
//   push_state(k, t, x, v)  --tx_ready ring-->  encode per neighbor (+echo), impair, send
//                           <--tx_free ring---
//   drain(callback)         <--rx_ready ring--  receive, verify, reassemble, RTT sample
//                           --rx_free ring--->
//
// The rings carry buffer indices; buffers (2*value_count doubles each) are allocated in the
// constructor. The I/O thread is a platform::RtThread (net.io_cpu, EndpointConfig::io_priority)
// and shares no lock with any other thread: statistics are published in seqlock snapshot boxes
// (platform/snapshot_box.hpp) and start-up commands (probing) travel as atomics.
//
// Lifecycle (net/README.md): every datagram carries the sender's incarnation; a restarted
// neighbour (higher incarnation) is accepted afresh, an older incarnation is dropped. Round
// trips come from this station's own send records (the echo names our sequence number), and
// with the echo's holding time they give the clock offset to each neighbour (NTP-style). A
// neighbour silent for `peer_silence_s` is marked down and marked up again at its next packet
// (counted; the non-RT side logs the events, PeerEvents). With a Fingerprint configured the
// I/O thread sends it to every neighbour (the first pushes, then every 25th) and keeps the
// newest one received from each.
//
// The RT side never touches the socket, never allocates and never locks;
// push_state() wakes the I/O thread through a non-blocking eventfd write (one syscall, never
// blocks) unless the I/O thread is spinning for it (tick-synchronous TX, below), in which
// case the push is a ring write and nothing else. Everything else here is non-RT (start-up,
// shutdown, statistics).
//
// Tick-synchronous TX (EndpointConfig::tx_spin): the RT tick pushes once per period, so the
// I/O thread knows when the next push is due (previous push + period). It sleeps in ppoll
// until `tx_spin_lead_s` before that instant and then spins, receiving as it goes, until the
// push arrives or `tx_spin_tail_s` after the instant; the push is then sent within a ring
// poll (~0.1 us) instead of after a thread wake-up (tens of us on a VM). A push outside the
// window falls back to the eventfd wake-up: nothing is lost, it is only slower (counted).
//
// Direct TX (EndpointConfig::tx_direct, net/tx_direct.hpp): the tick encodes the push and sends it
// itself, one non-blocking sendmmsg for all neighbours, and publishes the push on the TX ring
// without waking the I/O thread, which does the push's bookkeeping at its next wake-up (it wakes
// for received datagrams, at least every two periods on its own; the tick wakes it only when
// kDirectBacklogWake pushes wait). The I/O thread's
// path is taken for the whole push when a neighbour is not ready, an earlier push is still owed
// by the I/O thread (order kept), or the push is too large; datagrams the kernel would not take
// are sent by the I/O thread (counted: tx_direct_unfinished, tx_direct_would_block).
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "net/delay_queue.hpp"
#include "net/envelope.hpp"
#include "net/impairment.hpp"
#include "net/io_thread.hpp"
#include "net/key_agreement.hpp"
#include "net/keys.hpp"
#include "net/peer_liveness.hpp"
#include "net/peer_stats.hpp"
#include "net/rate_limit.hpp"
#include "net/receive_account.hpp"
#include "net/round_trip.hpp"
#include "net/rtt.hpp"
#include "net/sequence_ceiling.hpp"
#include "net/state_channel.hpp"
#include "net/tx_direct.hpp"
#include "net/tx_spin.hpp"
#include "net/transport.hpp"
#include "net/wire.hpp"
#include "platform/snapshot_box.hpp"

namespace haptic::net {

// CLOCK_MONOTONIC in seconds: the clock of every wire timestamp (same across processes of a host).
double monotonic_s();
std::int64_t monotonic_ns();

struct PeerLink {
  std::uint16_t station_id = 0;
  bool impaired = false;           // apply `impairment` to packets we send to this peer
  LinkImpairment impairment{};     // directed link this station -> peer
  std::uint64_t seed = 1;          // seed of this directed link
  PublicKey public_key{};          // the neighbour's long-term public key (EndpointConfig::pairwise_keys)
};

struct EndpointConfig {
  WireConfig wire{};
  std::uint32_t value_count = 0;  // 3n doubles per vector
  std::vector<PeerLink> peers;
  RttConfig rtt{};
  std::size_t delay_queue_datagrams = 8192;  // net.delay_queue_datagrams, in [16, 1<<20]
  // The I/O thread spins on non-blocking receive instead of sleeping in ppoll (lowest latency,
  // burns one core: only with a core to spare; net.io_busy_poll, default false).
  bool io_busy_poll = false;
  // Tick-synchronous TX (see above; net.tx_spin, net.tx_spin_lead_us, net.tx_spin_tail_us).
  // tx_period_s is the RT tick's period (the station sets it). CPU cost: about
  // (lead + the tick's wake-up lateness) per period on the I/O thread's core.
  bool tx_spin = false;
  double tx_period_s = 0.0;
  int io_cpu = -1;  // pin the I/O thread to this CPU (net.io_cpu; -1 = let the scheduler place it)
  // SCHED_FIFO priority of the I/O thread (the station's station.io_priority; 0 = SCHED_OTHER).
  // Refused (no CAP_SYS_NICE): the thread runs SCHED_OTHER and io_setup_warnings() says why.
  int io_priority = 0;
  // A neighbour with no authentic datagram for this long is marked down (net.peer_silence_s).
  double peer_silence_s = 0.25;
  // Sent to every neighbour while the station runs (scene_nodes = 0: none sent).
  Fingerprint fingerprint{};
  // Direct TX (see above; net.tx_direct): the tick sends its push itself. Not with tx_spin.
  bool tx_direct = false;
  double tx_spin_lead_s = 100e-6;
  double tx_spin_tail_s = 300e-6;
  double impairment_epoch_s = -1.0;  // blackout times are relative to this (monotonic_s); <0: start()
  // Sequence number of the first run packet: earlier ones (probing) draw their fates from a
  // stream of their own, run packet seq draws fate seq - this of the link's stream, as the
  // simulator's channel does (net::SendImpairment).
  std::uint64_t impairment_first_run_seq = 0;
  // Sequence sanity (net.max_sequence_ahead_ticks): once the station has told the endpoint its
  // tick (note_tick), an authentic datagram with a sequence beyond that tick + this is dropped
  // (future_sequence) before it touches any state.
  std::uint64_t max_sequence_ahead_ticks = 50;
  // The session's common epoch (CLOCK_MONOTONIC ns of sequence 0), when the station was given one
  // (station.start_at / --start-at), else -1. With it and tx_period_s, the ceiling holds from the
  // start, before the first note_tick: (now - epoch) / period + max_sequence_ahead_ticks (never
  // below max_sequence_ahead_ticks). Without it (a station that plans its own epoch and may have
  // to discover a session already running) there is no ceiling until note_tick.
  std::int64_t sequence_epoch_ns = -1;
  // Pairwise keys (net/keys.hpp; net.key_file): each directed pair has its own traffic key, from
  // the pair's key exchange (own_keys, PeerLink::public_key) and a fresh per-run nonce of each
  // end, agreed by hello messages (wire kind 3) from the first push on. Until a pair has agreed,
  // no state or fingerprint is sent to that neighbour or accepted from it. false: the one shared
  // session key wire.key for everything (net.shared_session_key).
  bool pairwise_keys = false;
  StationKeyPair own_keys{};
  // Per-source datagram rate limit on the I/O thread (token bucket, burst = 0.1 s of it), applied
  // before the MAC is computed; 0 = automatic: 20x the expected rate (fragments per packet per
  // tx_period_s, 500 packets/s without a period). net.rx_rate_limit_per_s.
  double rx_rate_limit_per_s = 0.0;
  // Payload envelope (physically possible states), checked on every authentic state packet:
  // a node farther than envelope_max_offset_m from its rest position envelope_rest_x (3n), or
  // faster than envelope_max_speed_m_per_s, drops the packet (out_of_envelope). Empty / 0: off.
  std::vector<double> envelope_rest_x;
  double envelope_max_offset_m = 0.0;
  double envelope_max_speed_m_per_s = 0.0;
};

// One received state packet with its round-trip context (drain_packets()).
struct RxPacket {
  std::uint16_t sender = 0;
  std::uint64_t seq = 0;
  double send_time_s = 0.0;      // sender's CLOCK_MONOTONIC stamp
  bool has_echo = false;         // the sender echoed one of our packets (and we have its send record)
  std::uint64_t echo_seq = 0;    // our newest sequence the sender had received
  double echo_time_s = 0.0;      // our own send stamp of echo_seq, from our send records (OUR clock)
  const double* x_hat = nullptr;
  const double* v_hat = nullptr;
  std::uint32_t count = 0;
  double delivered_s = 0.0;      // CLOCK_MONOTONIC when the I/O thread put it in the RX ring
  std::uint32_t slot = 0;        // the RX buffer holding x_hat, v_hat (drain_packets: keep it, release_rx)
  // Clock-free upper bound on this data's age at our time now_s: the sender sent it after it
  // received our packet stamped echo_time_s, so age <= now_s - echo_time_s (a round trip).
  // +inf without an echo. RT-safe.
  double age_bound_s(double now_s) const { return has_echo ? now_s - echo_time_s : 1e300; }
};

class Endpoint {
 public:
  static constexpr std::size_t kRxBuffers = 64;
  static constexpr std::size_t kRxHeld = 32;  // RX buffers the RT side may keep (one per neighbour: net.peers <= this)
  static constexpr std::size_t kTxBuffers = 16;
  // Direct TX: the I/O thread wakes for the pushes' bookkeeping at least every two periods (4 ms
  // without a period) on its own; the tick wakes it only when this many pushes wait (a late I/O thread).
  static constexpr std::size_t kDirectBacklogWake = 8;
  static constexpr std::size_t kRxBatch = 16;  // datagrams per recvmmsg

  // Allocates everything. Throws std::invalid_argument naming the config key on bad config.
  Endpoint(const EndpointConfig& cfg, std::unique_ptr<Transport> transport);
  ~Endpoint();
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;

  // Launches the I/O thread on a platform::RtThread (not RT-safe). Throws when the thread cannot
  // be created or net.io_cpu cannot be applied.
  void start();
  void stop();   // stops and joins it (not RT-safe); idempotent

  // ---- RT side (one RT thread) -----------------------------------------------------------
  // Hands every received valid state packet to on_state(sender, seq, send_time_s, x_hat,
  // v_hat, count) in arrival order; returns how many. RT-safe: no allocation, lock or syscall.
  template <class F>
  std::size_t drain(F&& on_state, std::size_t max_packets = std::numeric_limits<std::size_t>::max()) {
    std::size_t n = 0;
    std::uint32_t idx = 0;
    while (n < max_packets && rx_.consumer_pop(idx)) {
      const RxMeta& m = rx_.meta(idx);
      const double* x = rx_.values(idx);
      on_state(m.sender, m.seq, m.send_time_s, x, x + value_count_, value_count_);
      rx_.consumer_release(idx);
      ++n;
    }
    return n;
  }
  // Same, handing an RxPacket (adds the echo, for the age guard of net/README.md). An on_packet that
  // returns bool keeps the buffer when it returns true: its values stay valid and untouched (out of
  // the ring) until release_rx(p.slot); the RT side may hold at most kRxHeld buffers. RT-safe.
  template <class F>
  std::size_t drain_packets(F&& on_packet, std::size_t max_packets = std::numeric_limits<std::size_t>::max()) {
    std::size_t n = 0;
    std::uint32_t idx = 0;
    while (n < max_packets && rx_.consumer_pop(idx)) {
      const RxMeta& m = rx_.meta(idx);
      RxPacket p;
      p.sender = m.sender;
      p.seq = m.seq;
      p.send_time_s = m.send_time_s;
      p.has_echo = m.has_echo;
      p.echo_seq = m.echo_seq;
      p.echo_time_s = m.echo_time_s;
      p.x_hat = rx_.values(idx);
      p.v_hat = p.x_hat + value_count_;
      p.count = value_count_;
      p.delivered_s = static_cast<double>(m.delivered_ns) * 1e-9;
      p.slot = idx;
      if constexpr (std::is_same_v<std::invoke_result_t<F&, const RxPacket&>, bool>) {
        if (!on_packet(static_cast<const RxPacket&>(p))) rx_.consumer_release(idx);
      } else {
        on_packet(static_cast<const RxPacket&>(p));
        rx_.consumer_release(idx);
      }
      ++n;
    }
    return n;
  }
  // Gives back an RX buffer drain_packets' on_packet kept. RT-safe.
  void release_rx(std::uint32_t slot) { rx_.consumer_release(slot); }
  // Queues (seq, send_time_s, x_hat, v_hat) for every neighbor. send_time_s is CLOCK_MONOTONIC
  // seconds (monotonic_s()); a negative value lets the I/O thread stamp it. false (and counted
  // as a TX overrun) when the I/O thread is behind. RT-safe (no allocation/lock; one
  // non-blocking eventfd write).
  // safe_state (or any non-finite value in x_hat/v_hat) sends the safe-state flag and zeros
  // instead of the state: a station never transmits a non-finite state. proxy: the station's
  // virtual proxy position (3 values) sent with it for the neighbours' live views (nullptr: none).
  bool push_state(std::uint64_t seq, double send_time_s, const double* x_hat, const double* v_hat, bool safe_state = false,
                  const double* proxy = nullptr);
  // The station's current tick k (the sequence numbers it pushes): from the first call on,
  // authentic datagrams with a sequence above k + max_sequence_ahead_ticks are dropped
  // (future_sequence). RT-safe (one relaxed atomic store).
  void note_tick(std::int64_t k) { ceiling_.note_tick(k); }
  // A planned pause of our sending ends now (the gap between probing and the run, while the core is
  // built): echoes of packets sent before now_ns are no round-trip samples (the neighbours held them
  // through the pause; RoundTrip::on_echo). Thread-safe (one atomic store). Not RT-safe by intent:
  // called once, before the run loop.
  void sending_resumes(std::int64_t now_ns) { echo_floor_ns_.store(now_ns, std::memory_order_relaxed); }
  // Per neighbor (index into config peers): the current round-trip bound in ticks of
  // period_s and its generation (bumps on every change: probing done, over-bound event).
  // RT-safe (atomics).
  std::uint32_t rtt_bound_ticks(std::size_t peer_index, double period_s) const;
  std::uint64_t rtt_bound_generation(std::size_t peer_index) const;

  // ---- start-up / monitoring (non-RT) -----------------------------------------------------
  // Blocks up to timeout_s until the RX ring holds a packet (for non-RT consumers: tools,
  // benchmarks; the RT tick polls drain() instead). true when one is waiting. Not RT-safe.
  bool wait_rx(double timeout_s);
  // Probing commands are carried out by the I/O thread (which owns the estimators); these
  // wait (bounded, 2 s) until it has. Not RT-safe.
  void begin_probing();
  // Ends probing on every neighbor with enough samples; true when all have a bound.
  bool finish_probing();
  // Our loss allowance for the link to peers[peer_index] (ticks, >= 0), sent from now on with our
  // frozen round-trip bound in the fingerprint messages (the neighbour's arrives in
  // PeerStats::peer_loss_allowance_ticks). Thread-safe (an atomic the I/O thread reads). Not RT-safe.
  void set_loss_allowance(std::size_t peer_index, int ticks);
  // Our step bound T^max (s, > 0), sent from now on in the fingerprint messages to every neighbour
  // (theirs arrives in PeerStats::peer_step_max_s): eq. (18) at the neighbour needs it. Thread-safe
  // (an atomic the I/O thread reads). Not RT-safe.
  void set_step_max(double t_max_s);
  // Snapshot of the statistics; never blocks the I/O thread. Not RT-safe (allocates).
  EndpointStats stats() const;
  std::uint64_t incarnation() const { return incarnation_; }
  // The I/O thread's work once, on the calling thread, at now_ns (CLOCK_MONOTONIC ns or a clock the
  // caller plays): receive what the transport holds, then send what is due, every clock read of the
  // step being now_ns. For a harness that drives the receive path without a thread (the session
  // fuzz target, tools/fuzz). Only when start() was never called: throws std::logic_error otherwise.
  // Not RT-safe.
  void step_without_thread(std::int64_t now_ns);
  // The I/O thread's set-up warnings (e.g. SCHED_FIFO refused), after start(). Not RT-safe.
  const std::vector<std::string>& io_setup_warnings() const { return io_.warnings(); }
  // "SCHED_FIFO <p>" or "SCHED_OTHER" (after start()).
  const std::string& io_scheduling() const { return io_.scheduling(); }
  std::size_t peer_count() const { return peers_.size(); }
  std::uint32_t value_count() const { return value_count_; }
  const Transport& transport() const { return *transport_; }

 private:
  struct RxMeta {
    std::uint16_t sender;
    std::uint64_t seq;
    double send_time_s;
    bool has_echo;
    std::uint64_t echo_seq;
    double echo_time_s;
    std::int64_t delivered_ns;
  };
  struct TxMeta {
    std::uint64_t seq;
    double send_time_s;
    std::int64_t push_ns;
    bool safe_state;
    bool has_proxy;
    double proxy[3];
    DirectPush direct;  // what the tick sent itself (direct TX)
  };
  // One neighbour, by role (each part in its own file, unit-tested alone).
  struct PeerState {
    explicit PeerState(const RttConfig& rtt) : round_trip(rtt) {}
    PeerLink link;
    SendImpairment impaired;   // the impairment emulator's fates of our link to it
    RoundTrip round_trip;      // echoes, round trips, clock offset, the published bound
    ReceiveAccount received;   // incarnations, sequences, loss, one-way time
    PeerLiveness liveness;     // silence detection
    PairAgreement keys;        // pairwise keys (EndpointConfig::pairwise_keys)
    PeerStats stats;           // the rest (sent counters, fingerprint, safe state); I/O thread only
    platform::SnapshotBox<PeerStats> box;  // published copy of everything
    platform::SnapshotBox<DirectTicket> ticket;  // what the tick needs to send to it (direct TX)
    std::atomic<std::int32_t> own_loss_allowance{-1};  // set_loss_allowance(); sent in fingerprints
  };

  // ---- I/O thread -----------------------------------------------------------------------
  void run();
  bool spin_for_push(std::int64_t until_ns);  // tick-synchronous TX window
  void io_step(std::int64_t now_ns, bool rx, bool caught_spinning = false);  // rx, tx, release, publish
  void check_silence(std::int64_t now_ns);
  // monotonic_ns(), or the caller's clock during step_without_thread().
  std::int64_t io_clock() const { return step_now_ns_ >= 0 ? step_now_ns_ : monotonic_ns(); }
  void apply_probe_command();
  void publish_stats();
  // Receiving: the loop, then per datagram the rate limit of its source (false: dropped), the
  // decoder's limits for it, decode and dispatch, and the hand-off of a state packet to the tick.
  void handle_rx(std::int64_t now_ns);
  bool admit(int source, std::int64_t now_ns);
  DecodeLimits rx_limits(int source, std::int64_t now_ns) const;
  void take_datagram(const RxDatagram& d, std::int64_t now_ns);  // counted, rate-limited, then receive_one
  bool refill_rx(std::size_t n);  // reads up to n datagrams into rx_batch_; false: none (or an error, counted)
  bool rx_pending() const { return rx_next_ < rx_count_; }  // datagrams read but not yet handled
  void receive_one(const RxDatagram& d, std::int64_t now_ns);
  void on_authentic(PeerState& p, std::uint64_t incarnation, std::int64_t now_ns);  // incarnation, up
  void on_hello(PeerState& p, const DecodedState& st);                               // key agreement
  void on_fingerprint(PeerState& p, const DecodedState& st);
  void on_state(PeerState& p, const DecodedState& st, std::int64_t now_ns);  // echo, RTT, offset, stats
  void deliver(const DecodedState& st);
  // Sending: per push the wanted hellos, fingerprints and the state to every neighbour.
  void handle_tx(std::int64_t now_ns, bool caught_spinning = false);
  void take_push(const TxMeta& m, const double* x, std::int64_t now_ns, bool caught_spinning);
  void count_push(const TxMeta& m, bool caught_spinning);  // tx_* counters, hand-off
  OutgoingState outgoing(const TxMeta& m, const double* x, std::uint16_t dest, std::int64_t stamp_ns) const;
  void send_push_to(PeerState& p, std::size_t i, const TxMeta& m, const double* x, std::int64_t stamp_ns, std::int64_t now_ns);
  // A neighbour's part of a push the tick sent itself: its counters, and the datagrams it could not send.
  void finish_direct(PeerState& p, OutgoingState o, const DirectPeerSend& d);
  // The tick: sends m's push itself when every neighbour's ticket is ready and nothing is owed; true when all went.
  bool try_direct(TxMeta& m, const double* x);
  DirectTicket ticket_of(const PeerState& p) const;
  void send_state(PeerState& p, const OutgoingState& o, std::int64_t now_ns);  // impaired, fragmented
  void send_fingerprints(std::int64_t stamp_ns, bool all = false);  // all: not only the scheduled ones
  // While no push comes (the planned pause between probing and the run), a fingerprint to every
  // agreed neighbour every net.peer_silence_s / 3: under this run's traffic key it keeps this
  // incarnation alive for them, so a newer one announced meanwhile is refused, never taken for a restart.
  void send_keepalive(std::int64_t now_ns);
  void send_hellos(std::int64_t stamp_ns);
  bool hellos_wanted() const;  // a neighbour without agreed keys, or one that asked for a hello
  // With pairwise keys, the hellos hellos_wanted() asks for, and the hello timer restarted from
  // now_ns (called with each push and when the timer is due).
  void send_wanted_hellos(std::int64_t stamp_ns, std::int64_t now_ns);
  void send_now(std::uint16_t dest, const std::uint8_t* d, std::size_t len, PeerState& p);
  int find_peer(std::uint16_t id) const;

  std::uint32_t value_count_;
  std::unique_ptr<Transport> transport_;
  Encoder encoder_;
  Decoder decoder_;
  std::vector<std::unique_ptr<PeerState>> peers_;
  std::size_t frags_per_packet_;
  std::uint64_t incarnation_;
  Fingerprint fingerprint_;
  bool pairwise_;  // EndpointConfig::pairwise_keys

  // The rings to and from the RT thread, and what the RT side touches.
  StateChannel<RxMeta, kRxBuffers> rx_;
  StateChannel<TxMeta, kTxBuffers> tx_;
  // Direct TX (the tick's side): its encoder batch, the tickets it read, and how many pushes it
  // left to the I/O thread (owed) against how many the I/O thread has sent (done): equal = the
  // tick may send directly without overtaking an earlier push.
  bool tx_direct_;
  DirectSender direct_;
  DirectTicket direct_tickets_[kDirectMaxDatagrams];
  std::uint64_t tx_io_owed_ = 0;
  std::atomic<std::uint64_t> tx_io_done_{0};
  std::atomic<std::uint64_t> tx_overruns_{0};
  // true while the I/O thread spins on the TX ring (push_state() then skips the wake-up;
  // seq_cst on both sides: a push is either seen by the spin or wakes the thread).
  std::atomic<bool> tx_spinning_{false};
  std::atomic<std::uint64_t> tx_pushed_{0};
  SequenceCeiling ceiling_;
  std::atomic<std::int64_t> echo_floor_ns_{0};  // sending_resumes()
  std::atomic<std::uint64_t> own_step_max_ns_{0};  // set_step_max(); sent in fingerprints (0: none yet)
  DeliveryWaiter rx_waiter_;  // wait_rx()

  // The I/O thread and what only it touches.
  IoThread io_;
  bool busy_poll_;
  std::int64_t tx_period_ns_;
  TxSpinSchedule spin_;
  double epoch_s_;  // impairment epoch
  std::int64_t silence_ns_;
  std::int64_t step_now_ns_ = -1;  // step_without_thread()'s clock (-1: the I/O thread's, monotonic_ns())
  std::vector<std::uint8_t> rx_store_, tx_buf_;
  RxDatagram rx_batch_[kRxBatch];
  std::size_t rx_next_ = 0, rx_count_ = 0;  // rx_batch_[rx_next_, rx_count_) are read, not yet handled
  DelayQueue delay_;
  SendRecords send_records_;
  SourceRateLimit rate_limit_;
  PayloadEnvelope envelope_;
  std::uint64_t pushes_sent_ = 0;
  // Sequence of our control messages (fingerprints, hellos): one more for each one sent, so a
  // receiver's control replay window refuses any repeat (wire.hpp, Decoder).
  std::uint64_t control_seq_ = 0;
  std::int64_t last_push_ns_ = 0, next_keepalive_ns_ = 0;  // send_keepalive
  // Hellos also go out on a timer (one period, 2 ms without one) while hellos_wanted(): a station
  // that does not push yet (probing before its k = 0) still agrees keys with a running neighbour.
  std::int64_t hello_interval_ns_ = 2'000'000, next_hello_ns_ = 0;
  EndpointCounters counters_{};  // published to counters_box_
  platform::SnapshotBox<EndpointCounters> counters_box_;

  // Probing commands (non-RT -> I/O thread): the request number, the command, the I/O
  // thread's acknowledgement and the result of the newest finish.
  enum : int { kProbeNone = 0, kProbeBegin = 1, kProbeFinish = 2 };
  std::atomic<int> probe_command_{kProbeNone};
  std::atomic<std::uint64_t> probe_request_{0}, probe_done_{0};
  std::atomic<bool> probe_all_bound_{false};
  bool probe_command(int command);  // posts and waits (bounded); the finish result
};

}  // namespace haptic::net
