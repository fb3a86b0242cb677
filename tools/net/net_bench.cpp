// Network layer benchmarks (results kept in tools/bench/results/net_bench.json):
//  - encode+authenticate and verify+decode cost per state packet, 33-node scene (float64 and
//    float32) and the 3000-node scene;
//  - one-way latency through our stack against minimal UDP between the same two processes (a
//    forked child) in the same run, two ways:
//    (a) BM_OneWayPeriodic: what a station sees. A sender thread wakes every 2 ms on absolute
//        deadlines (like the tick) and sends one 33-node state; the latency is CLOCK_MONOTONIC
//        at the receiver (same host clock) minus the stamp taken just before the send:
//          mode 0  minimal UDP: stamp, sendto() of the same payload size; the child's thread
//                  blocked in recv() stamps when recv returns;
//          mode 1  our stack, I/O thread woken by eventfd: stamp, push_state(); I/O thread:
//                  encode + MAC + sendto; child's I/O thread: recv, verify, decode, RX ring,
//                  stamped when the state is in the ring (what the tick polls);
//          mode 2  as 1 with tick-synchronous TX (net.tx_spin): no wake-up on the send side;
//          mode 3  as 1 with direct TX (net.tx_direct): the sender encodes and sends in
//                  push_state(), no wake-up on the send side and no spinning core.
//        Argument: 0 float64 (2 datagrams), 1 float32 (1 datagram). Per mode also the sender's
//        cost of the send call (sendto / push_state: what the tick pays).
//        BM_OneWayPeriodicRaw: the same over raw Ethernet (AF_PACKET) between veth pairs, the
//        minimal pair being two AF_PACKET sockets; only with NET_BENCH_RAW_PREFIX set
//        (tools/bench/raw_oneway.sh makes the pairs in a namespace of its own and removes it).
//    (b) round trip / 2 ping-pongs (BM_OneWayLatency_*): minimal UDP, the wire codec inline,
//        and our stack (eventfd hand-off; OurStackDirect: direct TX at both ends) echoed by a
//        non-RT thread blocked in wait_rx() (one more thread wake-up per hop than a station,
//        whose tick polls the ring). The *OneCpuEach pair places each process on one CPU, as
//        two single-core hosts: the parent's threads on CPU 0, the child's on CPU 1, for the
//        minimal pair and the stack (direct TX, I/O threads pinned by net.io_cpu) alike, so each
//        hop has one cross-CPU wake-up in both and the stack's hand-off to the waiting thread
//        stays on its CPU. The unpinned pair lets the scheduler place the four threads.
#include <benchmark/benchmark.h>
#include <net/if.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <ctime>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "platform/clock.hpp"
#include "net/endpoint.hpp"
#include "net/transport_raw.hpp"
#include "net/transport_udp.hpp"
#include "net/wire.hpp"

using namespace haptic::net;

