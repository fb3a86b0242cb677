#include "net/endpoint.hpp"

#include <poll.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <thread>

#include "platform/clock.hpp"

namespace haptic::net {

std::int64_t monotonic_ns() { return platform::monotonic_ns(); }
double monotonic_s() { return platform::monotonic_s(); }

namespace {
using platform::to_timespec;
inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}
std::vector<std::uint16_t> peer_ids(const EndpointConfig& cfg) {
  std::vector<std::uint16_t> ids;
  for (const auto& p : cfg.peers) ids.push_back(p.station_id);
  return ids;
}
const EndpointConfig& checked(const EndpointConfig& cfg, const Transport* t) {
  if (t == nullptr) throw std::invalid_argument("net: endpoint needs a transport");
  if (cfg.value_count == 0 || cfg.value_count > 3u * 100000u)
    throw std::invalid_argument("net: scene value count (3 x nodes) must be in [1, 300000]");
  if (cfg.peers.empty()) throw std::invalid_argument("net.peers must list at least one neighbor");
  if (cfg.peers.size() > Endpoint::kRxHeld)
    throw std::invalid_argument("net.peers lists " + std::to_string(cfg.peers.size()) + " neighbours; at most " +
                                std::to_string(Endpoint::kRxHeld) + " (the tick holds one receive buffer per neighbour)");
  if (cfg.delay_queue_datagrams < 16 || cfg.delay_queue_datagrams > (1u << 20))
    throw std::invalid_argument("net.delay_queue_datagrams must be in [16, 1048576]");
  if (cfg.io_priority < 0 || cfg.io_priority > 98)
    throw std::invalid_argument("station.io_priority must be 0 (SCHED_OTHER) or a SCHED_FIFO priority 1..98; got " +
                                std::to_string(cfg.io_priority));
  if (!(cfg.peer_silence_s >= 0.01 && cfg.peer_silence_s <= 60.0))
    throw std::invalid_argument("net.peer_silence_s must be in [0.01, 60] s");
  if (cfg.io_cpu < -1 || cfg.io_cpu >= CPU_SETSIZE)
    throw std::invalid_argument("net.io_cpu must be -1 (unpinned) or a CPU number; got " + std::to_string(cfg.io_cpu));
  if (cfg.tx_spin && cfg.tx_direct)
    throw std::invalid_argument("net.tx_spin and net.tx_direct are both true: choose one (tx_direct: the tick sends "
                                "itself; tx_spin: the I/O thread spins for the push)");
  if (cfg.tx_spin) {
    if (!(cfg.tx_period_s > 0.0 && cfg.tx_period_s <= 1.0))
      throw std::invalid_argument("net.tx_spin needs the tick period (0, 1] s; got " + std::to_string(cfg.tx_period_s));
    if (!(cfg.tx_spin_lead_s >= 0.0 && cfg.tx_spin_lead_s < cfg.tx_period_s))
      throw std::invalid_argument("net.tx_spin_lead_us must be in [0, period)");
    if (!(cfg.tx_spin_tail_s > 0.0 && cfg.tx_spin_lead_s + cfg.tx_spin_tail_s < cfg.tx_period_s))
      throw std::invalid_argument("net.tx_spin_tail_us must be > 0 and lead + tail < period");
  }
  if (!(cfg.rx_rate_limit_per_s >= 0.0 && std::isfinite(cfg.rx_rate_limit_per_s)))
    throw std::invalid_argument("net.rx_rate_limit_per_s must be >= 0 (0 = automatic)");
  if (cfg.max_sequence_ahead_ticks < 1 || cfg.max_sequence_ahead_ticks > (1ull << 40))
    throw std::invalid_argument("net.max_sequence_ahead_ticks must be in [1, 2^40]");
  if (cfg.envelope_max_offset_m > 0.0 && cfg.envelope_rest_x.size() != cfg.value_count)
    throw std::invalid_argument("net: the payload envelope needs the rest positions of every node (3n values)");
  if (!(cfg.envelope_max_offset_m >= 0.0) || !(cfg.envelope_max_speed_m_per_s >= 0.0))
    throw std::invalid_argument("net: payload envelope bounds must be >= 0");
  if (cfg.wire.max_datagram_bytes > t->max_datagram_bytes())
    throw std::invalid_argument("net.max_datagram_bytes = " + std::to_string(cfg.wire.max_datagram_bytes) +
                                " exceeds what transport " + t->name() + " carries (" +
                                std::to_string(t->max_datagram_bytes()) + ")");
  return cfg;
}
WireConfig with_incarnation(WireConfig w) {
  if (w.incarnation == 0) w.incarnation = new_incarnation();
  return w;
}
// 20x the expected datagram rate per source (one packet per tick, plus fingerprints), or as configured.
double rx_rate_per_s(const EndpointConfig& cfg, std::size_t frags_per_packet) {
  const double packets_per_s = cfg.tx_period_s > 0.0 ? 1.0 / cfg.tx_period_s : 500.0;
  return cfg.rx_rate_limit_per_s > 0.0 ? cfg.rx_rate_limit_per_s
                                       : 20.0 * packets_per_s * static_cast<double>(frags_per_packet + 1);
}
std::int64_t to_ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }
}  // namespace

