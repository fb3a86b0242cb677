#include "net/endpoint.hpp"

#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/eventfd.h>
#include <sys/prctl.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <system_error>
#include <thread>

#include "platform/rt_thread.hpp"
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
  if (cfg.delay_queue_datagrams < 16 || cfg.delay_queue_datagrams > (1u << 20))
    throw std::invalid_argument("net.delay_queue_datagrams must be in [16, 1048576]");
  if (cfg.io_priority < 0 || cfg.io_priority > 98)
    throw std::invalid_argument("station.io_priority must be 0 (SCHED_OTHER) or a SCHED_FIFO priority 1..98; got " +
                                std::to_string(cfg.io_priority));
  if (!(cfg.peer_silence_s >= 0.01 && cfg.peer_silence_s <= 60.0))
    throw std::invalid_argument("net.peer_silence_s must be in [0.01, 60] s");
  if (cfg.io_cpu < -1 || cfg.io_cpu >= CPU_SETSIZE)
    throw std::invalid_argument("net.io_cpu must be -1 (unpinned) or a CPU number; got " + std::to_string(cfg.io_cpu));
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
bool heap_later(const auto& a, const auto& b) {
  return a.release_ns != b.release_ns ? a.release_ns > b.release_ns : a.order > b.order;
}
}  // namespace

Endpoint::Endpoint(const EndpointConfig& cfg, std::unique_ptr<Transport> transport)
    : value_count_(checked(cfg, transport.get()).value_count),
      transport_(std::move(transport)),
      encoder_(with_incarnation(cfg.wire)),
      decoder_(cfg.wire, peer_ids(cfg), cfg.value_count),
      frags_per_packet_(encoder_.fragment_count(cfg.value_count)),
      epoch_s_(cfg.impairment_epoch_s),
      busy_poll_(cfg.io_busy_poll),
      tx_spin_(cfg.tx_spin),
      io_cpu_(cfg.io_cpu),
      tx_period_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_period_s * 1e9))),
      tx_lead_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_spin_lead_s * 1e9))),
      tx_tail_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_spin_tail_s * 1e9))),
      io_priority_(cfg.io_priority),
      incarnation_(encoder_.config().incarnation),
      fingerprint_(cfg.fingerprint),
      silence_ns_(static_cast<std::int64_t>(std::llround(cfg.peer_silence_s * 1e9))),
      max_sequence_ahead_(cfg.max_sequence_ahead_ticks),
      envelope_{cfg.envelope_max_offset_m > 0.0 ? cfg.envelope_rest_x : std::vector<double>{}, cfg.envelope_max_offset_m,
                cfg.envelope_max_speed_m_per_s},
      pairwise_(cfg.pairwise_keys) {
  if (frags_per_packet_ == 0)
    throw std::invalid_argument("net: scene too large for " + std::to_string(kMaxFragments) +
                                " fragments of net.max_datagram_bytes = " + std::to_string(cfg.wire.max_datagram_bytes));
  // 20x the expected datagram rate per source (one packet per tick, plus fingerprints), or as configured.
  const double packets_per_s = cfg.tx_period_s > 0.0 ? 1.0 / cfg.tx_period_s : 500.0;
  rx_rate_per_s_ = cfg.rx_rate_limit_per_s > 0.0 ? cfg.rx_rate_limit_per_s
                                                 : 20.0 * packets_per_s * static_cast<double>(frags_per_packet_ + 1);
  rx_burst_ = std::max(16.0, 0.1 * rx_rate_per_s_);
  sequence_epoch_ns_ = cfg.sequence_epoch_ns;
  for (const auto& l : cfg.peers) {
    auto p = std::make_unique<PeerState>();
    p->link = l;
    if (l.impaired) p->impaired = SendImpairment(l.impairment, l.seed, cfg.impairment_first_run_seq);
    p->rtt = RttEstimator(cfg.rtt);
    p->stats.station_id = l.station_id;
    if (pairwise_) {
      p->pair = pair_keys(cfg.own_keys, cfg.wire.station_id, l.public_key, l.station_id);
      decoder_.set_peer_keys(l.station_id, p->pair.rx, nullptr);  // hellos only, until agreed
    }
    p->box.writer_publish(p->stats);
    peers_.push_back(std::move(p));
  }
  if (pairwise_) my_nonce_ = new_run_nonce();
  if (tx_period_ns_ > 0) hello_interval_ns_ = tx_period_ns_;
  send_records_.resize(kSendRecords);
  rx_meta_.resize(kRxBuffers);
  rx_store_.resize(kRxBuffers * 2 * value_count_);
  tx_meta_.resize(kTxBuffers);
  tx_store_.resize(kTxBuffers * 2 * value_count_);
  for (std::uint32_t i = 0; i < kRxBuffers; ++i) rx_free_.writer_try_push(i);
  for (std::uint32_t i = 0; i < kTxBuffers; ++i) tx_free_.writer_try_push(i);
  max_datagram_ = cfg.wire.max_datagram_bytes;
  rx_buf_.resize(kMaxDatagramBytes + 1);
  tx_buf_.resize(max_datagram_);
  delay_store_.resize(cfg.delay_queue_datagrams * max_datagram_);
  delay_heap_.reserve(cfg.delay_queue_datagrams);
  delay_free_.reserve(cfg.delay_queue_datagrams);
  for (std::size_t i = cfg.delay_queue_datagrams; i-- > 0;) delay_free_.push_back(static_cast<std::uint32_t>(i));
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_fd_ < 0) throw std::system_error(errno, std::generic_category(), "net: eventfd");
  rx_wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (rx_wake_fd_ < 0) throw std::system_error(errno, std::generic_category(), "net: eventfd");
}