namespace {

WireConfig wire(std::uint16_t station, ValueEncoding enc = ValueEncoding::float64) {
  WireConfig w;
  w.session_id = 77;
  w.station_id = station;
  w.encoding = enc;
  for (std::size_t i = 0; i < w.key.bytes.size(); ++i) w.key.bytes[i] = static_cast<std::uint8_t>(i + 1);
  return w;
}

struct State {
  std::vector<double> x, v;
  explicit State(std::uint32_t n) : x(n), v(n) {
    for (std::uint32_t i = 0; i < n; ++i) {
      x[i] = 0.001 * i;
      v[i] = -0.002 * i;
    }
  }
  OutgoingState out(std::uint64_t seq) const {
    OutgoingState o;
    o.dest = 0;
    o.seq = seq;
    o.send_time_ns = 1;
    o.has_echo = true;
    o.value_count = static_cast<std::uint32_t>(x.size());
    o.x_hat = x.data();
    o.v_hat = v.data();
    return o;
  }
};

void BM_EncodeAuthenticate(benchmark::State& st) {
  const auto nodes = static_cast<std::uint32_t>(st.range(0));
  const auto enc_kind = st.range(1) ? ValueEncoding::float32 : ValueEncoding::float64;
  Encoder enc(wire(1, enc_kind));
  State s(3 * nodes);
  std::vector<std::uint8_t> buf(kDefaultDatagramBytes);
  const std::size_t frags = enc.fragment_count(3 * nodes);
  std::uint64_t seq = 0;
  std::size_t bytes = 0;
  for (auto _ : st) {
    const OutgoingState o = s.out(++seq);
    for (std::size_t f = 0; f < frags; ++f) {
      bytes += enc.encode_fragment(o, f, buf.data(), buf.size());
      benchmark::DoNotOptimize(buf.data());
    }
  }
  st.counters["datagrams_per_packet"] = static_cast<double>(frags);
  st.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  st.SetLabel(enc_kind == ValueEncoding::float32 ? "float32" : "float64");
}
BENCHMARK(BM_EncodeAuthenticate)->Args({33, 0})->Args({33, 1})->Args({3000, 0});

void BM_VerifyDecode(benchmark::State& st) {
  const auto nodes = static_cast<std::uint32_t>(st.range(0));
  const auto enc_kind = st.range(1) ? ValueEncoding::float32 : ValueEncoding::float64;
  Encoder enc(wire(1, enc_kind));
  const std::uint16_t peers[] = {1};
  State s(3 * nodes), out(3 * nodes);
  const std::size_t frags = enc.fragment_count(3 * nodes);
  // A batch of distinct sequences (the decoder rejects replays); a fresh decoder per batch.
  const std::size_t batch = nodes > 100 ? 16 : 1024;
  std::vector<std::vector<std::uint8_t>> dgs(batch * frags, std::vector<std::uint8_t>(kDefaultDatagramBytes));
  std::vector<std::size_t> lens(batch * frags);
  for (std::size_t p = 0; p < batch; ++p)
    for (std::size_t f = 0; f < frags; ++f)
      lens[p * frags + f] = enc.encode_fragment(s.out(p + 1), f, dgs[p * frags + f].data(), kDefaultDatagramBytes);
  auto dec = std::make_unique<Decoder>(wire(0, enc_kind), peers, 3 * nodes);
  std::size_t p = 0, complete = 0;
  for (auto _ : st) {
    if (p == batch) {
      st.PauseTiming();
      dec = std::make_unique<Decoder>(wire(0, enc_kind), peers, 3 * nodes);
      p = 0;
      st.ResumeTiming();
    }
    DecodedState d;
    for (std::size_t f = 0; f < frags; ++f) {
      if (dec->decode(dgs[p * frags + f].data(), lens[p * frags + f], d) == DecodeStatus::complete) {
        d.copy_out(out.x.data(), out.v.data());
        ++complete;
      }
    }
    benchmark::DoNotOptimize(out.x.data());
    ++p;
  }
  if (complete == 0) st.SkipWithError("nothing decoded");
  st.SetLabel(enc_kind == ValueEncoding::float32 ? "float32" : "float64");
}
BENCHMARK(BM_VerifyDecode)->Args({33, 0})->Args({33, 1})->Args({3000, 0});

// ---------------------------------------------------------------- latency, two processes

constexpr std::uint32_t kValues = 99;  // 33-node scene
constexpr std::size_t kUdpPayload = 2 * kValues * sizeof(double);  // same payload size
std::atomic<int>* g_phase = nullptr;  // shared with the echo process: 0 udp, 1 stack (eventfd), 2 quit, 3 direct TX, 4 / 5 direct TX one CPU each, float64 / float32
pid_t g_child = -1;
int g_udp = -1;
sockaddr_in g_echo_addr{};
std::unique_ptr<Endpoint> g_ep, g_ep_direct;  // the ping-pong's stack: eventfd hand-off, direct TX
std::uint16_t g_port_child_udp = 0;
// The one-CPU-each ping-pongs: the parent's minimal socket and the child's echo address, and the
// parent's direct-TX endpoints with their I/O threads on CPU 0 (phases 4 and 5 in the child).
int g_udp_one_cpu = -1;
sockaddr_in g_echo_one_cpu_addr{};
std::unique_ptr<Endpoint> g_ep_one_cpu[2];  // float64 (phase 4), float32 (phase 5: the lab's encoding)

int udp_socket(std::uint16_t& port) {
  int s = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
  port = ntohs(a.sin_port);
  return s;
}

bool g_busy = false;  // --busy: I/O threads busy-poll (EndpointConfig::io_busy_poll)

EndpointConfig stack_config(std::uint16_t self, std::uint16_t peer, ValueEncoding enc = ValueEncoding::float64) {
  EndpointConfig c;
  c.io_busy_poll = g_busy;
  c.wire = wire(self, enc);
  c.value_count = kValues;
  PeerLink l;
  l.station_id = peer;
  c.peers.push_back(l);
  return c;
}

std::string lo(std::uint16_t port) { return "127.0.0.1:" + std::to_string(port); }

int g_codec = -1;               // parent's codec socket
sockaddr_in g_codec_addr{};     // child's codec echo socket
std::uint16_t g_port_child_codec = 0;

// Codec echo: recv -> verify+decode -> encode+MAC -> send, in one thread (no rings, no I/O
// thread): what our wire format costs on top of a plain UDP ping-pong.
void codec_echo(int s) {
  const std::uint16_t peers[] = {0};
  Encoder enc(wire(1));
  Decoder dec(wire(1), peers, kValues);
  std::vector<std::uint8_t> b(65536), out(kDefaultDatagramBytes);
  std::vector<double> x(kValues), v(kValues);
  for (;;) {
    sockaddr_in from{};
    socklen_t fl = sizeof from;
    const ssize_t n = ::recvfrom(s, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&from), &fl);
    if (n <= 0) continue;
    if (n == 1) break;
    DecodedState st;
    if (dec.decode(b.data(), static_cast<std::size_t>(n), st) != DecodeStatus::complete) continue;
    st.copy_out(x.data(), v.data());
    OutgoingState o;
    o.seq = st.seq;
    o.value_count = kValues;
    o.x_hat = x.data();
    o.v_hat = v.data();
    for (std::size_t f = 0; f < enc.fragment_count(kValues); ++f) {
      const std::size_t len = enc.encode_fragment(o, f, out.data(), out.size());
      ::sendto(s, out.data(), len, 0, reinterpret_cast<sockaddr*>(&from), fl);
    }
  }
}


// ------------------------------------------------ periodic one-way (same-host clock stamps)

constexpr std::int64_t kPeriodNs = 2'000'000;  // the station's tick
constexpr std::size_t kSlots = 8192;
constexpr int kModes = 4;  // minimal, stack eventfd, stack tx_spin, stack tx_direct (BM_OneWayPeriodic)
constexpr std::uint64_t kQuitSeq = ~std::uint64_t{0};  // the minimal receiver's stop datagram
struct OneWaySlot {
  std::atomic<std::uint64_t> seq{0};
  std::atomic<std::int64_t> latency_ns{0};
};
// Shared with the child: [mode][encoding 0..1] sample slots indexed by sequence.
struct PeriodicShared {
  OneWaySlot slot[kModes][2][kSlots];
  std::atomic<bool> quit{false};
};