Endpoint::Endpoint(const EndpointConfig& cfg, std::unique_ptr<Transport> transport)
    : value_count_(checked(cfg, transport.get()).value_count),
      transport_(std::move(transport)),
      encoder_(with_incarnation(cfg.wire)),
      decoder_(cfg.wire, peer_ids(cfg), cfg.value_count),
      frags_per_packet_(encoder_.fragment_count(cfg.value_count)),
      incarnation_(encoder_.config().incarnation),
      fingerprint_(cfg.fingerprint),
      pairwise_(cfg.pairwise_keys),
      rx_(cfg.value_count),
      tx_(cfg.value_count),
      tx_direct_(cfg.tx_direct),
      direct_(encoder_, *transport_, cfg.tx_direct ? cfg.peers.size() : kDirectMaxDatagrams + 1, cfg.value_count,
              cfg.wire.max_datagram_bytes),
      ceiling_(cfg.max_sequence_ahead_ticks, cfg.sequence_epoch_ns, to_ns(cfg.tx_period_s)),
      io_(cfg.io_cpu, cfg.io_priority),
      busy_poll_(cfg.io_busy_poll),
      tx_period_ns_(to_ns(cfg.tx_period_s)),
      spin_(cfg.tx_spin ? to_ns(cfg.tx_period_s) : 0, to_ns(cfg.tx_spin_lead_s), to_ns(cfg.tx_spin_tail_s)),
      epoch_s_(cfg.impairment_epoch_s),
      silence_ns_(to_ns(cfg.peer_silence_s)),
      rx_store_(kRxBatch * (cfg.wire.max_datagram_bytes + 1)),
      tx_buf_(cfg.wire.max_datagram_bytes),
      delay_(cfg.delay_queue_datagrams, cfg.wire.max_datagram_bytes),
      rate_limit_(rx_rate_per_s(cfg, frags_per_packet_), std::max(16.0, 0.1 * rx_rate_per_s(cfg, frags_per_packet_)),
                  cfg.peers.size()),
      envelope_{cfg.envelope_max_offset_m > 0.0 ? cfg.envelope_rest_x : std::vector<double>{}, cfg.envelope_max_offset_m,
                cfg.envelope_max_speed_m_per_s} {
  if (frags_per_packet_ == 0)
    throw std::invalid_argument("net: scene too large for " + std::to_string(kMaxFragments) +
                                " fragments of net.max_datagram_bytes = " + std::to_string(cfg.wire.max_datagram_bytes));
  const RunNonce my_nonce = pairwise_ ? new_run_nonce() : RunNonce{};
  for (const auto& l : cfg.peers) {
    auto p = std::make_unique<PeerState>(cfg.rtt);
    p->link = l;
    if (l.impaired) p->impaired = SendImpairment(l.impairment, l.seed, cfg.impairment_first_run_seq);
    p->stats.station_id = l.station_id;
    if (pairwise_) {
      p->keys = PairAgreement(cfg.own_keys, cfg.wire.station_id, l.public_key, l.station_id, my_nonce);
      decoder_.set_peer_keys(l.station_id, p->keys.hello_rx_key(), nullptr);  // hellos only, until agreed
    }
    peers_.push_back(std::move(p));
  }
  for (std::size_t i = 0; i < kRxBatch; ++i)  // one larger than a legal datagram: MSG_TRUNC tells the real size
    rx_batch_[i] = RxDatagram{rx_store_.data() + i * (cfg.wire.max_datagram_bytes + 1), cfg.wire.max_datagram_bytes + 1, 0, -2};
  publish_stats();
  if (tx_period_ns_ > 0) hello_interval_ns_ = tx_period_ns_;
}

Endpoint::~Endpoint() { stop(); }

bool Endpoint::wait_rx(double timeout_s) {
  return rx_waiter_.wait(timeout_s, [this] { return rx_.ready_size() > 0; });
}

void Endpoint::start() {
  if (io_.running()) return;
  if (epoch_s_ < 0.0) epoch_s_ = monotonic_s();
  io_.start([this] { run(); });
}

void Endpoint::stop() { io_.stop(); }

int Endpoint::find_peer(std::uint16_t id) const {
  for (std::size_t i = 0; i < peers_.size(); ++i)
    if (peers_[i]->link.station_id == id) return static_cast<int>(i);
  return -1;
}

