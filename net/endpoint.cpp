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
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace haptic::net {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}
double monotonic_s() { return static_cast<double>(monotonic_ns()) * 1e-9; }

namespace {
timespec to_timespec(std::int64_t ns) {
  return timespec{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}
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
  if (cfg.wire.max_datagram_bytes > t->max_datagram_bytes())
    throw std::invalid_argument("net.max_datagram_bytes = " + std::to_string(cfg.wire.max_datagram_bytes) +
                                " exceeds what transport " + t->name() + " carries (" +
                                std::to_string(t->max_datagram_bytes()) + ")");
  return cfg;
}
bool heap_later(const auto& a, const auto& b) {
  return a.release_ns != b.release_ns ? a.release_ns > b.release_ns : a.order > b.order;
}
}  // namespace

Endpoint::Endpoint(const EndpointConfig& cfg, std::unique_ptr<Transport> transport)
    : value_count_(checked(cfg, transport.get()).value_count),
      transport_(std::move(transport)),
      encoder_(cfg.wire),
      decoder_(cfg.wire, peer_ids(cfg), cfg.value_count),
      frags_per_packet_(encoder_.fragment_count(cfg.value_count)),
      epoch_s_(cfg.impairment_epoch_s),
      busy_poll_(cfg.io_busy_poll),
      tx_spin_(cfg.tx_spin),
      io_cpu_(cfg.io_cpu),
      tx_period_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_period_s * 1e9))),
      tx_lead_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_spin_lead_s * 1e9))),
      tx_tail_ns_(static_cast<std::int64_t>(std::llround(cfg.tx_spin_tail_s * 1e9))) {
  if (frags_per_packet_ == 0)
    throw std::invalid_argument("net: scene too large for " + std::to_string(kMaxFragments) +
                                " fragments of net.max_datagram_bytes = " + std::to_string(cfg.wire.max_datagram_bytes));
  for (const auto& l : cfg.peers) {
    auto p = std::make_unique<PeerState>();
    p->link = l;
    if (l.impaired) p->impaired = ImpairedLink(l.impairment, l.seed);
    p->rtt = RttEstimator(cfg.rtt);
    p->stats.station_id = l.station_id;
    peers_.push_back(std::move(p));
  }
  rx_meta_.resize(kRxBuffers);
  rx_store_.resize(kRxBuffers * 2 * value_count_);
  tx_meta_.resize(kTxBuffers);
  tx_store_.resize(kTxBuffers * 2 * value_count_);
  for (std::uint32_t i = 0; i < kRxBuffers; ++i) rx_free_.try_push(i);
  for (std::uint32_t i = 0; i < kTxBuffers; ++i) tx_free_.try_push(i);
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
  thread_ = std::thread([this] { run(); });
  if (io_cpu_ >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(io_cpu_, &set);
    const int e = ::pthread_setaffinity_np(thread_.native_handle(), sizeof set, &set);
    if (e != 0) {
      stop();
      throw std::system_error(e, std::generic_category(),
                              "net.io_cpu = " + std::to_string(io_cpu_) + ": cannot pin the I/O thread");
    }
  }
}