// One medium (UDP on loopback, raw Ethernet on veth pairs): the minimal pair's sending end and the
// stack's sending endpoints (modes 1..3), in the parent; the receivers are in the forked child.
struct Medium {
  const char* name = "udp";
  PeriodicShared* shared = nullptr;
  int min_send = -1;
  sockaddr_storage min_to{};
  socklen_t min_to_len = 0;
  std::unique_ptr<Endpoint> ep[kModes][2];
  pid_t child = -1;
};
Medium g_udp_medium, g_raw_medium;
const char* g_raw_prefix = nullptr;  // NET_BENCH_RAW_PREFIX: veth pairs <prefix><i>a / <prefix><i>b, i = 0..6

// Placement (2+ CPUs): the sender ("tick") on CPU 1, the sending I/O threads on CPU 0, the
// receiving I/O threads on CPU 1 except direct TX's on CPU 0, and the minimal receiver on CPU 0:
// what sends from CPU 1 (minimal, direct) is received on CPU 0, what sends from CPU 0 (the I/O
// threads) on CPU 1. Every mode then has exactly one cross-CPU wake-up on its receive side, as
// two stations on two hosts have one (NIC interrupt -> receiving thread); only the eventfd mode
// adds a second on its send side.
const bool g_pin = std::thread::hardware_concurrency() >= 2;
void pin_self(int cpu) {
  if (!g_pin) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  ::pthread_setaffinity_np(::pthread_self(), sizeof set, &set);
}

void record(OneWaySlot& s, std::uint64_t seq, std::int64_t ns) {
  s.latency_ns.store(ns, std::memory_order_relaxed);
  s.seq.store(seq, std::memory_order_release);
}

// Child: the minimal receiver, blocked in recv() (stamps when it returns) until the quit datagram.
std::thread minimal_receiver(PeriodicShared* sh, int fd) {
  return std::thread([sh, fd] {
    pin_self(0);
    std::vector<std::uint8_t> b(65536);
    for (;;) {
      const ssize_t n = ::recv(fd, b.data(), b.size(), 0);
      const std::int64_t now = monotonic_ns();
      if (n < 16) continue;
      std::uint64_t seq;
      std::int64_t stamp;
      std::memcpy(&seq, b.data(), 8);
      std::memcpy(&stamp, b.data() + 8, 8);
      if (seq == kQuitSeq) break;
      const int enc = static_cast<int>((seq >> 62) & 1);
      record(sh->slot[0][enc][seq % kSlots], seq, now - stamp);
    }
  });
}

// Child: receive side of every periodic mode, each on its own thread. stack_t: the receiving
// transports of modes 1..3, float64 then float32 each.
void periodic_receivers(PeriodicShared* sh, int min_recv, std::vector<std::unique_ptr<Transport>> stack_t,
                        std::vector<std::thread>& threads, std::vector<std::unique_ptr<Endpoint>>& eps) {
  threads.push_back(minimal_receiver(sh, min_recv));
  std::size_t t = 0;
  for (int mode = 1; mode < kModes; ++mode)
    for (int enc = 0; enc < 2; ++enc) {
      EndpointConfig c = stack_config(1, 0, enc ? ValueEncoding::float32 : ValueEncoding::float64);
      // Direct TX sends from the sender's CPU, as the minimal pair does: its receiver goes where theirs is.
      c.io_cpu = g_pin ? (mode == 3 ? 0 : 1) : -1;
      auto ep = std::make_unique<Endpoint>(c, std::move(stack_t[t++]));
      ep->start();
      Endpoint* e = ep.get();
      eps.push_back(std::move(ep));
      threads.emplace_back([sh, e, mode, enc] {
        while (!sh->quit.load(std::memory_order_acquire)) {
          if (!e->wait_rx(0.05)) continue;
          e->drain_packets([&](const RxPacket& p) {
            const auto ns = static_cast<std::int64_t>(std::llround((p.delivered_s - p.send_time_s) * 1e9));
            record(sh->slot[mode][enc][p.seq % kSlots], p.seq, ns);
          });
        }
      });
    }
}

// Parent: the sending endpoints of modes 1..3 over parent_t (same order as the child's).
void periodic_senders(Medium& m, std::vector<std::unique_ptr<Transport>> parent_t) {
  std::size_t t = 0;
  for (int mode = 1; mode < kModes; ++mode)
    for (int enc = 0; enc < 2; ++enc) {
      EndpointConfig c = stack_config(0, 1, enc ? ValueEncoding::float32 : ValueEncoding::float64);
      c.tx_spin = mode == 2;
      c.tx_direct = mode == 3;
      c.io_cpu = g_pin ? 0 : -1;
      c.tx_period_s = static_cast<double>(kModes * kPeriodNs) * 1e-9;  // it pushes every kModes periods
      m.ep[mode][enc] = std::make_unique<Endpoint>(c, std::move(parent_t[t++]));
      m.ep[mode][enc]->start();
    }
}

void sleep_until_ns(std::int64_t t) { haptic::platform::sleep_until_monotonic_ns(t); }

void start_echo_process();

std::vector<double> sorted(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v;
}
double quantile_us(const std::vector<double>& sm, double f) {
  return sm.empty() ? 0.0 : sm[std::min(sm.size() - 1, static_cast<std::size_t>(f * static_cast<double>(sm.size())))] * 1e6;
}
double mean_us(const std::vector<double>& sm) {
  double s = 0.0;
  for (double x : sm) s += x * 1e6;
  return sm.empty() ? 0.0 : s / static_cast<double>(sm.size());
}