bool Endpoint::push_state(std::uint64_t seq, double send_time_s, const double* x_hat, const double* v_hat, bool safe_state,
                          const double* proxy) {
  std::uint32_t idx = 0;
  if (!tx_.producer_acquire(idx)) {
    tx_overruns_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  double* dst = tx_.values(idx);
  std::memcpy(dst, x_hat, sizeof(double) * value_count_);
  std::memcpy(dst + value_count_, v_hat, sizeof(double) * value_count_);
  // Never transmit a non-finite state: send the safe-state flag (and zeros) instead.
  for (std::size_t i = 0; i < 2 * std::size_t{value_count_} && !safe_state; ++i) safe_state = !std::isfinite(dst[i]);
  TxMeta& m = tx_.meta(idx);
  m = TxMeta{seq, send_time_s, monotonic_ns(), safe_state, false, {0, 0, 0}, DirectPush{}};  // vDSO clock read, no syscall
  if (proxy != nullptr && std::isfinite(proxy[0]) && std::isfinite(proxy[1]) && std::isfinite(proxy[2]))
    m.has_proxy = true, m.proxy[0] = proxy[0], m.proxy[1] = proxy[1], m.proxy[2] = proxy[2];
  const bool sent = tx_direct_ && try_direct(m, dst);
  tx_.producer_publish(idx);
  if (sent) {  // the I/O thread does the bookkeeping at its next wake-up; wake it only for a backlog
    if (tx_.ready_size() >= kDirectBacklogWake) io_.wake();
    return true;
  }
  ++tx_io_owed_;
  // Dekker pair with spin_for_push() (seq_cst, no fences): if we see the I/O thread spinning,
  // its end-of-window check sees this push; otherwise we wake it.
  tx_pushed_.fetch_add(1, std::memory_order_seq_cst);
  if (tx_spinning_.load(std::memory_order_seq_cst)) return true;  // the spin sees it
  io_.wake();  // EFD_NONBLOCK: never blocks
  return true;
}

bool Endpoint::try_direct(TxMeta& m, const double* x) {
  if (!direct_.enabled() || tx_io_owed_ != tx_io_done_.load(std::memory_order_acquire)) return false;
  const std::size_t n = peers_.size();
  for (std::size_t i = 0; i < n; ++i)
    if (!peers_[i]->ticket.reader_try_snapshot(direct_tickets_[i]) || !direct_tickets_[i].ready) return false;
  const OutgoingState o = outgoing(m, x, 0, m.send_time_s >= 0.0 ? to_ns(m.send_time_s) : m.push_ns);
  m.direct.stamp_ns = o.send_time_ns;
  direct_.send(o, direct_tickets_, n, m.direct);
  m.direct.done_ns = monotonic_ns();
  return m.direct.complete;
}

std::uint32_t Endpoint::rtt_bound_ticks(std::size_t i, double period_s) const {
  if (i >= peers_.size()) return 0;
  return bound_ticks(static_cast<double>(peers_[i]->round_trip.bound_ns()) * 1e-9, period_s);
}

std::uint64_t Endpoint::rtt_bound_generation(std::size_t i) const {
  return i < peers_.size() ? peers_[i]->round_trip.generation() : 0;
}

bool Endpoint::probe_command(int command) {
  if (!io_.started() || !io_.running()) {
    // No I/O thread: nothing runs concurrently, apply here.
    probe_command_.store(command, std::memory_order_relaxed);
    apply_probe_command();
    return probe_all_bound_.load(std::memory_order_relaxed);
  }
  probe_command_.store(command, std::memory_order_relaxed);
  const std::uint64_t req = probe_request_.fetch_add(1, std::memory_order_acq_rel) + 1;
  io_.wake();
  // Bounded wait: the I/O thread looks at the request at least every 100 ms.
  for (int i = 0; i < 2000 && probe_done_.load(std::memory_order_acquire) < req; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return probe_done_.load(std::memory_order_acquire) >= req && probe_all_bound_.load(std::memory_order_acquire);
}

void Endpoint::apply_probe_command() {
  const int c = probe_command_.exchange(kProbeNone, std::memory_order_relaxed);
  if (c == kProbeBegin) {
    for (auto& p : peers_) p->round_trip.begin_probing();
  } else if (c == kProbeFinish) {
    bool all = true;
    for (auto& p : peers_) all = p->round_trip.finish_probing() && all;
    probe_all_bound_.store(all, std::memory_order_release);
  }
  publish_stats();
}

void Endpoint::begin_probing() { probe_command(kProbeBegin); }

bool Endpoint::finish_probing() { return probe_command(kProbeFinish); }

void Endpoint::set_loss_allowance(std::size_t peer_index, int ticks) {
  peers_.at(peer_index)->own_loss_allowance.store(ticks, std::memory_order_release);
}

void Endpoint::set_step_max(double t_max_s) {
  own_step_max_ns_.store(static_cast<std::uint64_t>(std::llround(t_max_s * 1e9)), std::memory_order_release);
}

void Endpoint::publish_stats() {
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    PeerStats& ps = p.stats;
    p.round_trip.fill(ps);
    p.received.fill(ps);
    p.liveness.fill(ps);
    p.keys.fill(ps);
    const IncarnationWatch w = decoder_.incarnations(p.link.station_id);
    ps.refused_incarnation = w.refused;
    ps.refused_incarnation_datagrams = w.refused_datagrams;
    ps.key_compromise = w.compromised;
    ps.key_compromise_s = static_cast<double>(w.compromised_ns) * 1e-9;
    ps.key_compromise_conflict = w.conflicting_datagrams;
    ps.key_compromise_seq = w.conflict_seq;
    p.box.writer_publish(ps);
    if (tx_direct_ && direct_.enabled()) p.ticket.writer_publish(ticket_of(p));
  }
  counters_.drops = decoder_.drops();
  counters_.tx_spin_windows = spin_.windows();
  counters_box_.writer_publish(counters_);
}

DirectTicket Endpoint::ticket_of(const PeerState& p) const {
  DirectTicket t;
  t.ready = (!pairwise_ || p.keys.agreed()) && !p.link.impaired;
  t.station_id = p.link.station_id;
  t.key = pairwise_ ? p.keys.tx_traffic() : encoder_.config().key;
  t.echo = p.round_trip.newest_echo();
  t.previous = p.round_trip.previous_echo();
  return t;
}

EndpointStats Endpoint::stats() const {
  EndpointStats s;
  static_cast<EndpointCounters&>(s) = counters_box_.reader_snapshot();
  s.incarnation = incarnation_;
  s.tx_overruns = tx_overruns_.load(std::memory_order_relaxed);
  s.io_thread_cpu_s = io_.cpu_s();
  s.tx_handoff_mean_s = s.tx_packets ? s.tx_handoff_sum_s / static_cast<double>(s.tx_packets) : 0.0;
  for (const auto& p : peers_) s.peers.push_back(p->box.reader_snapshot());
  return s;
}

// ------------------------------------------------------------------ I/O thread

void Endpoint::io_step(std::int64_t now_ns, bool rx, bool caught_spinning) {
  if (probe_request_.load(std::memory_order_acquire) != probe_done_.load(std::memory_order_relaxed)) {
    const std::uint64_t req = probe_request_.load(std::memory_order_acquire);
    apply_probe_command();
    probe_done_.store(req, std::memory_order_release);
  }
  // Direct TX: the pushes the tick sent itself get their send records before any echo of them is read.
  if (tx_direct_) handle_tx(now_ns, caught_spinning);
  if (rx || rx_pending()) handle_rx(now_ns);
  handle_tx(now_ns, caught_spinning);
  if (now_ns >= next_hello_ns_) send_wanted_hellos(now_ns, now_ns);
  send_keepalive(now_ns);
  delay_.release_due(io_clock(), [this](std::uint16_t dest, const std::uint8_t* d, std::size_t len) {
    const int pi = find_peer(dest);
    if (pi >= 0) send_now(dest, d, len, *peers_[static_cast<std::size_t>(pi)]);
  });
  check_silence(io_clock());
  publish_stats();
}

void Endpoint::step_without_thread(std::int64_t now_ns) {
  if (io_.started()) throw std::logic_error("net: step_without_thread() on an endpoint whose I/O thread was started");
  step_now_ns_ = now_ns;
  io_step(now_ns, true);
  step_now_ns_ = -1;
}

void Endpoint::check_silence(std::int64_t now_ns) {
  for (auto& p : peers_) p->liveness.check(now_ns, silence_ns_);
}

void Endpoint::run() {
  io_.body_started();
  // The ppoll timeouts below schedule the TX spin window: a SCHED_OTHER thread's default
  // 50 us timer slack would make it late, so ask for none (per thread; harmless otherwise).
  if (spin_.enabled()) ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  pollfd fds[2] = {{transport_->fd(), POLLIN, 0}, {io_.wake_fd(), POLLIN, 0}};
  while (io_.running()) {
    if (busy_poll_) {
      io_step(monotonic_ns(), true);
      continue;
    }
    const std::int64_t now = monotonic_ns();
    std::int64_t wake_at = now + 100'000'000;  // re-check running at least every 100 ms
    wake_at = std::min(wake_at, now + silence_ns_ / 2);  // notice a silent neighbour in time
    wake_at = std::min(wake_at, delay_.next_release_ns());
    if (pairwise_ && hellos_wanted()) wake_at = std::min(wake_at, next_hello_ns_);
    if (pairwise_) wake_at = std::min(wake_at, std::max(next_keepalive_ns_, last_push_ns_ + silence_ns_ / 3));
    if (tx_direct_ && direct_.enabled())  // the bookkeeping of pushes the tick sent itself (it does not wake us)
      wake_at = std::min(wake_at, now + (tx_period_ns_ > 0 ? 2 * tx_period_ns_ : 4'000'000));
    const TxSpinSchedule::Plan plan = spin_.plan(now);
    if (plan.spin) {
      spin_for_push(plan.until_ns);  // without a push, the loop moves on to the next slot
      continue;
    }
    wake_at = std::min(wake_at, plan.wake_ns);
    if (rx_pending()) wake_at = now;  // the rest of a batch already read
    const timespec timeout = to_timespec(std::max<std::int64_t>(0, wake_at - now));
    const int r = ::ppoll(fds, 2, &timeout, nullptr);
    if (r < 0 && errno != EINTR) break;
    if (fds[1].revents & POLLIN) io_.clear_wake();
    io_step(monotonic_ns(), (fds[0].revents & POLLIN) != 0);
  }
  // The pushes' bookkeeping (direct TX), a final snapshot, and the CPU time for stats() after the thread is gone.
  handle_tx(monotonic_ns());
  publish_stats();
  io_.body_stopping();
}

bool Endpoint::spin_for_push(std::int64_t until_ns) {
  tx_spinning_.store(true, std::memory_order_seq_cst);
  bool sent = false;
  std::int64_t now = monotonic_ns();
  while (io_.running_relaxed() && now < until_ns) {
    if (tx_.ready_size() > 0) {
      io_step(now, true, /*caught_spinning=*/true);
      sent = true;
      break;
    }
    handle_rx(now);  // non-blocking: keep receiving while we wait
    delay_.release_due(now, [this](std::uint16_t dest, const std::uint8_t* d, std::size_t len) {
      const int pi = find_peer(dest);
      if (pi >= 0) send_now(dest, d, len, *peers_[static_cast<std::size_t>(pi)]);
    });
    cpu_relax();
    now = monotonic_ns();
  }
  spin_.on_window_end(sent);  // the pusher stopped: stop spinning
  tx_spinning_.store(false, std::memory_order_seq_cst);
  (void)tx_pushed_.load(std::memory_order_seq_cst);  // pairs with push_state()
  // A push that raced with the end of the window skipped its eventfd write: take it now.
  if (!sent && tx_.ready_size() > 0) {
    io_step(monotonic_ns(), false);
    sent = true;
  }
  if (!sent) io_step(monotonic_ns(), false);  // publish what the window received
  return sent;
}

// ------------------------------------------------------------------ receiving

bool Endpoint::admit(int source, std::int64_t now_ns) {
  if (source == kSourceUnchecked) return true;
  const int pi = source >= 0 ? find_peer(static_cast<std::uint16_t>(source)) : -1;
  if (rate_limit_.take(pi, now_ns)) return true;
  decoder_.count_drop(DropReason::rate_limited);
  if (pi >= 0) ++peers_[static_cast<std::size_t>(pi)]->stats.rate_limited;
  return false;
}

DecodeLimits Endpoint::rx_limits(int source, std::int64_t now_ns) const {
  DecodeLimits lim;
  lim.source_station = source;
  lim.max_sequence = ceiling_.ceiling(now_ns);
  if (envelope_.active()) lim.envelope = &envelope_;
  lim.now_ns = now_ns;
  lim.incarnation_quiet_ns = silence_ns_;  // a restart is accepted only after net.peer_silence_s of silence
  return lim;
}

void Endpoint::receive_one(const RxDatagram& d, std::int64_t now_ns) {
  DecodedState st;
  const DecodeLimits lim = rx_limits(d.source, now_ns);
  // A datagram larger than the buffer (one more than the largest legal one) was truncated: the
  // decoder drops it as oversized from its length alone.
  const DecodeStatus ds = decoder_.decode(d.buf, std::min(d.len, d.cap), st, lim);
  if (ds != DecodeStatus::complete && ds != DecodeStatus::fingerprint && ds != DecodeStatus::hello) return;
  const int pi = find_peer(st.sender);
  if (pi < 0) return;  // cannot happen: the decoder knows the same peers
  PeerState& p = *peers_[static_cast<std::size_t>(pi)];
  on_authentic(p, st.incarnation, now_ns);
  if (ds == DecodeStatus::hello) {
    on_hello(p, st);
    return;
  }
  if (ds == DecodeStatus::fingerprint) {
    on_fingerprint(p, st);
    return;
  }
  if (st.value_count != value_count_) {  // a peer with another scene: never hand it to the tick
    ++counters_.wrong_scene_size;
    return;
  }
  p.stats.peer_safe_state = st.safe_state;
  if (st.safe_state) {
    // The neighbour is in its safe state: its echo still measures the round trip, but there is
    // no state to couple to (the tick's edge goes over its bound and acts as a damper).
    ++p.stats.safe_state_packets;
    on_state(p, st, now_ns);
    return;
  }
  on_state(p, st, now_ns);
  deliver(st);
}

void Endpoint::on_authentic(PeerState& p, std::uint64_t incarnation, std::int64_t now_ns) {
  if (p.received.on_incarnation(incarnation)) {
    // A restarted neighbour: its sequence numbers and echoes start afresh, a new process brings
    // a new nonce (agree again), and its new probing fixes a new bound and allowance.
    if (pairwise_) {
      p.keys.forget();
      decoder_.set_peer_keys(p.link.station_id, p.keys.hello_rx_key(), nullptr);
    }
    p.round_trip.restart();
    p.stats.peer_rtt_probe_bound_s = 0.0;
    p.stats.peer_loss_allowance_ticks = -1;
    p.stats.peer_step_max_s = 0.0;
    // The decoder accepted it after net.peer_silence_s of silence: the old one is down (if the
    // periodic check has not said so yet), the new one comes up below.
    p.liveness.check(now_ns, silence_ns_);
  }
  p.liveness.on_receive(now_ns);
}

void Endpoint::on_hello(PeerState& p, const DecodedState& st) {
  if (p.keys.on_hello(st.hello_nonce, st.hello_echo, st.hello_agreed))
    decoder_.set_peer_keys(p.link.station_id, p.keys.hello_rx_key(), &p.keys.rx_traffic());
}

void Endpoint::on_fingerprint(PeerState& p, const DecodedState& st) {
  ++counters_.fingerprints_received;
  p.stats.has_fingerprint = true;
  p.stats.fingerprint = st.fingerprint;
  if (st.round_trip_bound_ns != 0) p.stats.peer_rtt_probe_bound_s = static_cast<double>(st.round_trip_bound_ns) * 1e-9;
  if (st.loss_allowance_ticks >= 0) p.stats.peer_loss_allowance_ticks = st.loss_allowance_ticks;
  if (st.step_max_ns != 0) p.stats.peer_step_max_s = static_cast<double>(st.step_max_ns) * 1e-9;
}

void Endpoint::on_state(PeerState& p, const DecodedState& st, std::int64_t now_ns) {
  p.round_trip.note_received(st.seq, st.send_time_ns, now_ns);
  if (st.has_echo)
    p.round_trip.on_echo(st.echo_seq, st.echo_hold_ns, st.send_time_ns, now_ns, send_records_, echo_floor_ns_.load(std::memory_order_relaxed));
  p.received.on_state(st.seq, st.send_time_ns, now_ns);
  if (st.has_proxy && (!p.stats.has_proxy || st.new_incarnation || st.seq > p.stats.proxy_seq)) {  // the newest one
    p.stats.has_proxy = true;
    p.stats.proxy_seq = st.seq;
    for (std::size_t a = 0; a < 3; ++a) p.stats.proxy_m[a] = st.proxy(a);
  }
}

void Endpoint::deliver(const DecodedState& st) {
  std::uint32_t idx = 0;
  if (!rx_.producer_acquire(idx)) {
    ++counters_.rx_ring_full;
    return;
  }
  double* x = rx_.values(idx);
  st.copy_out(x, x + value_count_);
  const std::int64_t* sent = st.has_echo ? send_records_.send_ns(st.echo_seq) : nullptr;
  rx_.meta(idx) = RxMeta{st.sender,         st.seq,      static_cast<double>(st.send_time_ns) * 1e-9,
                         sent != nullptr,   st.echo_seq, sent ? static_cast<double>(*sent) * 1e-9 : 0.0,
                         monotonic_ns()};
  rx_.producer_publish(idx);
  rx_waiter_.delivered();
}

void Endpoint::handle_rx(std::int64_t now_ns) {
  bool drained = false;  // the last read returned fewer datagrams than it asked for: the socket was empty
  for (int n = 0; n < 4096; ++n) {
    if (n > 0) {
      // A push is waiting: send it first. Under a flood this batch could otherwise hold our own
      // state back for thousands of datagrams (measured: round-trip bounds up by 2-3 ticks and
      // echoes missing at 20,000 junk datagrams/s, tools/flood). The rest of a batch already read
      // waits in rx_batch_ for the next call (rx_pending()).
      if (tx_.ready_size() > 0) return;
      now_ns = io_clock();  // each datagram's own receive time (echo slots, rate buckets)
    }
    // With a push waiting, read one datagram, not a batch: the push leaves after at most one.
    // After a short read, back to ppoll rather than a read that would find nothing (it wakes
    // again at once for what came since).
    if (!rx_pending()) {
      if (drained) return;
      const std::size_t want = tx_.ready_size() > 0 ? 1 : kRxBatch;
      if (!refill_rx(want)) return;
      drained = rx_count_ < want;
    }
    take_datagram(rx_batch_[rx_next_++], now_ns);
  }
}

bool Endpoint::refill_rx(std::size_t n) {
  for (auto& d : rx_batch_) d.source = kSourceUnchecked;
  rx_next_ = rx_count_ = 0;
  const long got = transport_->receive_batch(rx_batch_, n);
  if (got < 0) ++counters_.receive_errors;
  if (got <= 0) return false;
  rx_count_ = static_cast<std::size_t>(got);
  return true;
}

void Endpoint::take_datagram(const RxDatagram& d, std::int64_t now_ns) {
  ++counters_.datagrams_received;
  // Per-source rate limit before any decoding or MAC work (a flood costs recv + this).
  if (!admit(d.source, now_ns)) return;
  if (d.len == 0) {
    decoder_.count_drop(DropReason::zero_length);
    return;
  }
  receive_one(d, now_ns);
}

// ------------------------------------------------------------------ sending

void Endpoint::send_fingerprints(std::int64_t stamp_ns, bool all) {
  if (fingerprint_.scene_nodes == 0) return;
  // The first pushes, then every 25th (20 Hz at a 2 ms tick): a neighbour that starts or
  // restarts later learns it within 50 ms. Pairwise keys: only to a neighbour whose keys are
  // agreed, and at once after an agreement.
  const bool scheduled = all || pushes_sent_ <= 8 || pushes_sent_ % 25 == 0;
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    if (pairwise_ && !p.keys.agreed()) continue;
    if (!p.keys.take_fingerprint_due() && !scheduled) continue;
    const std::size_t len = encoder_.encode_fingerprint(
        p.link.station_id, ++control_seq_, stamp_ns, fingerprint_, tx_buf_.data(), tx_buf_.size(),
        static_cast<std::uint64_t>(std::llround(p.round_trip.estimator().probe_bound_s() * 1e9)),
        pairwise_ ? &p.keys.tx_traffic() : nullptr, p.own_loss_allowance.load(std::memory_order_acquire),
        own_step_max_ns_.load(std::memory_order_acquire));
    if (len) send_now(p.link.station_id, tx_buf_.data(), len, p);
  }
}

