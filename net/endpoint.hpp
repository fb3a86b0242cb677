#pragma once
// A station's network endpoint: one I/O thread that owns the socket (a Transport), the wire
// encoder/decoder, the per-link impairment emulator and the per-neighbor RTT estimators, and
// four fixed-capacity SPSC rings (rt/spsc_ring.hpp) that connect it to the RT thread.
//
//   RT thread                                  I/O thread
//   push_state(k, t, x, v)  --tx_ready ring-->  encode per neighbor (+echo), impair, send
//                           <--tx_free ring---
//   drain(callback)         <--rx_ready ring--  receive, verify, reassemble, RTT sample
//                           --rx_free ring--->
//
// The rings carry buffer indices; buffers (2*value_count doubles each) are allocated in the
// constructor. The RT side never touches the socket, never allocates and never locks;
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
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "net/impairment.hpp"
#include "net/rtt.hpp"
#include "net/transport.hpp"
#include "net/wire.hpp"
#include "rt/spsc_ring.hpp"

namespace haptic::net {

// CLOCK_MONOTONIC in seconds: the clock of every wire timestamp (same across processes of a host).
double monotonic_s();
std::int64_t monotonic_ns();

struct PeerLink {
  std::uint16_t station_id = 0;
  bool impaired = false;           // apply `impairment` to packets we send to this peer
  LinkImpairment impairment{};     // directed link this station -> peer
  std::uint64_t seed = 1;          // seed of this directed link
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
  double tx_spin_lead_s = 100e-6;
  double tx_spin_tail_s = 300e-6;
  double impairment_epoch_s = -1.0;  // blackout times are relative to this (monotonic_s); <0: start()
};

// Statistics of one neighbor (a copy; read from any non-RT thread).
struct PeerStats {
  std::uint16_t station_id = 0;
  std::uint64_t packets_received = 0;     // complete state packets delivered
  std::uint64_t newest_seq = 0;
  std::uint64_t lowest_seq = 0;
  double loss_fraction = 0.0;             // 1 - distinct received / (newest - lowest + 1)
  double one_way_mean_s = 0.0;            // receive time - sender stamp (same-host clocks only)
  double one_way_max_s = 0.0;
  std::uint64_t packets_sent = 0, datagrams_sent = 0, impair_lost = 0, impair_duplicated = 0,
                send_errors = 0, delay_queue_full = 0;
  std::uint64_t rtt_samples = 0;
  double rtt_last_s = 0.0, rtt_mean_s = 0.0, rtt_min_s = 0.0, rtt_max_s = 0.0, rtt_bound_s = 0.0;
  bool rtt_probing = false, rtt_has_bound = false;
  std::uint64_t rtt_over_bound_events = 0, rtt_bound_generation = 0;
};

struct EndpointStats {
  DropCounters drops{};
  std::uint64_t datagrams_received = 0, receive_errors = 0, rx_ring_full = 0, tx_overruns = 0;
  std::uint64_t wrong_scene_size = 0;  // authentic packets whose 3n differs from ours (dropped)
  // Push -> first datagram handed to the transport (I/O thread), per state packet.
  std::uint64_t tx_packets = 0, tx_caught_spinning = 0;  // caught inside a spin window
  std::uint64_t tx_spin_windows = 0;                     // spin windows opened (net.tx_spin)
  double io_thread_cpu_s = 0.0;  // CPU time the I/O thread has used (spinning included)
  double tx_handoff_mean_s = 0.0, tx_handoff_max_s = 0.0;
  std::vector<PeerStats> peers;
};

// One received state packet with its round-trip context (drain_packets()).
struct RxPacket {
  std::uint16_t sender = 0;
  std::uint64_t seq = 0;
  double send_time_s = 0.0;      // sender's CLOCK_MONOTONIC stamp
  bool has_echo = false;         // the sender echoed one of our packets
  std::uint64_t echo_seq = 0;    // our newest sequence the sender had received
  double echo_time_s = 0.0;      // our own send stamp of echo_seq (OUR clock)
  const double* x_hat = nullptr;
  const double* v_hat = nullptr;
  std::uint32_t count = 0;
  double delivered_s = 0.0;      // CLOCK_MONOTONIC when the I/O thread put it in the RX ring
  // Clock-free upper bound on this data's age at our time now_s: the sender sent it after it
  // received our packet stamped echo_time_s, so age <= now_s - echo_time_s (a round trip).
  // +inf without an echo. RT-safe.
  double age_bound_s(double now_s) const { return has_echo ? now_s - echo_time_s : 1e300; }
};

class Endpoint {
 public:
  static constexpr std::size_t kRxBuffers = 64;
  static constexpr std::size_t kTxBuffers = 16;