bool Endpoint::wait_rx(double timeout_s) {
  // Register first, then look: a delivery either is seen here or writes the eventfd (the I/O
  // thread writes it only while someone waits, so the RT-polled path pays no syscall).
  rx_waiters_.fetch_add(1, std::memory_order_seq_cst);
  (void)rx_delivered_.load(std::memory_order_seq_cst);  // pairs with handle_rx (see there)
  if (rx_ready_.size() > 0) {
    rx_waiters_.fetch_sub(1, std::memory_order_relaxed);
    return true;
  }
  pollfd p{rx_wake_fd_, POLLIN, 0};
  const timespec t = to_timespec(static_cast<std::int64_t>(std::max(0.0, timeout_s) * 1e9));
  if (::ppoll(&p, 1, &t, nullptr) > 0) {
    std::uint64_t v;
    [[maybe_unused]] auto r = ::read(rx_wake_fd_, &v, sizeof v);
  }
  rx_waiters_.fetch_sub(1, std::memory_order_relaxed);
  return rx_ready_.size() > 0;
}

Endpoint::~Endpoint() {
  stop();
  if (wake_fd_ >= 0) ::close(wake_fd_);
  if (rx_wake_fd_ >= 0) ::close(rx_wake_fd_);
}

void Endpoint::start() {
  if (running_.load(std::memory_order_acquire)) return;
  if (epoch_s_ < 0.0) epoch_s_ = monotonic_s();
  running_.store(true, std::memory_order_release);
  platform::RtConfig rc;
  rc.sched_fifo = io_priority_ > 0;
  rc.priority = io_priority_ > 0 ? io_priority_ : 1;
  rc.cpu = io_cpu_;
  rc.lock_memory = false;  // the station's RT thread locks the process's memory
  rc.isolate_cpu = false;
  rc.prefault_stack_bytes = 0;
  rc.prefault_heap_bytes = 0;
  try {
    thread_ = std::make_unique<platform::RtThread>(rc, [this](const platform::RtReport&) { run(); });
  } catch (const std::invalid_argument& e) {
    running_.store(false, std::memory_order_release);
    throw std::invalid_argument(std::string("net.io_cpu = ") + std::to_string(io_cpu_) + ": " + e.what());
  } catch (...) {
    running_.store(false, std::memory_order_release);
    throw;
  }
  io_warnings_.clear();
  bool fifo = io_priority_ > 0;
  for (const auto& w : thread_->setup_warnings()) {
    if (w.find("PREEMPT_RT") != std::string::npos) continue;  // the station's RT thread reports the kernel
    if (w.find("SCHED_FIFO") != std::string::npos) fifo = false;
    if (w.find("pinning to cpu") != std::string::npos) {
      stop();
      throw std::runtime_error("net.io_cpu = " + std::to_string(io_cpu_) + ": cannot pin the I/O thread (" + w + ")");
    }
    io_warnings_.push_back("I/O thread: " + w);
  }
  io_sched_ = fifo ? "SCHED_FIFO " + std::to_string(io_priority_) : std::string("SCHED_OTHER");
}

double Endpoint::io_thread_cpu_s() const {
  const std::int64_t id = io_clock_.load(std::memory_order_acquire);
  if (!thread_ || id < 0) return static_cast<double>(io_cpu_at_stop_ns_.load(std::memory_order_relaxed)) * 1e-9;
  return static_cast<double>(platform::clock_ns(static_cast<clockid_t>(id))) * 1e-9;
}

void Endpoint::stop() {
  if (!thread_) return;
  running_.store(false, std::memory_order_release);
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(wake_fd_, &one, sizeof one);
  thread_->join();
  thread_.reset();
}