void Endpoint::send_keepalive(std::int64_t now_ns) {
  if (!pairwise_ || fingerprint_.scene_nodes == 0) return;
  const std::int64_t every = silence_ns_ / 3;
  if (now_ns - last_push_ns_ < every || now_ns < next_keepalive_ns_) return;
  next_keepalive_ns_ = now_ns + every;
  send_fingerprints(now_ns, true);
}

void Endpoint::send_hellos(std::int64_t stamp_ns) {
  // Every push (and every hello_interval_ns_ without pushes) until the pair has agreed; after
  // that only when a hello of the peer asked for one (it lacks our nonce or our agreement), so
  // at most one hello per peer per push or interval.
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    if (!p.keys.hello_wanted()) continue;
    const PairAgreement::Hello h = p.keys.take_hello();
    const std::size_t len = encoder_.encode_hello(p.link.station_id, ++control_seq_, stamp_ns, p.keys.my_nonce(), *h.echo, h.agreed,
                                                  p.keys.hello_tx_key(), tx_buf_.data(), tx_buf_.size());
    if (len == 0) continue;
    send_now(p.link.station_id, tx_buf_.data(), len, p);
    p.keys.count_hello_sent();
  }
}

void Endpoint::send_wanted_hellos(std::int64_t stamp_ns, std::int64_t now_ns) {
  if (!pairwise_ || !hellos_wanted()) return;
  send_hellos(stamp_ns);
  next_hello_ns_ = now_ns + hello_interval_ns_;
}