double Endpoint::io_thread_cpu_s() const {
  if (!thread_.joinable()) return io_cpu_at_stop_s_;
  clockid_t cid{};
  timespec ts{};
  if (pthread_getcpuclockid(const_cast<std::thread&>(thread_).native_handle(), &cid) != 0 || clock_gettime(cid, &ts) != 0)
    return 0.0;
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void Endpoint::stop() {
  if (!thread_.joinable()) return;
  io_cpu_at_stop_s_ = io_thread_cpu_s();
  running_.store(false, std::memory_order_release);
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(wake_fd_, &one, sizeof one);
  thread_.join();
}

int Endpoint::find_peer(std::uint16_t id) const {
  for (std::size_t i = 0; i < peers_.size(); ++i)
    if (peers_[i]->link.station_id == id) return static_cast<int>(i);
  return -1;
}

bool Endpoint::push_state(std::uint64_t seq, double send_time_s, const double* x_hat, const double* v_hat) {
  std::uint32_t idx = 0;
  if (!tx_free_.try_pop(idx)) {
    tx_overruns_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  double* dst = tx_store_.data() + std::size_t{idx} * 2 * value_count_;
  std::memcpy(dst, x_hat, sizeof(double) * value_count_);
  std::memcpy(dst + value_count_, v_hat, sizeof(double) * value_count_);
  tx_meta_[idx] = TxMeta{seq, send_time_s, monotonic_ns()};  // vDSO clock read, no syscall
  tx_ready_.try_push(idx);  // cannot fail: as many slots as buffers
  // Dekker pair with spin_for_push() (seq_cst, no fences): if we see the I/O thread spinning,
  // its end-of-window check sees this push; otherwise we wake it.
  tx_pushed_.fetch_add(1, std::memory_order_seq_cst);
  if (tx_spinning_.load(std::memory_order_seq_cst)) return true;  // the spin sees it
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(wake_fd_, &one, sizeof one);  // EFD_NONBLOCK: never blocks
  return true;
}

std::uint32_t Endpoint::rtt_bound_ticks(std::size_t i, double period_s) const {
  if (i >= peers_.size() || !(period_s > 0.0)) return 0;
  const double b = static_cast<double>(peers_[i]->bound_ns.load(std::memory_order_acquire)) * 1e-9;
  return static_cast<std::uint32_t>(std::ceil(b / period_s - 1e-9));
}

std::uint64_t Endpoint::rtt_bound_generation(std::size_t i) const {
  return i < peers_.size() ? peers_[i]->bound_generation.load(std::memory_order_acquire) : 0;
}

void Endpoint::publish_bound(PeerState& p) {
  p.bound_ns.store(static_cast<std::uint64_t>(p.rtt.bound_s() * 1e9), std::memory_order_relaxed);
  p.bound_generation.store(p.rtt.generation(), std::memory_order_release);
}

void Endpoint::begin_probing() {
  std::lock_guard lock(stats_mutex_);
  for (auto& p : peers_) p->rtt.begin_probing();
}

bool Endpoint::finish_probing() {
  std::lock_guard lock(stats_mutex_);
  bool all = true;
  for (auto& p : peers_) {
    if (!p->rtt.probing() && p->rtt.has_bound()) continue;
    if (p->rtt.finish_probing()) publish_bound(*p);
    else all = false;
  }
  return all;
}

EndpointStats Endpoint::stats() const {
  std::lock_guard lock(stats_mutex_);
  EndpointStats s;
  s.drops = decoder_.drops();
  s.datagrams_received = datagrams_received_;
  s.receive_errors = receive_errors_;
  s.rx_ring_full = rx_ring_full_;
  s.wrong_scene_size = wrong_scene_size_;
  s.tx_overruns = tx_overruns_.load(std::memory_order_relaxed);
  s.tx_packets = tx_packets_;
  s.tx_caught_spinning = tx_caught_spinning_;
  s.tx_spin_windows = windows_;
  s.io_thread_cpu_s = io_thread_cpu_s();
  s.tx_handoff_mean_s = tx_packets_ ? tx_handoff_sum_s_ / static_cast<double>(tx_packets_) : 0.0;
  s.tx_handoff_max_s = tx_handoff_max_s_;
  for (const auto& p : peers_) {
    PeerStats ps = p->stats;
    ps.rtt_samples = p->rtt.samples();
    ps.rtt_last_s = p->rtt.last_s();
    ps.rtt_mean_s = p->rtt.mean_s();
    ps.rtt_min_s = p->rtt.min_s();
    ps.rtt_max_s = p->rtt.max_s();
    ps.rtt_bound_s = p->rtt.bound_s();
    ps.rtt_probing = p->rtt.probing();
    ps.rtt_has_bound = p->rtt.has_bound();
    ps.rtt_over_bound_events = p->rtt.over_bound_events();
    ps.rtt_bound_generation = p->rtt.generation();
    if (ps.packets_received > 0) {
      const double span = static_cast<double>(ps.newest_seq - ps.lowest_seq + 1);
      ps.loss_fraction = std::max(0.0, 1.0 - static_cast<double>(ps.packets_received) / span);
    }
    s.peers.push_back(ps);
  }
  return s;
}

// ------------------------------------------------------------------ I/O thread

void Endpoint::run() {
  // The ppoll timeouts below schedule the TX spin window: a SCHED_OTHER thread's default
  // 50 us timer slack would make it late, so ask for none (per thread; harmless otherwise).
  if (tx_spin_) ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  pollfd fds[2] = {{transport_->fd(), POLLIN, 0}, {wake_fd_, POLLIN, 0}};
  while (running_.load(std::memory_order_acquire)) {
    if (busy_poll_) {
      std::lock_guard lock(stats_mutex_);
      const std::int64_t t = monotonic_ns();
      handle_rx(t);
      handle_tx(t);
      release_due(t);
      continue;
    }
    std::int64_t now = monotonic_ns();
    std::int64_t wake_at = now + 100'000'000;  // re-check running_ at least every 100 ms
    if (!delay_heap_.empty()) wake_at = std::min(wake_at, delay_heap_.front().release_ns);
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
        std::uint64_t w;
        {
          std::lock_guard lock(stats_mutex_);
          w = ++windows_;
        }
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
    now = monotonic_ns();
    std::lock_guard lock(stats_mutex_);
    if (fds[0].revents & POLLIN) handle_rx(now);
    handle_tx(now);
    release_due(monotonic_ns());
  }
}

bool Endpoint::spin_for_push(std::int64_t until_ns) {
  tx_spinning_.store(true, std::memory_order_seq_cst);
  bool sent = false;
  std::int64_t now = monotonic_ns();
  while (running_.load(std::memory_order_relaxed) && now < until_ns) {
    if (tx_ready_.size() > 0) {
      std::lock_guard lock(stats_mutex_);
      handle_tx(now, /*caught_spinning=*/true);
      release_due(monotonic_ns());
      sent = true;
      break;
    }
    {
      std::lock_guard lock(stats_mutex_);
      handle_rx(now);  // non-blocking: keep receiving while we wait
      release_due(now);
    }
    cpu_relax();
    now = monotonic_ns();
  }
  missed_windows_ = sent ? 0 : missed_windows_ + 1;  // the pusher stopped: stop spinning
  tx_spinning_.store(false, std::memory_order_seq_cst);
  (void)tx_pushed_.load(std::memory_order_seq_cst);  // pairs with push_state()
  // A push that raced with the end of the window skipped its eventfd write: take it now.
  if (!sent && tx_ready_.size() > 0) {
    std::lock_guard lock(stats_mutex_);
    handle_tx(monotonic_ns());
    sent = true;
  }
  return sent;
}

void Endpoint::handle_rx(std::int64_t now_ns) {
  for (int budget = 0; budget < 4096; ++budget) {
    const long n = transport_->receive(rx_buf_.data(), rx_buf_.size());
    if (n == 0) return;
    if (n < 0) {
      ++receive_errors_;
      return;
    }
    ++datagrams_received_;
    DecodedState st;
    const std::size_t len = std::min<std::size_t>(static_cast<std::size_t>(n), rx_buf_.size());
    if (static_cast<std::size_t>(n) > rx_buf_.size()) {
      // Larger than any legal datagram: the decoder drops it as oversized from its length.
      decoder_.decode(rx_buf_.data(), static_cast<std::size_t>(n) > max_datagram_ ? max_datagram_ + 1 : len, st);
      continue;
    }
    if (decoder_.decode(rx_buf_.data(), len, st) != DecodeStatus::complete) continue;
    if (st.value_count != value_count_) {  // a peer with another scene: never hand it to the tick
      ++wrong_scene_size_;
      continue;
    }
    const int pi = find_peer(st.sender);
    if (pi < 0) continue;  // cannot happen: the decoder knows the same peers
    PeerState& p = *peers_[static_cast<std::size_t>(pi)];
    // Echo bookkeeping: remember the newest packet of this peer to echo it back.
    if (!p.echo.valid || st.seq > p.echo.seq) {
      p.previous_echo = p.echo;
      p.echo = PeerState::EchoSlot{true, st.seq, st.send_time_ns, now_ns};
    }
    // Round trip: first time we see this echo of one of our own packets.
    if (st.has_echo && (!p.sampled_any || st.echo_seq > p.last_sampled_echo)) {
      p.sampled_any = true;
      p.last_sampled_echo = st.echo_seq;
      const bool over = p.rtt.add_sample(static_cast<double>(now_ns - st.echo_time_ns) * 1e-9);
      if (over) publish_bound(p);
    }
    PeerStats& ps = p.stats;
    if (ps.packets_received == 0) ps.lowest_seq = ps.newest_seq = st.seq;
    ps.lowest_seq = std::min(ps.lowest_seq, st.seq);
    ps.newest_seq = std::max(ps.newest_seq, st.seq);
    ++ps.packets_received;
    const double one_way = static_cast<double>(now_ns - st.send_time_ns) * 1e-9;
    ps.one_way_mean_s += (one_way - ps.one_way_mean_s) / static_cast<double>(ps.packets_received);
    ps.one_way_max_s = std::max(ps.one_way_max_s, one_way);

    std::uint32_t idx = 0;
    if (!rx_free_.try_pop(idx)) {
      ++rx_ring_full_;
      continue;
    }
    double* x = rx_store_.data() + std::size_t{idx} * 2 * value_count_;
    st.copy_out(x, x + value_count_);
    rx_meta_[idx] = RxMeta{st.sender,   st.seq,      static_cast<double>(st.send_time_ns) * 1e-9,
                           st.has_echo, st.echo_seq, static_cast<double>(st.echo_time_ns) * 1e-9,
                           monotonic_ns()};
    rx_ready_.try_push(idx);
    // Dekker pair with wait_rx(), seq_cst on both sides (no fences: ThreadSanitizer checks
    // this code): either the waiter's ring check sees this packet or we see the waiter.
    rx_delivered_.fetch_add(1, std::memory_order_seq_cst);
    if (rx_waiters_.load(std::memory_order_seq_cst) > 0) {
      const std::uint64_t one = 1;
      [[maybe_unused]] auto r = ::write(rx_wake_fd_, &one, sizeof one);
    }
  }
}

void Endpoint::send_now(std::uint16_t dest, const std::uint8_t* d, std::size_t len, PeerState& p) {
  if (transport_->send_to(dest, d, len)) ++p.stats.datagrams_sent;
  else ++p.stats.send_errors;
}

void Endpoint::handle_tx(std::int64_t now_ns, bool caught_spinning) {
  std::uint32_t idx = 0;
  while (tx_ready_.try_pop(idx)) {
    const TxMeta m = tx_meta_[idx];
    const double* x = tx_store_.data() + std::size_t{idx} * 2 * value_count_;
    last_push_ns_ = std::max(last_push_ns_, m.push_ns);
    missed_windows_ = 0;
    ++tx_packets_;
    if (caught_spinning) ++tx_caught_spinning_;
    const double handoff = static_cast<double>(monotonic_ns() - m.push_ns) * 1e-9;
    tx_handoff_sum_s_ += handoff;
    tx_handoff_max_s_ = std::max(tx_handoff_max_s_, handoff);
    const std::int64_t stamp = m.send_time_s >= 0.0 ? static_cast<std::int64_t>(std::llround(m.send_time_s * 1e9))
                                                     : now_ns;
    for (auto& pp : peers_) {
      PeerState& p = *pp;
      OutgoingState o;
      o.dest = p.link.station_id;
      o.seq = m.seq;
      o.send_time_ns = stamp;
      const PeerState::EchoSlot* e = p.echo_as_of(stamp);
      o.has_echo = e != nullptr;
      o.echo_seq = e ? e->seq : 0;
      o.echo_time_ns = e ? e->send_time_ns : 0;
      o.value_count = value_count_;
      o.x_hat = x;
      o.v_hat = x + value_count_;
      ++p.stats.packets_sent;
      PacketFate fate;
      fate.copies = 1;
      if (p.link.impaired) {
        fate = p.impaired.next_packet_at(static_cast<double>(now_ns) * 1e-9 - epoch_s_);
        if (fate.lost) ++p.stats.impair_lost;
        if (fate.duplicated) ++p.stats.impair_duplicated;
      }
      for (int c = 0; c < fate.copies; ++c) {
        const std::int64_t release = now_ns + static_cast<std::int64_t>(fate.delay_s[c] * 1e9);
        for (std::size_t f = 0; f < frags_per_packet_; ++f) {
          if (release <= now_ns) {
            const std::size_t len = encoder_.encode_fragment(o, f, tx_buf_.data(), tx_buf_.size());
            if (len) send_now(o.dest, tx_buf_.data(), len, p);
            continue;
          }
          if (delay_free_.empty()) {
            ++p.stats.delay_queue_full;
            continue;
          }
          const std::uint32_t slot = delay_free_.back();
          const std::size_t len =
              encoder_.encode_fragment(o, f, delay_store_.data() + std::size_t{slot} * max_datagram_, max_datagram_);
          if (len == 0) continue;
          delay_free_.pop_back();
          delay_heap_.push_back(Delayed{release, delay_order_++, o.dest, static_cast<std::uint32_t>(len), slot});
          std::push_heap(delay_heap_.begin(), delay_heap_.end(), [](const Delayed& a, const Delayed& b) {
            return heap_later(a, b);
          });
        }
      }
    }
    tx_free_.try_push(idx);
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