int Endpoint::find_peer(std::uint16_t id) const {
  for (std::size_t i = 0; i < peers_.size(); ++i)
    if (peers_[i]->link.station_id == id) return static_cast<int>(i);
  return -1;
}

bool Endpoint::push_state(std::uint64_t seq, double send_time_s, const double* x_hat, const double* v_hat, bool safe_state) {
  std::uint32_t idx = 0;
  if (!tx_free_.reader_try_pop(idx)) {
    tx_overruns_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  double* dst = tx_store_.data() + std::size_t{idx} * 2 * value_count_;
  std::memcpy(dst, x_hat, sizeof(double) * value_count_);
  std::memcpy(dst + value_count_, v_hat, sizeof(double) * value_count_);
  // Never transmit a non-finite state: send the safe-state flag (and zeros) instead.
  for (std::size_t i = 0; i < 2 * std::size_t{value_count_} && !safe_state; ++i) safe_state = !std::isfinite(dst[i]);
  tx_meta_[idx] = TxMeta{seq, send_time_s, monotonic_ns(), safe_state};  // vDSO clock read, no syscall
  tx_ready_.writer_try_push(idx);  // cannot fail: as many slots as buffers
  // Dekker pair with spin_for_push() (seq_cst, no fences): if we see the I/O thread spinning,
  // its end-of-window check sees this push; otherwise we wake it.
  tx_pushed_.fetch_add(1, std::memory_order_seq_cst);
  if (tx_spinning_.load(std::memory_order_seq_cst)) return true;  // the spin sees it
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(wake_fd_, &one, sizeof one);  // EFD_NONBLOCK: never blocks
  return true;
}

std::uint32_t Endpoint::rtt_bound_ticks(std::size_t i, double period_s) const {
  if (i >= peers_.size()) return 0;
  return bound_ticks(static_cast<double>(peers_[i]->bound_ns.load(std::memory_order_acquire)) * 1e-9, period_s);
}

std::uint64_t Endpoint::rtt_bound_generation(std::size_t i) const {
  return i < peers_.size() ? peers_[i]->bound_generation.load(std::memory_order_acquire) : 0;
}

void Endpoint::publish_bound(PeerState& p) {
  p.bound_ns.store(static_cast<std::uint64_t>(p.rtt.bound_s() * 1e9), std::memory_order_relaxed);
  p.bound_generation.store(p.rtt.generation(), std::memory_order_release);
}

bool Endpoint::probe_command(int command) {
  if (!thread_ || !running_.load(std::memory_order_acquire)) {
    // No I/O thread: nothing runs concurrently, apply here.
    probe_command_.store(command, std::memory_order_relaxed);
    apply_probe_command();
    return probe_all_bound_.load(std::memory_order_relaxed);
  }
  probe_command_.store(command, std::memory_order_relaxed);
  const std::uint64_t req = probe_request_.fetch_add(1, std::memory_order_acq_rel) + 1;
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(wake_fd_, &one, sizeof one);
  // Bounded wait: the I/O thread looks at the request at least every 100 ms.
  for (int i = 0; i < 2000 && probe_done_.load(std::memory_order_acquire) < req; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return probe_done_.load(std::memory_order_acquire) >= req && probe_all_bound_.load(std::memory_order_acquire);
}

void Endpoint::apply_probe_command() {
  const int c = probe_command_.exchange(kProbeNone, std::memory_order_relaxed);
  if (c == kProbeBegin) {
    for (auto& p : peers_) p->rtt.begin_probing();
  } else if (c == kProbeFinish) {
    bool all = true;
    for (auto& p : peers_) {
      if (!p->rtt.probing() && p->rtt.has_bound()) continue;
      if (p->rtt.finish_probing()) publish_bound(*p);
      else all = false;
    }
    probe_all_bound_.store(all, std::memory_order_release);
  }
  publish_stats();
}

void Endpoint::begin_probing() { probe_command(kProbeBegin); }

bool Endpoint::finish_probing() { return probe_command(kProbeFinish); }

void Endpoint::set_loss_allowance(std::size_t peer_index, int ticks) {
  peers_.at(peer_index)->own_loss_allowance.store(ticks, std::memory_order_release);
}

void Endpoint::publish_stats() {
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    PeerStats& ps = p.stats;
    ps.rtt_samples = p.rtt.samples();
    ps.rtt_last_s = p.rtt.last_s();
    ps.rtt_mean_s = p.rtt.mean_s();
    ps.rtt_min_s = p.rtt.min_s();
    ps.rtt_max_s = p.rtt.max_s();
    ps.rtt_bound_s = p.rtt.bound_s();
    ps.rtt_probe_bound_s = p.rtt.probe_bound_s();
    ps.rtt_probing = p.rtt.probing();
    ps.rtt_has_bound = p.rtt.has_bound();
    ps.rtt_over_bound_events = p.rtt.over_bound_events();
    ps.rtt_bound_generation = p.rtt.generation();
    ps.loss_fraction = 0.0;
    if (ps.packets_received_incarnation > 0) {
      const double span = static_cast<double>(ps.newest_seq - ps.lowest_seq + 1);
      ps.loss_fraction = std::max(0.0, 1.0 - static_cast<double>(ps.packets_received_incarnation) / span);
    }
    p.box.writer_publish(ps);
  }
  counters_.drops = decoder_.drops();
  counters_box_.writer_publish(counters_);
}

EndpointStats Endpoint::stats() const {
  EndpointStats s;
  static_cast<EndpointCounters&>(s) = counters_box_.reader_snapshot();
  s.incarnation = incarnation_;
  s.tx_overruns = tx_overruns_.load(std::memory_order_relaxed);
  s.io_thread_cpu_s = io_thread_cpu_s();
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
  if (rx) handle_rx(now_ns);
  handle_tx(now_ns, caught_spinning);
  if (now_ns >= next_hello_ns_) send_wanted_hellos(pushes_sent_, now_ns, now_ns);
  release_due(monotonic_ns());
  check_silence(monotonic_ns());
  publish_stats();
}

void Endpoint::check_silence(std::int64_t now_ns) {
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    if (p.stats.up && now_ns - p.last_receive_ns > silence_ns_) {
      p.stats.up = false;
      ++p.stats.down_events;
      p.stats.last_change_s = p.stats.last_down_s = static_cast<double>(now_ns) * 1e-9;
    }
  }
}