bool Endpoint::hellos_wanted() const {
  for (const auto& pp : peers_)
    if (pp->keys.hello_wanted()) return true;
  return false;
}

void Endpoint::send_now(std::uint16_t dest, const std::uint8_t* d, std::size_t len, PeerState& p) {
  if (transport_->send_to(dest, d, len)) {
    ++p.stats.datagrams_sent;
    p.stats.bytes_sent += len;
  } else {
    ++p.stats.send_errors;
  }
}

void Endpoint::handle_tx(std::int64_t now_ns, bool caught_spinning) {
  std::uint32_t idx = 0;
  while (tx_.consumer_pop(idx)) {
    take_push(tx_.meta(idx), tx_.values(idx), now_ns, caught_spinning);
    tx_.consumer_release(idx);
  }
}

void Endpoint::count_push(const TxMeta& m, bool caught_spinning) {
  ++counters_.tx_packets;
  if (caught_spinning) ++counters_.tx_caught_spinning;
  const std::int64_t handed = m.direct.attempted ? m.direct.done_ns : monotonic_ns();  // push -> the kernel
  const double handoff = static_cast<double>(handed - m.push_ns) * 1e-9;
  counters_.tx_handoff_sum_s += handoff;
  counters_.tx_handoff_max_s = std::max(counters_.tx_handoff_max_s, handoff);
  if (m.safe_state) ++counters_.tx_safe_state;
  if (!tx_direct_) return;
  if (!m.direct.attempted) ++counters_.tx_direct_declined;
  else if (m.direct.complete) ++counters_.tx_direct;
  else ++counters_.tx_direct_unfinished;
  if (m.direct.attempted && (m.direct.error == EAGAIN || m.direct.error == EWOULDBLOCK || m.direct.error == ENOBUFS))
    ++counters_.tx_direct_would_block;
}