// The counters of BM_OneWayPeriodic: per mode the one-way latency's min, P50, mean, P99, max,
// losses and the sender's cost of the send call (push_state: what the tick pays), each stack mode
// against the minimal pair, and the TX hand-off figures.
void report_one_way(benchmark::State& st, const Medium& md, int enc, bool rt, std::vector<double> (&samples)[kModes],
                    std::vector<double> (&send_cost)[kModes], const std::uint64_t (&lost)[kModes]) {
  st.counters["sender_sched_fifo"] = rt ? 1.0 : 0.0;
  st.counters["pinned"] = g_pin ? 1.0 : 0.0;
  static const char* names[kModes] = {"udp", "stack_wake", "stack_spin", "stack_direct"};
  double p50[kModes] = {}, p99[kModes] = {}, mean[kModes] = {};
  for (int m = 0; m < kModes; ++m) {
    const std::vector<double> sm = sorted(samples[m]), sc = sorted(send_cost[m]);
    p50[m] = quantile_us(sm, 0.5);
    p99[m] = quantile_us(sm, 0.99);
    mean[m] = mean_us(sm);
    const std::string n = names[m];
    st.counters[n + "_min_us"] = quantile_us(sm, 0.0);
    st.counters[n + "_p50_us"] = p50[m];
    st.counters[n + "_mean_us"] = mean[m];
    st.counters[n + "_p99_us"] = p99[m];
    st.counters[n + "_max_us"] = sm.empty() ? 0.0 : sm.back() * 1e6;
    st.counters[n + "_lost"] = static_cast<double>(lost[m]);
    st.counters[n + "_send_call_p50_us"] = quantile_us(sc, 0.5);
    st.counters[n + "_send_call_mean_us"] = mean_us(sc);
    st.counters[n + "_send_call_p99_us"] = quantile_us(sc, 0.99);
  }
  for (int m = 1; m < kModes; ++m) {
    const std::string n = names[m];
    st.counters["ratio_" + n + "_p50"] = p50[0] > 0 ? p50[m] / p50[0] : 0.0;
    st.counters["ratio_" + n + "_mean"] = mean[0] > 0 ? mean[m] / mean[0] : 0.0;
    st.counters["ratio_" + n + "_p99"] = p99[0] > 0 ? p99[m] / p99[0] : 0.0;
  }
  const EndpointStats es = md.ep[2][enc]->stats(), ed = md.ep[3][enc]->stats();
  st.counters["spin_caught_fraction"] = static_cast<double>(es.tx_caught_spinning) / std::max<double>(1.0, static_cast<double>(es.tx_packets));
  st.counters["spin_handoff_mean_us"] = es.tx_handoff_mean_s * 1e6;
  st.counters["wake_handoff_mean_us"] = md.ep[1][enc]->stats().tx_handoff_mean_s * 1e6;
  st.counters["direct_handoff_mean_us"] = ed.tx_handoff_mean_s * 1e6;
  st.counters["direct_fraction"] = static_cast<double>(ed.tx_direct) / std::max<double>(1.0, static_cast<double>(ed.tx_packets));
  st.counters["direct_would_block"] = static_cast<double>(ed.tx_direct_would_block);
  st.SetLabel(std::string(md.name) + ", " + (enc ? "float32" : "float64") +
              " 33-node state; minimal: stamp, sendto -> recv returns; stack: stamp, push_state -> in the receiver's RX ring");
}

// The sender thread as a tick: SCHED_FIFO like the station's RT thread when we may (it preempts
// a spinning SCHED_OTHER I/O thread at once, as in a station), pinned; restored by the destructor.
// The calling thread on one CPU while it lives (nothing when not pinning), its affinity restored.
struct OnCpu {
  cpu_set_t old{};
  explicit OnCpu(int cpu) {
    ::pthread_getaffinity_np(::pthread_self(), sizeof old, &old);
    pin_self(cpu);
  }
  ~OnCpu() { ::pthread_setaffinity_np(::pthread_self(), sizeof old, &old); }
};

struct TickThread {
  const OnCpu on{1};
  int old_policy = 0;
  sched_param old_param{};
  bool rt = false;
  TickThread() {
    ::pthread_getschedparam(::pthread_self(), &old_policy, &old_param);
    const sched_param fifo{80};
    rt = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &fifo) == 0;
  }
  ~TickThread() {
    if (rt) ::pthread_setschedparam(::pthread_self(), old_policy, &old_param);
  }
};