void Endpoint::run() {
  {
    clockid_t cid{};
    if (pthread_getcpuclockid(pthread_self(), &cid) == 0) io_clock_.store(static_cast<std::int64_t>(cid), std::memory_order_release);
  }
  // The ppoll timeouts below schedule the TX spin window: a SCHED_OTHER thread's default
  // 50 us timer slack would make it late, so ask for none (per thread; harmless otherwise).
  if (tx_spin_) ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  pollfd fds[2] = {{transport_->fd(), POLLIN, 0}, {wake_fd_, POLLIN, 0}};
  while (running_.load(std::memory_order_acquire)) {
    if (busy_poll_) {
      io_step(monotonic_ns(), true);
      continue;
    }
    std::int64_t now = monotonic_ns();
    std::int64_t wake_at = now + 100'000'000;  // re-check running_ at least every 100 ms
    wake_at = std::min(wake_at, now + silence_ns_ / 2);  // notice a silent neighbour in time
    if (!delay_heap_.empty()) wake_at = std::min(wake_at, delay_heap_.front().release_ns);
    if (pairwise_ && hellos_wanted()) wake_at = std::min(wake_at, next_hello_ns_);
    if (tx_spin_ && last_push_ns_ >= 0 && missed_windows_ < kMaxMissedWindows) {
      // The next push is due one period after the previous one (the previous push's stamp,
      // not our wake-up, so a late wake-up does not shift the window).
      std::int64_t due = last_push_ns_ + tx_period_ns_;
      while (due + tx_tail_ns_ < now) due += tx_period_ns_;  // missed pushes: next slot
      const std::int64_t open = due - tx_lead_ns_;
      if (now >= open - wake_late_ns_) {
        // Our own timer wake-up is late by tens of us on some machines: learn by how much
        // (the largest lateness of the last 64 windows) and go to sleep that much earlier.
        const std::int64_t late = std::max<std::int64_t>(0, now - (open - wake_late_ns_));
        window_late_max_ = std::max(window_late_max_, late);
        const std::uint64_t w = ++counters_.tx_spin_windows;
        if (w % 64 == 0) {
          wake_late_ns_ = std::min<std::int64_t>(window_late_max_, tx_period_ns_ / 4);
          window_late_max_ = 0;
        }
        spin_for_push(due + tx_tail_ns_);  // without a push, the loop moves on to the next slot
        continue;
      }
      wake_at = std::min(wake_at, open - wake_late_ns_);
    }
    const timespec timeout = to_timespec(std::max<std::int64_t>(0, wake_at - now));
    const int r = ::ppoll(fds, 2, &timeout, nullptr);
    if (r < 0 && errno != EINTR) break;
    if (fds[1].revents & POLLIN) {
      std::uint64_t v;
      [[maybe_unused]] auto rr = ::read(wake_fd_, &v, sizeof v);
    }
    io_step(monotonic_ns(), (fds[0].revents & POLLIN) != 0);
  }
  // Final snapshot, and the CPU time for stats() after the thread is gone.
  publish_stats();
  clockid_t cid{};
  if (pthread_getcpuclockid(pthread_self(), &cid) == 0)
    io_cpu_at_stop_ns_.store(static_cast<std::uint64_t>(platform::clock_ns(cid)), std::memory_order_relaxed);
  io_clock_.store(-1, std::memory_order_release);
}