void Endpoint::take_push(const TxMeta& m, const double* x, std::int64_t now_ns, bool caught_spinning) {
  spin_.on_push(m.push_ns);
  count_push(m, caught_spinning);
  const std::int64_t stamp =
      m.direct.attempted ? m.direct.stamp_ns : (m.send_time_s >= 0.0 ? to_ns(m.send_time_s) : now_ns);
  send_records_.record(m.seq, stamp);
  send_wanted_hellos(stamp, now_ns);
  send_fingerprints(stamp);
  ++pushes_sent_;
  last_push_ns_ = now_ns;
  for (std::size_t i = 0; i < peers_.size(); ++i) send_push_to(*peers_[i], i, m, x, stamp, now_ns);
  // A push the tick left to us (whole or in part) is sent: the tick may send directly again.
  if (!m.direct.complete) tx_io_done_.fetch_add(1, std::memory_order_release);
}

OutgoingState Endpoint::outgoing(const TxMeta& m, const double* x, std::uint16_t dest, std::int64_t stamp_ns) const {
  OutgoingState o;
  o.dest = dest;
  o.seq = m.seq;
  o.send_time_ns = stamp_ns;
  o.value_count = value_count_;
  o.x_hat = x;
  o.v_hat = x + value_count_;
  o.safe_state = m.safe_state;
  o.proxy = m.has_proxy ? m.proxy : nullptr;
  return o;
}