  // Allocates everything. Throws std::invalid_argument naming the config key on bad config.
  Endpoint(const EndpointConfig& cfg, std::unique_ptr<Transport> transport);
  ~Endpoint();
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;

  void start();  // launches the I/O thread (not RT-safe)
  void stop();   // stops and joins it (not RT-safe); idempotent

  // ---- RT side (one RT thread) -----------------------------------------------------------
  // Hands every received valid state packet to on_state(sender, seq, send_time_s, x_hat,
  // v_hat, count) in arrival order; returns how many. RT-safe: no allocation, lock or syscall.
  template <class F>
  std::size_t drain(F&& on_state, std::size_t max_packets = std::numeric_limits<std::size_t>::max()) {
    std::size_t n = 0;
    std::uint32_t idx = 0;
    while (n < max_packets && rx_ready_.try_pop(idx)) {
      const RxMeta& m = rx_meta_[idx];
      const double* x = rx_store_.data() + std::size_t{idx} * 2 * value_count_;
      on_state(m.sender, m.seq, m.send_time_s, x, x + value_count_, value_count_);
      rx_free_.try_push(idx);  // cannot fail: as many slots as buffers
      ++n;
    }
    return n;
  }
  // Same, handing an RxPacket (adds the echo, for the age guard of net/README.md). RT-safe.
  template <class F>
  std::size_t drain_packets(F&& on_packet, std::size_t max_packets = std::numeric_limits<std::size_t>::max()) {
    std::size_t n = 0;
    std::uint32_t idx = 0;
    while (n < max_packets && rx_ready_.try_pop(idx)) {
      const RxMeta& m = rx_meta_[idx];
      RxPacket p;
      p.sender = m.sender;
      p.seq = m.seq;
      p.send_time_s = m.send_time_s;
      p.has_echo = m.has_echo;
      p.echo_seq = m.echo_seq;
      p.echo_time_s = m.echo_time_s;
      p.x_hat = rx_store_.data() + std::size_t{idx} * 2 * value_count_;
      p.v_hat = p.x_hat + value_count_;
      p.count = value_count_;
      p.delivered_s = static_cast<double>(m.delivered_ns) * 1e-9;
      on_packet(static_cast<const RxPacket&>(p));
      rx_free_.try_push(idx);
      ++n;
    }
    return n;
  }
  // Queues (seq, send_time_s, x_hat, v_hat) for every neighbor. send_time_s is CLOCK_MONOTONIC
  // seconds (monotonic_s()); a negative value lets the I/O thread stamp it. false (and counted
  // as a TX overrun) when the I/O thread is behind. RT-safe (no allocation/lock; one
  // non-blocking eventfd write).
  bool push_state(std::uint64_t seq, double send_time_s, const double* x_hat, const double* v_hat);
  // Per neighbor (index into config peers): the current round-trip bound in ticks of
  // period_s and its generation (bumps on every change: probing done, over-bound event).
  // RT-safe (atomics).
  std::uint32_t rtt_bound_ticks(std::size_t peer_index, double period_s) const;
  std::uint64_t rtt_bound_generation(std::size_t peer_index) const;