bool Endpoint::spin_for_push(std::int64_t until_ns) {
  tx_spinning_.store(true, std::memory_order_seq_cst);
  bool sent = false;
  std::int64_t now = monotonic_ns();
  while (running_.load(std::memory_order_relaxed) && now < until_ns) {
    if (tx_ready_.size() > 0) {
      io_step(now, true, /*caught_spinning=*/true);
      sent = true;
      break;
    }
    handle_rx(now);  // non-blocking: keep receiving while we wait
    release_due(now);
    cpu_relax();
    now = monotonic_ns();
  }
  missed_windows_ = sent ? 0 : missed_windows_ + 1;  // the pusher stopped: stop spinning
  tx_spinning_.store(false, std::memory_order_seq_cst);
  (void)tx_pushed_.load(std::memory_order_seq_cst);  // pairs with push_state()
  // A push that raced with the end of the window skipped its eventfd write: take it now.
  if (!sent && tx_ready_.size() > 0) {
    io_step(monotonic_ns(), false);
    sent = true;
  }
  if (!sent) io_step(monotonic_ns(), false);  // publish what the window received
  return sent;
}

void Endpoint::on_incarnation(PeerState& p, std::uint64_t incarnation) {
  if (p.has_incarnation && incarnation == p.stats.incarnation) return;
  if (p.has_incarnation) {
    if (pairwise_) forget_keys(p);  // a new process, a new nonce: agree again
    // A restarted neighbour: its sequence numbers and echoes start afresh.
    ++p.stats.incarnation_changes;
    p.echo = {};
    p.previous_echo = {};
    p.stats.packets_received_incarnation = 0;
    p.offset_window_n = 0;
    p.stats.peer_rtt_probe_bound_s = 0.0;  // its new probing fixes a new bound (and allowance)
    p.stats.peer_loss_allowance_ticks = -1;
  }
  p.has_incarnation = true;
  p.stats.incarnation = incarnation;
}

void Endpoint::on_state(PeerState& p, const DecodedState& st, std::int64_t now_ns) {
  // Echo bookkeeping: remember the newest packet of this peer to echo it back.
  if (!p.echo.valid || st.seq > p.echo.seq) {
    p.previous_echo = p.echo;
    p.echo = PeerState::EchoSlot{true, st.seq, st.send_time_ns, now_ns};
  }
  // Round trip from OUR send record of the echoed sequence, first time we see this echo.
  if (st.has_echo && (!p.sampled_any || st.echo_seq > p.last_sampled_echo)) {
    const SendRecord* rec = send_record(st.echo_seq);
    if (rec == nullptr) {
      ++p.stats.echoes_unmatched;
    } else {
      p.sampled_any = true;
      p.last_sampled_echo = st.echo_seq;
      const bool over = p.rtt.add_sample(static_cast<double>(now_ns - rec->send_ns) * 1e-9);
      if (over) publish_bound(p);
      // Clock offset, NTP-style: t1 our send, t2 = t3 - hold their receipt, t3 their send, t4 now.
      const double t1 = static_cast<double>(rec->send_ns) * 1e-9, t4 = static_cast<double>(now_ns) * 1e-9;
      const double t3 = static_cast<double>(st.send_time_ns) * 1e-9;
      const double hold = static_cast<double>(std::max<std::int64_t>(0, st.echo_hold_ns)) * 1e-9;
      const double t2 = t3 - hold;
      const double offset = ((t2 - t1) + (t3 - t4)) / 2.0;
      const double path = (t4 - t1) - hold;  // the offset's error is at most path / 2
      if (p.offset_window_n == 0 || path < p.offset_window_best_rtt) {
        p.offset_window_best_rtt = path;
        p.offset_window_best = offset;
      }
      ++p.stats.clock_offset_samples;
      // The first window publishes as it goes; later ones when complete (min-RTT filter).
      if (p.stats.clock_offset_samples <= 128 || ++p.offset_window_n >= 128) {
        p.stats.clock_offset_s = p.offset_window_best;
        p.stats.clock_offset_rtt_s = p.offset_window_best_rtt;
      }
      if (p.stats.clock_offset_samples <= 128) ++p.offset_window_n;
      if (p.offset_window_n >= 128) p.offset_window_n = 0;
    }
  }
  PeerStats& ps = p.stats;
  if (ps.packets_received_incarnation == 0) ps.lowest_seq = ps.newest_seq = st.seq;
  ps.lowest_seq = std::min(ps.lowest_seq, st.seq);
  if (st.seq >= ps.newest_seq) {
    ps.newest_seq = st.seq;
    ps.newest_send_time_s = static_cast<double>(st.send_time_ns) * 1e-9;
  }
  ++ps.packets_received;
  ++ps.packets_received_incarnation;
  const double one_way = static_cast<double>(now_ns - st.send_time_ns) * 1e-9;
  ps.one_way_mean_s += (one_way - ps.one_way_mean_s) / static_cast<double>(ps.packets_received);
  ps.one_way_max_s = std::max(ps.one_way_max_s, one_way);
}