void Endpoint::send_push_to(PeerState& p, std::size_t i, const TxMeta& m, const double* x, std::int64_t stamp_ns,
                            std::int64_t now_ns) {
  OutgoingState o = outgoing(m, x, p.link.station_id, stamp_ns);
  if (m.direct.attempted) {
    finish_direct(p, o, m.direct.peer[i]);
    return;
  }
  if (pairwise_ && !p.keys.agreed()) {  // no state leaves before the pair has agreed
    ++p.stats.tx_without_keys;
    return;
  }
  const EchoSlot* e = p.round_trip.echo_as_of(stamp_ns);
  o.has_echo = e != nullptr;
  o.echo_seq = e ? e->seq : 0;
  o.echo_hold_ns = e ? stamp_ns - e->receive_time_ns : 0;
  send_state(p, o, now_ns);
}

void Endpoint::finish_direct(PeerState& p, OutgoingState o, const DirectPeerSend& d) {
  ++p.stats.packets_sent;
  p.stats.datagrams_sent += d.datagrams_sent;
  p.stats.bytes_sent += d.bytes_sent;
  if (d.datagrams_sent >= frags_per_packet_) return;
  if (pairwise_ && !p.keys.agreed()) {  // the pair's keys were dropped since (a restart): no state leaves
    ++p.stats.tx_without_keys;
    return;
  }
  // The rest with the echo the tick chose, so every fragment of the packet carries the same header.
  o.has_echo = d.has_echo;
  o.echo_seq = d.echo_seq;
  o.echo_hold_ns = d.echo_hold_ns;
  const SessionKey* key = pairwise_ ? &p.keys.tx_traffic() : nullptr;
  for (std::size_t f = d.datagrams_sent; f < frags_per_packet_; ++f) {
    const std::size_t len = encoder_.encode_fragment(o, f, tx_buf_.data(), tx_buf_.size(), key);
    if (len) send_now(o.dest, tx_buf_.data(), len, p);
  }
}