// One iteration = one 2 ms period. The modes take turns period by period (0, 1, 2, 3, 0, ...) so
// that they see the same machine load; each endpoint therefore pushes every kModes periods (its
// tick-synchronous TX is configured with that period). A sample is read one rotation after its
// send, so the sender never waits or polls (no interference).
void one_way_periodic(benchmark::State& st, Medium& md) {
  const int enc = static_cast<int>(st.range(0));
  static std::uint64_t seq_base[2][kModes][2] = {};
  std::uint64_t (&base)[kModes][2] = seq_base[&md == &g_raw_medium ? 1 : 0];
  std::vector<double> x(kValues, 0.25), v(kValues, -0.5);
  // The state's size; over raw Ethernet at most one frame (the stack sends float64 as 2 datagrams).
  const std::size_t bytes = enc ? kUdpPayload / 2 : kUdpPayload;
  std::vector<std::uint8_t> payload(&md == &g_raw_medium ? std::min(bytes, kDefaultDatagramBytes) : bytes, 0x5A);
  std::vector<double> samples[kModes], send_cost[kModes];
  std::uint64_t lost[kModes] = {};
  const TickThread tick;
  const std::uint64_t tag = std::uint64_t{static_cast<unsigned>(enc)} << 62;
  auto send = [&](int mode, std::uint64_t seq) {
    const std::int64_t stamp = monotonic_ns();
    if (mode == 0) {
      std::memcpy(payload.data(), &seq, 8);
      std::memcpy(payload.data() + 8, &stamp, 8);
      ::sendto(md.min_send, payload.data(), payload.size(), 0, reinterpret_cast<sockaddr*>(&md.min_to), md.min_to_len);
    } else {
      md.ep[mode][enc]->push_state(seq, static_cast<double>(stamp) * 1e-9, x.data(), v.data());
    }
    return static_cast<double>(monotonic_ns() - stamp) * 1e-9;
  };
  std::uint64_t pending[kModes] = {};  // sequence sent in the previous rotation, per mode
  auto collect = [&](int mode) {
    const std::uint64_t seq = pending[mode];
    if (seq == 0) return;
    OneWaySlot& slot = md.shared->slot[mode][enc][seq % kSlots];
    if (slot.seq.load(std::memory_order_acquire) != seq) {
      ++lost[mode];
      return;
    }
    samples[mode].push_back(static_cast<double>(slot.latency_ns.load(std::memory_order_relaxed)) * 1e-9);
  };
  std::int64_t next = monotonic_ns() + kPeriodNs;
  long k = 0;
  for (int i = 0; i < 10 * kModes; ++i, ++k, next += kPeriodNs) {  // warm-up rotations
    sleep_until_ns(next);
    send(static_cast<int>(k % kModes), tag | ++base[k % kModes][enc]);
  }
  for (auto _ : st) {
    sleep_until_ns(next);
    next += kPeriodNs;
    const int mode = static_cast<int>(k++ % kModes);
    collect(mode);
    pending[mode] = tag | ++base[mode][enc];
    send_cost[mode].push_back(send(mode, pending[mode]));
  }
  report_one_way(st, md, enc, tick.rt, samples, send_cost, lost);
}

void BM_OneWayPeriodic(benchmark::State& st) {
  start_echo_process();
  one_way_periodic(st, g_udp_medium);
}
BENCHMARK(BM_OneWayPeriodic)->Arg(0)->Arg(1)->ArgName("f32")->Iterations(6000)->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------- raw Ethernet (veth pairs)

std::string raw_if(int i, char end) { return std::string(g_raw_prefix) + std::to_string(i) + end; }

// An AF_PACKET datagram socket on interface ifname for our EtherType: the minimal raw pair's end.
int raw_socket(const std::string& ifname) {
  const int fd = ::socket(AF_PACKET, SOCK_DGRAM | SOCK_CLOEXEC, htons(kEtherTypeLocalExperimental1));
  sockaddr_ll sll{};
  sll.sll_family = AF_PACKET;
  sll.sll_protocol = htons(kEtherTypeLocalExperimental1);
  sll.sll_ifindex = static_cast<int>(::if_nametoindex(ifname.c_str()));
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&sll), sizeof sll) != 0) {
    std::fprintf(stderr, "bench_net: raw socket on %s: %s\n", ifname.c_str(), std::strerror(errno));
    std::exit(2);
  }
  return fd;
}