bool Endpoint::RateBucket::take(std::int64_t now_ns, double rate_per_s, double burst) {
  if (last_ns < 0) tokens = burst;
  else tokens = std::min(burst, tokens + static_cast<double>(now_ns - last_ns) * 1e-9 * rate_per_s);
  last_ns = now_ns;
  if (tokens < 1.0) return false;
  tokens -= 1.0;
  return true;
}

bool Endpoint::admit(int source, std::int64_t now_ns) {
  if (source == kSourceUnchecked) return true;
  const int pi = source >= 0 ? find_peer(static_cast<std::uint16_t>(source)) : -1;
  RateBucket& b = pi >= 0 ? peers_[static_cast<std::size_t>(pi)]->bucket : unknown_bucket_;
  if (b.take(now_ns, rx_rate_per_s_, rx_burst_)) return true;
  decoder_.count_drop(DropReason::rate_limited);
  if (pi >= 0) ++peers_[static_cast<std::size_t>(pi)]->stats.rate_limited;
  return false;
}

DecodeLimits Endpoint::rx_limits(int source, std::int64_t now_ns) const {
  DecodeLimits lim;
  lim.source_station = source;
  std::int64_t own = own_tick_.load(std::memory_order_relaxed);
  if (own < 0 && sequence_epoch_ns_ >= 0 && tx_period_ns_ > 0)  // a common epoch: the session's tick by the clock
    own = std::max<std::int64_t>(0, (now_ns - sequence_epoch_ns_) / tx_period_ns_);
  if (own >= 0) lim.max_sequence = static_cast<std::uint64_t>(own) + max_sequence_ahead_;
  if (envelope_.active()) lim.envelope = &envelope_;
  return lim;
}

void Endpoint::receive_one(std::size_t n, int source, std::int64_t now_ns) {
  DecodedState st;
  const DecodeLimits lim = rx_limits(source, now_ns);
  const std::size_t len = std::min<std::size_t>(n, rx_buf_.size());
  if (n > rx_buf_.size()) {
    // Larger than any legal datagram: the decoder drops it as oversized from its length.
    decoder_.decode(rx_buf_.data(), n > max_datagram_ ? max_datagram_ + 1 : len, st, lim);
    return;
  }
  const DecodeStatus ds = decoder_.decode(rx_buf_.data(), len, st, lim);
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
  on_incarnation(p, incarnation);
  p.last_receive_ns = now_ns;
  p.stats.last_receive_s = static_cast<double>(now_ns) * 1e-9;
  if (!p.stats.up) {
    p.stats.up = true;
    ++p.stats.up_events;
    p.stats.last_change_s = p.stats.last_up_s = static_cast<double>(now_ns) * 1e-9;
  }
}

void Endpoint::on_fingerprint(PeerState& p, const DecodedState& st) {
  ++counters_.fingerprints_received;
  p.stats.has_fingerprint = true;
  p.stats.fingerprint = st.fingerprint;
  if (st.round_trip_bound_ns != 0) p.stats.peer_rtt_probe_bound_s = static_cast<double>(st.round_trip_bound_ns) * 1e-9;
  if (st.loss_allowance_ticks >= 0) p.stats.peer_loss_allowance_ticks = st.loss_allowance_ticks;
}

void Endpoint::deliver(const DecodedState& st) {
  std::uint32_t idx = 0;
  if (!rx_free_.reader_try_pop(idx)) {
    ++counters_.rx_ring_full;
    return;
  }
  double* x = rx_store_.data() + std::size_t{idx} * 2 * value_count_;
  st.copy_out(x, x + value_count_);
  const SendRecord* rec = st.has_echo ? send_record(st.echo_seq) : nullptr;
  rx_meta_[idx] = RxMeta{st.sender,      st.seq,      static_cast<double>(st.send_time_ns) * 1e-9,
                         rec != nullptr, st.echo_seq, rec ? static_cast<double>(rec->send_ns) * 1e-9 : 0.0,
                         monotonic_ns()};
  rx_ready_.writer_try_push(idx);
  // Dekker pair with wait_rx(), seq_cst on both sides (no fences: ThreadSanitizer checks
  // this code): either the waiter's ring check sees this packet or we see the waiter.
  rx_delivered_.fetch_add(1, std::memory_order_seq_cst);
  if (rx_waiters_.load(std::memory_order_seq_cst) > 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] auto r = ::write(rx_wake_fd_, &one, sizeof one);
  }
}