void Endpoint::send_state(PeerState& p, const OutgoingState& o, std::int64_t now_ns) {
  const SessionKey* key = pairwise_ ? &p.keys.tx_traffic() : nullptr;
  ++p.stats.packets_sent;
  PacketFate fate;
  fate.copies = 1;
  if (p.link.impaired) {
    fate = p.impaired.fate(o.seq, static_cast<double>(now_ns) * 1e-9 - epoch_s_);
    if (fate.lost) ++p.stats.impair_lost;
    if (fate.duplicated) ++p.stats.impair_duplicated;
  }
  for (int c = 0; c < fate.copies; ++c) {
    const std::int64_t release = now_ns + static_cast<std::int64_t>(fate.delay_s[c] * 1e9);
    for (std::size_t f = 0; f < frags_per_packet_; ++f) {
      if (release <= now_ns) {
        const std::size_t len = encoder_.encode_fragment(o, f, tx_buf_.data(), tx_buf_.size(), key);
        if (len) send_now(o.dest, tx_buf_.data(), len, p);
        continue;
      }
      std::uint8_t* slot = delay_.slot();
      if (slot == nullptr) {
        ++p.stats.delay_queue_full;
        continue;
      }
      const std::size_t len = encoder_.encode_fragment(o, f, slot, delay_.max_datagram_bytes(), key);
      if (len) delay_.commit(release, o.dest, len);
    }
  }
}

}  // namespace haptic::net