// Veth pair 0 carries the minimal raw pair, pairs 1..6 the stack's endpoints (modes 1..3 x encodings).
void start_raw_process() {
  if (g_raw_medium.child > 0) return;
  Medium& m = g_raw_medium;
  m.name = "raw";
  void* pm = ::mmap(nullptr, sizeof(PeriodicShared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  m.shared = new (pm) PeriodicShared();
  m.min_send = raw_socket(raw_if(0, 'a'));
  const int min_recv = raw_socket(raw_if(0, 'b'));
  auto* to = reinterpret_cast<sockaddr_ll*>(&m.min_to);
  to->sll_family = AF_PACKET;
  to->sll_protocol = htons(kEtherTypeLocalExperimental1);
  to->sll_ifindex = static_cast<int>(::if_nametoindex(raw_if(0, 'a').c_str()));
  to->sll_halen = 6;
  const MacAddress peer0 = interface_mac(raw_if(0, 'b'));
  std::memcpy(to->sll_addr, peer0.data(), 6);
  m.min_to_len = sizeof(sockaddr_ll);
  std::vector<std::unique_ptr<Transport>> parent_t, child_t;
  for (int i = 1; i <= 6; ++i) {
    parent_t.push_back(std::make_unique<RawEthernetTransport>(raw_if(i, 'a'), std::vector<RawPeer>{{1, interface_mac(raw_if(i, 'b'))}}));
    child_t.push_back(std::make_unique<RawEthernetTransport>(raw_if(i, 'b'), std::vector<RawPeer>{{0, interface_mac(raw_if(i, 'a'))}}));
  }
  m.child = ::fork();
  if (m.child == 0) {
    parent_t.clear();
    std::vector<std::thread> threads;
    std::vector<std::unique_ptr<Endpoint>> eps;
    periodic_receivers(m.shared, min_recv, std::move(child_t), threads, eps);
    for (auto& t : threads) t.join();
    for (auto& e : eps) e->stop();
    std::_Exit(0);
  }
  ::close(min_recv);
  child_t.clear();
  periodic_senders(m, std::move(parent_t));
}

void BM_OneWayPeriodicRaw(benchmark::State& st) {
  start_raw_process();
  one_way_periodic(st, g_raw_medium);
}

// Child: a UDP echo thread (blocking recvfrom, a 1-byte datagram ends it), pinned to cpu (>= 0).
std::thread udp_echo_thread(int udp, int cpu) {
  return std::thread([udp, cpu] {
    if (cpu >= 0) pin_self(cpu);
    std::vector<std::uint8_t> b(65536);
    for (;;) {
      sockaddr_in from{};
      socklen_t fl = sizeof from;
      const ssize_t n = ::recvfrom(udp, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&from), &fl);
      if (n <= 0) continue;
      if (n == 1) break;  // quit
      ::sendto(udp, b.data(), static_cast<std::size_t>(n), 0, reinterpret_cast<sockaddr*>(&from), fl);
    }
  });
}

// Child: echoes every state a waits for in phase pa (b in phase pb) until phase 2.
void stack_echo(Endpoint& a, int pa, Endpoint* b = nullptr, int pb = -1) {
  for (int phase; (phase = g_phase->load(std::memory_order_acquire)) != 2;) {
    if (phase != pa && phase != pb) {
      ::usleep(2000);
      continue;
    }
    Endpoint& e = phase == pa ? a : *b;
    if (!e.wait_rx(0.01)) continue;
    e.drain([&](std::uint16_t, std::uint64_t seq, double, const double* x, const double* v, std::uint32_t) {
      e.push_state(seq, -1.0, x, v);
    });
  }
}

[[noreturn]] void echo_process(int udp, int udp_one_cpu, std::unique_ptr<UdpTransport> stack_transport,
                               std::unique_ptr<UdpTransport> direct_transport,
                               std::unique_ptr<UdpTransport> one_cpu_transport[2], int codec, int oneway_udp,
                               std::vector<std::unique_ptr<Transport>> periodic_t) {
  std::vector<std::thread> periodic_threads;
  std::vector<std::unique_ptr<Endpoint>> periodic_eps;
  periodic_receivers(g_udp_medium.shared, oneway_udp, std::move(periodic_t), periodic_threads, periodic_eps);
  std::thread codec_thread([codec] { codec_echo(codec); });
  // UDP echoes on their own threads (blocking recv; the one-CPU-each one on CPU 1), the stack
  // echo in this thread when phase 1 or 3, on a thread of its own on CPU 1 when phase 4 or 5.
  std::thread udp_echo = udp_echo_thread(udp, -1);
  std::thread udp_echo_one_cpu = udp_echo_thread(udp_one_cpu, 1);
  Endpoint ep(stack_config(1, 0), std::move(stack_transport));
  EndpointConfig dc = stack_config(1, 0);
  dc.tx_direct = true;
  Endpoint direct(dc, std::move(direct_transport));
  dc.io_cpu = g_pin ? 1 : -1;
  Endpoint one_cpu(dc, std::move(one_cpu_transport[0]));
  EndpointConfig dc32 = dc;
  dc32.wire = wire(1, ValueEncoding::float32);
  Endpoint one_cpu32(dc32, std::move(one_cpu_transport[1]));
  ep.start();
  direct.start();
  one_cpu.start();
  one_cpu32.start();
  std::thread stack_echo_one_cpu([&one_cpu, &one_cpu32] {
    pin_self(1);
    stack_echo(one_cpu, 4, &one_cpu32, 5);
  });
  stack_echo(ep, 1, &direct, 3);
  stack_echo_one_cpu.join();
  ep.stop();
  direct.stop();
  one_cpu.stop();
  one_cpu32.stop();
  g_udp_medium.shared->quit.store(true, std::memory_order_release);
  udp_echo.join();
  udp_echo_one_cpu.join();
  codec_thread.join();
  for (auto& t : periodic_threads) t.join();
  for (auto& e : periodic_eps) e->stop();
  std::_Exit(0);
}

// A connected pair of UDP transports on loopback: first the parent's (station 0), then the child's.
std::pair<std::unique_ptr<UdpTransport>, std::unique_ptr<UdpTransport>> udp_pair() {
  auto a = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  auto b = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  a->set_peer({1, lo(b->local_port())});
  b->set_peer({0, lo(a->local_port())});
  return {std::move(a), std::move(b)};
}

sockaddr_in loopback(std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  return a;
}

void start_echo_process() {
  if (g_child > 0) return;
  void* mem = ::mmap(nullptr, sizeof(std::atomic<int>), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  g_phase = new (mem) std::atomic<int>(0);
  Medium& m = g_udp_medium;
  void* pm = ::mmap(nullptr, sizeof(PeriodicShared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  m.shared = new (pm) PeriodicShared();
  std::uint16_t parent_oneway_port = 0, child_oneway_port = 0;
  m.min_send = udp_socket(parent_oneway_port);
  const int child_oneway = udp_socket(child_oneway_port);
  const sockaddr_in to = loopback(child_oneway_port);
  std::memcpy(&m.min_to, &to, sizeof to);
  m.min_to_len = sizeof to;
  std::vector<std::unique_ptr<Transport>> per_parent, per_child;
  for (int i = 0; i < 2 * (kModes - 1); ++i) {
    auto [a, b] = udp_pair();
    per_parent.push_back(std::move(a));
    per_child.push_back(std::move(b));
  }
  std::uint16_t parent_udp_port = 0;
  g_udp = udp_socket(parent_udp_port);
  int child_udp = udp_socket(g_port_child_udp);
  std::uint16_t parent_codec_port = 0;
  g_codec = udp_socket(parent_codec_port);
  int child_codec = udp_socket(g_port_child_codec);
  std::uint16_t parent_one_cpu_port = 0, child_one_cpu_port = 0;
  g_udp_one_cpu = udp_socket(parent_one_cpu_port);
  const int child_udp_one_cpu = udp_socket(child_one_cpu_port);
  auto [parent_t, child_t] = udp_pair();
  auto [parent_direct, child_direct] = udp_pair();
  std::unique_ptr<UdpTransport> parent_one_cpu[2], child_one_cpu[2];
  for (int e = 0; e < 2; ++e) std::tie(parent_one_cpu[e], child_one_cpu[e]) = udp_pair();
  g_child = ::fork();
  if (g_child == 0) {
    parent_t.reset();
    parent_direct.reset();
    for (auto& t : parent_one_cpu) t.reset();
    per_parent.clear();
    echo_process(child_udp, child_udp_one_cpu, std::move(child_t), std::move(child_direct), child_one_cpu,
                 child_codec, child_oneway, std::move(per_child));
  }
  ::close(child_udp_one_cpu);
  g_echo_one_cpu_addr = loopback(child_one_cpu_port);
  ::close(child_oneway);
  per_child.clear();
  periodic_senders(m, std::move(per_parent));
  ::close(child_udp);
  ::close(child_codec);
  g_codec_addr = loopback(g_port_child_codec);
  child_t.reset();
  child_direct.reset();
  for (auto& t : child_one_cpu) t.reset();
  g_echo_addr = loopback(g_port_child_udp);
  g_ep = std::make_unique<Endpoint>(stack_config(0, 1), std::move(parent_t));
  g_ep->start();
  EndpointConfig dc = stack_config(0, 1);
  dc.tx_direct = true;
  g_ep_direct = std::make_unique<Endpoint>(dc, std::move(parent_direct));
  g_ep_direct->start();
  dc.io_cpu = g_pin ? 0 : -1;
  for (int e = 0; e < 2; ++e) {
    dc.wire = wire(0, e ? ValueEncoding::float32 : ValueEncoding::float64);
    g_ep_one_cpu[e] = std::make_unique<Endpoint>(dc, std::move(parent_one_cpu[e]));
    g_ep_one_cpu[e]->start();
  }
}

void minimal_ping_pong(benchmark::State& st, int fd, const sockaddr_in& echo, std::size_t payload) {
  start_echo_process();
  g_phase->store(0, std::memory_order_release);
  std::vector<std::uint8_t> b(payload, 0x5A), r(65536);
  for (auto _ : st) {
    const auto t0 = std::chrono::steady_clock::now();
    ::sendto(fd, b.data(), b.size(), 0, reinterpret_cast<const sockaddr*>(&echo), sizeof echo);
    ::recv(fd, r.data(), r.size(), 0);
    const auto t1 = std::chrono::steady_clock::now();
    st.SetIterationTime(std::chrono::duration<double>(t1 - t0).count() / 2.0);
  }
}
void BM_OneWayLatency_MinimalUdpPingPong(benchmark::State& st) {
  minimal_ping_pong(st, g_udp, g_echo_addr, kUdpPayload);
  st.SetLabel("one-way = round trip / 2, 1584-byte UDP payload, loopback, two processes");
}
BENCHMARK(BM_OneWayLatency_MinimalUdpPingPong)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);
void BM_OneWayLatency_MinimalUdpPingPongOneCpuEach(benchmark::State& st) {
  start_echo_process();  // before pinning: the forked child must not inherit CPU 0
  const OnCpu on(0);
  minimal_ping_pong(st, g_udp_one_cpu, g_echo_one_cpu_addr, static_cast<std::size_t>(st.range(0)));
  st.counters["pinned"] = g_pin ? 1.0 : 0.0;
  st.SetLabel("as MinimalUdpPingPong with this payload (bytes: a 33-node state's x and v in float64 / float32), this thread on CPU 0, the echo's on CPU 1");
}
BENCHMARK(BM_OneWayLatency_MinimalUdpPingPongOneCpuEach)->Arg(kUdpPayload)->Arg(kUdpPayload / 2)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

void BM_OneWayLatency_WireCodecInline(benchmark::State& st) {
  start_echo_process();
  g_phase->store(0, std::memory_order_release);
  const std::uint16_t peers[] = {1};
  Encoder enc(wire(0));
  std::vector<double> x(kValues, 0.25), v(kValues, -0.5);
  std::vector<std::uint8_t> out(kDefaultDatagramBytes), b(65536);
  static std::uint64_t seq = 0;
  Decoder dec(wire(0), peers, kValues);  // fresh per run: the echo's sequences restart with ours
  std::uint64_t lost = 0;
  for (auto _ : st) {
    const auto t0 = std::chrono::steady_clock::now();
    OutgoingState o;
    o.dest = 1;
    o.seq = ++seq;
    o.value_count = kValues;
    o.x_hat = x.data();
    o.v_hat = v.data();
    for (std::size_t f = 0; f < enc.fragment_count(kValues); ++f) {
      const std::size_t len = enc.encode_fragment(o, f, out.data(), out.size());
      ::sendto(g_codec, out.data(), len, 0, reinterpret_cast<sockaddr*>(&g_codec_addr), sizeof g_codec_addr);
    }
    DecodedState d;
    bool done = false;
    while (!done) {
      const ssize_t n = ::recv(g_codec, b.data(), b.size(), 0);
      if (n <= 0) {
        ++lost;
        break;
      }
      if (dec.decode(b.data(), static_cast<std::size_t>(n), d) == DecodeStatus::complete) {
        d.copy_out(x.data(), v.data());
        done = true;
      }
    }
    const auto t1 = std::chrono::steady_clock::now();
    st.SetIterationTime(std::chrono::duration<double>(t1 - t0).count() / 2.0);
  }
  st.counters["lost"] = static_cast<double>(lost);
  st.SetLabel("one-way = round trip / 2: encode+MAC, 2 datagrams, verify+decode+reassemble, no threads");
}
BENCHMARK(BM_OneWayLatency_WireCodecInline)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

// The stack's ping-pong: ep here, the child's echo endpoint of the same kind (phase 1: eventfd
// hand-off, 3: direct TX).
void stack_ping_pong(benchmark::State& st, Endpoint& ep, int phase) {
  start_echo_process();
  g_phase->store(phase, std::memory_order_release);
  std::vector<double> x(kValues, 0.25), v(kValues, -0.5);
  static std::uint64_t seqs[6] = {};  // across runs: the decoders reject replayed sequences
  std::uint64_t& seq = seqs[phase];
  std::uint64_t lost = 0;
  // Warm up the path.
  for (int i = 0; i < 20; ++i) {
    ep.push_state(++seq, -1.0, x.data(), v.data());
    ::usleep(1000);
    ep.drain([](auto...) {});
  }
  for (auto _ : st) {
    const std::uint64_t want = ++seq;
    bool got = false;
    const auto t0 = std::chrono::steady_clock::now();
    ep.push_state(want, -1.0, x.data(), v.data());
    auto t1 = t0;
    while (!got) {
      ep.drain([&](std::uint16_t, std::uint64_t s, double, const double*, const double*, std::uint32_t) {
        if (s == want) got = true;
      });
      t1 = std::chrono::steady_clock::now();
      if (!got) {
        if (t1 - t0 > std::chrono::seconds(1)) {
          ++lost;
          break;
        }
        ep.wait_rx(0.01);
      }
    }
    const double rt = std::chrono::duration<double>(t1 - t0).count();
    if (std::getenv("NET_BENCH_DEBUG") && rt > 0.01) std::fprintf(stderr, "slow round trip seq %llu: %.1f ms\n", (unsigned long long)want, rt * 1e3);
    st.SetIterationTime(rt / 2.0);
  }
  st.counters["lost"] = static_cast<double>(lost);
  const EndpointStats es = ep.stats();
  st.counters["drops"] = static_cast<double>(es.drops.total());
  st.counters["rx"] = static_cast<double>(es.peers[0].packets_received);
  st.counters["tx_overruns"] = static_cast<double>(es.tx_overruns);
  st.counters["tx_direct"] = static_cast<double>(es.tx_direct);
  st.SetLabel(phase >= 3 ? "one-way = round trip / 2 via push_state (the caller sends)/UDP/I-O thread/drain, 33-node state"
                         : "one-way = round trip / 2 via push_state/I-O thread/UDP/I-O thread/drain, 33-node state");
}

void BM_OneWayLatency_OurStack(benchmark::State& st) {
  start_echo_process();
  stack_ping_pong(st, *g_ep, 1);
}
void BM_OneWayLatency_OurStackDirect(benchmark::State& st) {
  start_echo_process();
  stack_ping_pong(st, *g_ep_direct, 3);
}
void BM_OneWayLatency_OurStackDirectOneCpuEach(benchmark::State& st) {
  start_echo_process();  // before pinning: the forked child must not inherit CPU 0
  const OnCpu on(0);
  const int f32 = static_cast<int>(st.range(0));
  stack_ping_pong(st, *g_ep_one_cpu[f32], 4 + f32);
  st.counters["pinned"] = g_pin ? 1.0 : 0.0;
}
BENCHMARK(BM_OneWayLatency_OurStackDirect)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);
BENCHMARK(BM_OneWayLatency_OurStack)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);
BENCHMARK(BM_OneWayLatency_OurStackDirectOneCpuEach)->ArgName("f32")->Arg(0)->Arg(1)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

// The minimal receivers' stop datagram, on medium m.
void send_quit(Medium& m) {
  std::uint64_t quit[2] = {kQuitSeq, 0};
  ::sendto(m.min_send, quit, sizeof quit, 0, reinterpret_cast<sockaddr*>(&m.min_to), m.min_to_len);
}

void stop_children() {
  if (g_child > 0) {
    g_phase->store(2, std::memory_order_release);
    const char quit = 'q';
    ::sendto(g_udp, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_echo_addr), sizeof g_echo_addr);
    ::sendto(g_udp_one_cpu, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_echo_one_cpu_addr), sizeof g_echo_one_cpu_addr);
    ::sendto(g_codec, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_codec_addr), sizeof g_codec_addr);
    send_quit(g_udp_medium);
    int status = 0;
    ::waitpid(g_child, &status, 0);
    g_ep->stop();
    g_ep_direct->stop();
    for (auto& e : g_ep_one_cpu) e->stop();
  }
  if (g_raw_medium.child > 0) {
    g_raw_medium.shared->quit.store(true, std::memory_order_release);
    send_quit(g_raw_medium);
    int status = 0;
    ::waitpid(g_raw_medium.child, &status, 0);
  }
  for (Medium* m : {&g_udp_medium, &g_raw_medium})
    for (auto& row : m->ep)
      for (auto& e : row)
        if (e) e->stop();
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--busy") == 0) {
      g_busy = true;
      for (int j = i; j + 1 < argc; ++j) argv[j] = argv[j + 1];
      --argc;
      break;
    }
  benchmark::AddCustomContext("io_busy_poll", g_busy ? "true" : "false");
  // Raw Ethernet over veth pairs <prefix>0a/0b .. <prefix>6a/6b (tools/bench/raw_oneway.sh makes them in a namespace).
  g_raw_prefix = std::getenv("NET_BENCH_RAW_PREFIX");
  if (g_raw_prefix != nullptr)
    benchmark::RegisterBenchmark("BM_OneWayPeriodicRaw", BM_OneWayPeriodicRaw)
        ->Arg(0)->Arg(1)->ArgName("f32")->Iterations(6000)->Unit(benchmark::kMicrosecond);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  stop_children();
  return 0;
}