  // ---- start-up / monitoring (non-RT) -----------------------------------------------------
  // Blocks up to timeout_s until the RX ring holds a packet (for non-RT consumers: tools,
  // benchmarks; the RT tick polls drain() instead). true when one is waiting. Not RT-safe.
  bool wait_rx(double timeout_s);
  void begin_probing();
  // Ends probing on every neighbor with enough samples; true when all have a bound.
  bool finish_probing();
  EndpointStats stats() const;
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
  };
  struct Delayed {
    std::int64_t release_ns;
    std::uint64_t order;
    std::uint16_t dest;
    std::uint32_t len;
    std::uint32_t slot;
  };
  struct PeerState {
    PeerLink link;
    ImpairedLink impaired;
    RttEstimator rtt;
    // The newest packet received from this peer and the one before it, with their receive
    // times. A state is echoed only with a packet received by its own send stamp, so the
    // receiver's age bound (now - echoed send time) never understates the state's age.
    struct EchoSlot {
      bool valid = false;
      std::uint64_t seq = 0;
      std::int64_t send_time_ns = 0;
      std::int64_t receive_time_ns = 0;
    };
    EchoSlot echo, previous_echo;
    const EchoSlot* echo_as_of(std::int64_t stamp_ns) const {
      if (echo.valid && echo.receive_time_ns <= stamp_ns) return &echo;
      if (previous_echo.valid && previous_echo.receive_time_ns <= stamp_ns) return &previous_echo;
      return nullptr;
    }
    std::uint64_t last_sampled_echo = 0;
    bool sampled_any = false;
    PeerStats stats;
    std::atomic<std::uint64_t> bound_ns{0};
    std::atomic<std::uint64_t> bound_generation{0};
  };

  void run();
  bool spin_for_push(std::int64_t until_ns);  // I/O thread: tick-synchronous TX window
  void handle_rx(std::int64_t now_ns);
  void handle_tx(std::int64_t now_ns, bool caught_spinning = false);
  void release_due(std::int64_t now_ns);
  void send_now(std::uint16_t dest, const std::uint8_t* d, std::size_t len, PeerState& p);
  void publish_bound(PeerState& p);
  int find_peer(std::uint16_t id) const;

  std::uint32_t value_count_;
  std::unique_ptr<Transport> transport_;
  Encoder encoder_;
  Decoder decoder_;
  std::vector<std::unique_ptr<PeerState>> peers_;
  std::size_t frags_per_packet_;
  double epoch_s_;
  bool busy_poll_;
  bool tx_spin_;
  int io_cpu_;
  std::int64_t tx_period_ns_, tx_lead_ns_, tx_tail_ns_;

  rt::SpscRing<std::uint32_t, kRxBuffers> rx_ready_, rx_free_;
  rt::SpscRing<std::uint32_t, kTxBuffers> tx_ready_, tx_free_;
  std::vector<RxMeta> rx_meta_;
  std::vector<double> rx_store_;
  std::vector<TxMeta> tx_meta_;
  std::vector<double> tx_store_;
  std::atomic<std::uint64_t> tx_overruns_{0};
  // true while the I/O thread spins on tx_ready_ (push_state() then skips the eventfd write;
  // seq_cst on both sides: a push is either seen by the spin or wakes the thread).
  std::atomic<bool> tx_spinning_{false};
  std::atomic<std::uint64_t> tx_pushed_{0};

  // I/O thread only.
  std::vector<std::uint8_t> rx_buf_;
  std::vector<std::uint8_t> tx_buf_;
  std::vector<std::uint8_t> delay_store_;
  std::vector<Delayed> delay_heap_;
  std::vector<std::uint32_t> delay_free_;
  std::uint64_t delay_order_ = 0;
  std::size_t max_datagram_;
  int wake_fd_ = -1;
  int rx_wake_fd_ = -1;  // written by the I/O thread after a delivery while wait_rx() waits
  std::atomic<int> rx_waiters_{0};
  std::atomic<std::uint64_t> rx_delivered_{0};
  std::atomic<bool> running_{false};
  std::thread thread_;
  double io_cpu_at_stop_s_ = 0.0;
  double io_thread_cpu_s() const;

  mutable std::mutex stats_mutex_;  // guards PeerState::rtt/stats and the counters below
  std::uint64_t datagrams_received_ = 0, receive_errors_ = 0, rx_ring_full_ = 0, wrong_scene_size_ = 0;
  std::uint64_t tx_packets_ = 0, tx_caught_spinning_ = 0;
  double tx_handoff_sum_s_ = 0.0, tx_handoff_max_s_ = 0.0;
  std::int64_t last_push_ns_ = -1;  // I/O thread: push stamp of the newest packet sent
  // Consecutive windows without a push; at kMaxMissedWindows the thread stops spinning until
  // the next push (which arrives through the eventfd) re-arms it.
  static constexpr int kMaxMissedWindows = 4;
  int missed_windows_ = 0;
  std::int64_t wake_late_ns_ = 0, window_late_max_ = 0;  // learned timer lateness (run())
  std::uint64_t windows_ = 0;  // guarded by stats_mutex_ for stats()
};

}  // namespace haptic::net