void Endpoint::handle_rx(std::int64_t now_ns) {
  for (int budget = 0; budget < 4096; ++budget) {
    if (budget > 0) {
      // A push is waiting: send it first. Under a flood this batch could otherwise hold our own
      // state back for thousands of datagrams (measured: round-trip bounds up by 2-3 ticks and
      // echoes missing at 20,000 junk datagrams/s, tools/flood).
      if (tx_ready_.size() > 0) return;
      now_ns = monotonic_ns();  // each datagram's own receive time (echo slots, rate buckets)
    }
    int source = kSourceUnchecked;
    const long n = transport_->receive_from(rx_buf_.data(), rx_buf_.size(), source);
    if (n == Transport::kNoDatagram) return;
    if (n < 0) {
      ++counters_.receive_errors;
      return;
    }
    ++counters_.datagrams_received;
    // Per-source rate limit before any decoding or MAC work (a flood costs recv + this).
    if (!admit(source, now_ns)) continue;
    if (n == 0) {
      decoder_.count_drop(DropReason::zero_length);
      continue;
    }
    receive_one(static_cast<std::size_t>(n), source, now_ns);
  }
}

void Endpoint::send_fingerprints(std::uint64_t seq, std::int64_t stamp_ns) {
  if (fingerprint_.scene_nodes == 0) return;
  // The first pushes, then every 25th (20 Hz at a 2 ms tick): a neighbour that starts or
  // restarts later learns it within 50 ms. Pairwise keys: only to a neighbour whose keys are
  // agreed, and at once after an agreement.
  const bool scheduled = pushes_sent_ <= 8 || pushes_sent_ % 25 == 0;
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    if (pairwise_ && !p.stats.keys_agreed) continue;
    if (!scheduled && !p.fingerprint_due) continue;
    p.fingerprint_due = false;
    const std::size_t len =
        encoder_.encode_fingerprint(p.link.station_id, seq, stamp_ns, fingerprint_, tx_buf_.data(), tx_buf_.size(),
                                    static_cast<std::uint64_t>(std::llround(p.rtt.probe_bound_s() * 1e9)),
                                    pairwise_ ? &p.tx_traffic : nullptr, p.own_loss_allowance.load(std::memory_order_acquire));
    if (len) send_now(p.link.station_id, tx_buf_.data(), len, p);
  }
}

void Endpoint::send_hellos(std::uint64_t seq, std::int64_t stamp_ns) {
  // Every push (and every hello_interval_ns_ without pushes) until the pair has agreed; after
  // that only when a hello of the peer asked for one (it lacks our nonce or our agreement), so
  // at most one hello per peer per push or interval.
  for (auto& pp : peers_) {
    PeerState& p = *pp;
    if (p.stats.keys_agreed && !p.hello_due) continue;
    p.hello_due = false;
    const bool agreed = p.stats.keys_agreed && p.agreed_nonce == p.seen_nonce;
    const std::size_t len = encoder_.encode_hello(p.link.station_id, seq, stamp_ns, my_nonce_, p.seen_nonce, agreed,
                                                  p.pair.tx, tx_buf_.data(), tx_buf_.size());
    if (len == 0) continue;
    send_now(p.link.station_id, tx_buf_.data(), len, p);
    ++p.stats.hellos_sent;
  }
}

void Endpoint::send_wanted_hellos(std::uint64_t seq, std::int64_t stamp_ns, std::int64_t now_ns) {
  if (!pairwise_ || !hellos_wanted()) return;
  send_hellos(seq, stamp_ns);
  next_hello_ns_ = now_ns + hello_interval_ns_;
}

bool Endpoint::hellos_wanted() const {
  for (const auto& pp : peers_)
    if (!pp->stats.keys_agreed || pp->hello_due) return true;
  return false;
}

void Endpoint::on_hello(PeerState& p, const DecodedState& st) {
  ++p.stats.hellos_received;
  if (st.hello_nonce != p.seen_nonce) {
    p.seen_nonce = st.hello_nonce;  // a nonce we have not echoed yet: echo it with our next push
    p.hello_due = true;
  }
  // The peer's nonce is adopted only from a hello that echoes OUR nonce of this run: the peer
  // made it after it saw ours, so it is of this run (a hello recorded in another run echoes
  // another nonce, and our nonce is fresh random per Endpoint).
  if (st.hello_echo == my_nonce_ && !(p.stats.keys_agreed && p.agreed_nonce == st.hello_nonce)) {
    p.agreed_nonce = st.hello_nonce;
    p.tx_traffic = traffic_key(p.pair.tx, my_nonce_, p.agreed_nonce);
    p.rx_traffic = traffic_key(p.pair.rx, p.agreed_nonce, my_nonce_);
    decoder_.set_peer_keys(p.link.station_id, p.pair.rx, &p.rx_traffic);
    p.stats.keys_agreed = true;
    ++p.stats.key_agreements;
    p.fingerprint_due = true;
  }
  // The peer lacks our nonce, or has not adopted it yet: it needs a hello from us.
  if (st.hello_echo != my_nonce_ || !st.hello_agreed) p.hello_due = true;
}

void Endpoint::forget_keys(PeerState& p) {
  p.stats.keys_agreed = false;
  p.seen_nonce = RunNonce{};
  p.agreed_nonce = RunNonce{};
  decoder_.set_peer_keys(p.link.station_id, p.pair.rx, nullptr);
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
  while (tx_ready_.reader_try_pop(idx)) {
    const TxMeta m = tx_meta_[idx];
    const double* x = tx_store_.data() + std::size_t{idx} * 2 * value_count_;
    last_push_ns_ = std::max(last_push_ns_, m.push_ns);
    missed_windows_ = 0;
    ++counters_.tx_packets;
    if (caught_spinning) ++counters_.tx_caught_spinning;
    const double handoff = static_cast<double>(monotonic_ns() - m.push_ns) * 1e-9;
    counters_.tx_handoff_sum_s += handoff;
    counters_.tx_handoff_max_s = std::max(counters_.tx_handoff_max_s, handoff);
    const std::int64_t stamp = m.send_time_s >= 0.0 ? static_cast<std::int64_t>(std::llround(m.send_time_s * 1e9))
                                                     : now_ns;
    send_records_[m.seq % kSendRecords] = SendRecord{true, m.seq, stamp};
    if (m.safe_state) ++counters_.tx_safe_state;
    send_wanted_hellos(m.seq, stamp, now_ns);
    send_fingerprints(m.seq, stamp);
    ++pushes_sent_;
    for (auto& pp : peers_) {
      PeerState& p = *pp;
      if (pairwise_ && !p.stats.keys_agreed) {  // no state leaves before the pair has agreed
        ++p.stats.tx_without_keys;
        continue;
      }
      const SessionKey* key = pairwise_ ? &p.tx_traffic : nullptr;
      OutgoingState o;
      o.dest = p.link.station_id;
      o.seq = m.seq;
      o.send_time_ns = stamp;
      const PeerState::EchoSlot* e = p.echo_as_of(stamp);
      o.has_echo = e != nullptr;
      o.echo_seq = e ? e->seq : 0;
      o.echo_hold_ns = e ? stamp - e->receive_time_ns : 0;
      o.value_count = value_count_;
      o.x_hat = x;
      o.v_hat = x + value_count_;
      o.safe_state = m.safe_state;
      ++p.stats.packets_sent;
      PacketFate fate;
      fate.copies = 1;
      if (p.link.impaired) {
        fate = p.impaired.fate(m.seq, static_cast<double>(now_ns) * 1e-9 - epoch_s_);
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
          if (delay_free_.empty()) {
            ++p.stats.delay_queue_full;
            continue;
          }
          const std::uint32_t slot = delay_free_.back();
          const std::size_t len =
              encoder_.encode_fragment(o, f, delay_store_.data() + std::size_t{slot} * max_datagram_, max_datagram_, key);
          if (len == 0) continue;
          delay_free_.pop_back();
          delay_heap_.push_back(Delayed{release, delay_order_++, o.dest, static_cast<std::uint32_t>(len), slot});
          std::push_heap(delay_heap_.begin(), delay_heap_.end(), [](const Delayed& a, const Delayed& b) {
            return heap_later(a, b);
          });
        }
      }
    }
    tx_free_.writer_try_push(idx);
  }
}

void Endpoint::release_due(std::int64_t now_ns) {
  auto later = [](const Delayed& a, const Delayed& b) { return heap_later(a, b); };
  while (!delay_heap_.empty() && delay_heap_.front().release_ns <= now_ns) {
    std::pop_heap(delay_heap_.begin(), delay_heap_.end(), later);
    const Delayed d = delay_heap_.back();
    delay_heap_.pop_back();
    const int pi = find_peer(d.dest);
    if (pi >= 0)
      send_now(d.dest, delay_store_.data() + std::size_t{d.slot} * max_datagram_, d.len,
               *peers_[static_cast<std::size_t>(pi)]);
    delay_free_.push_back(d.slot);
  }
}

}  // namespace haptic::net
