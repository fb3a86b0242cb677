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
//          mode 2  as 1 with tick-synchronous TX (net.tx_spin): no wake-up on the send side.
//        Second argument: 0 float64 (2 datagrams), 1 float32 (1 datagram).
//    (b) round trip / 2 ping-pongs (BM_OneWayLatency_*): minimal UDP, the wire codec inline,
//        and our stack echoed by a non-RT thread blocked in wait_rx() (one more thread
//        wake-up per hop than a station, whose tick polls the ring).
#include <benchmark/benchmark.h>
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
#include <thread>
#include <vector>

#include "platform/clock.hpp"
#include "net/endpoint.hpp"
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
std::atomic<int>* g_phase = nullptr;  // shared with the echo process: 0 udp, 1 stack, 2 quit
pid_t g_child = -1;
int g_udp = -1;
sockaddr_in g_echo_addr{};
std::unique_ptr<Endpoint> g_ep;
std::uint16_t g_port_child_udp = 0;

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
struct OneWaySlot {
  std::atomic<std::uint64_t> seq{0};
  std::atomic<std::int64_t> latency_ns{0};
};
// Shared with the child: [mode 0..2][encoding 0..1] sample slots indexed by sequence.
struct PeriodicShared {
  OneWaySlot slot[3][2][kSlots];
};
PeriodicShared* g_per = nullptr;
int g_oneway_udp = -1;             // parent's socket for mode 0
sockaddr_in g_oneway_addr{};       // child's mode-0 receiver
std::unique_ptr<Endpoint> g_per_ep[3][2];  // parent's sending endpoints for modes 1 and 2

// Placement (2+ CPUs): the sender ("tick") on CPU 1, the sending I/O threads on CPU 0, the
// receiving I/O threads on CPU 1 and the minimal-UDP receiver on CPU 0. Every mode then has
// exactly one cross-CPU wake-up on its receive side, as two stations on two hosts have one
// (NIC interrupt -> receiving thread); only the eventfd mode adds a second on its send side.
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

// Child: receive side of every periodic mode, each on its own thread.
void periodic_receivers(int oneway_udp, std::vector<std::unique_ptr<UdpTransport>> stack_t,
                        std::vector<std::thread>& threads, std::vector<std::unique_ptr<Endpoint>>& eps) {
  threads.emplace_back([oneway_udp] {
    pin_self(0);
    std::vector<std::uint8_t> b(65536);
    for (;;) {
      const ssize_t n = ::recv(oneway_udp, b.data(), b.size(), 0);
      const std::int64_t now = monotonic_ns();
      if (n == 1) break;
      if (n < 16) continue;
      std::uint64_t seq;
      std::int64_t stamp;
      std::memcpy(&seq, b.data(), 8);
      std::memcpy(&stamp, b.data() + 8, 8);
      const int enc = static_cast<int>(seq >> 62);
      record(g_per->slot[0][enc][seq % kSlots], seq, now - stamp);
    }
  });
  std::size_t t = 0;
  for (int mode = 1; mode <= 2; ++mode)
    for (int enc = 0; enc < 2; ++enc) {
      EndpointConfig c = stack_config(1, 0, enc ? ValueEncoding::float32 : ValueEncoding::float64);
      c.io_cpu = g_pin ? 1 : -1;
      auto ep = std::make_unique<Endpoint>(c, std::move(stack_t[t++]));
      ep->start();
      Endpoint* e = ep.get();
      eps.push_back(std::move(ep));
      threads.emplace_back([e, mode, enc] {
        while (g_phase->load(std::memory_order_acquire) != 2) {
          if (!e->wait_rx(0.05)) continue;
          e->drain_packets([&](const RxPacket& p) {
            const auto ns = static_cast<std::int64_t>(std::llround((p.delivered_s - p.send_time_s) * 1e9));
            record(g_per->slot[mode][enc][p.seq % kSlots], p.seq, ns);
          });
        }
      });
    }
}

void sleep_until_ns(std::int64_t t) { haptic::platform::sleep_until_monotonic_ns(t); }

void start_echo_process();

constexpr int kModes = 3;  // udp, stack_wake, stack_spin (BM_OneWayPeriodic)

// The counters of BM_OneWayPeriodic: per mode the one-way latency's min, P50, mean, P99, max
// and losses, each stack mode against minimal UDP, and the TX hand-off figures.
void report_one_way(benchmark::State& st, int enc, bool rt, std::vector<double> (&samples)[kModes],
                    const std::uint64_t (&lost)[kModes]) {
  st.counters["sender_sched_fifo"] = rt ? 1.0 : 0.0;
  st.counters["pinned"] = g_pin ? 1.0 : 0.0;
  static const char* names[kModes] = {"udp", "stack_wake", "stack_spin"};
  double p50[kModes] = {}, p99[kModes] = {}, mean[kModes] = {};
  for (int m = 0; m < kModes; ++m) {
    auto& sm = samples[m];
    std::sort(sm.begin(), sm.end());
    auto q = [&](double f) { return sm.empty() ? 0.0 : sm[std::min(sm.size() - 1, static_cast<std::size_t>(f * static_cast<double>(sm.size())))] * 1e6; };
    p50[m] = q(0.5);
    p99[m] = q(0.99);
    for (double x1 : sm) mean[m] += x1 * 1e6;
    mean[m] = sm.empty() ? 0.0 : mean[m] / static_cast<double>(sm.size());
    const std::string n = names[m];
    st.counters[n + "_min_us"] = sm.empty() ? 0.0 : sm.front() * 1e6;
    st.counters[n + "_p50_us"] = p50[m];
    st.counters[n + "_mean_us"] = mean[m];
    st.counters[n + "_p99_us"] = p99[m];
    st.counters[n + "_max_us"] = sm.empty() ? 0.0 : sm.back() * 1e6;
    st.counters[n + "_lost"] = static_cast<double>(lost[m]);
  }
  for (int m = 1; m < kModes; ++m) {
    const std::string n = names[m];
    st.counters["ratio_" + n + "_p50"] = p50[0] > 0 ? p50[m] / p50[0] : 0.0;
    st.counters["ratio_" + n + "_mean"] = mean[0] > 0 ? mean[m] / mean[0] : 0.0;
    st.counters["ratio_" + n + "_p99"] = p99[0] > 0 ? p99[m] / p99[0] : 0.0;
  }
  const EndpointStats es = g_per_ep[2][enc]->stats();
  st.counters["spin_caught_fraction"] = static_cast<double>(es.tx_caught_spinning) / std::max<double>(1.0, static_cast<double>(es.tx_packets));
  st.counters["spin_handoff_mean_us"] = es.tx_handoff_mean_s * 1e6;
  st.counters["wake_handoff_mean_us"] = g_per_ep[1][enc]->stats().tx_handoff_mean_s * 1e6;
  st.SetLabel(std::string(enc ? "float32" : "float64") +
              " 33-node state; udp: stamp, sendto -> recv returns; stack: stamp, push_state -> in the receiver's RX ring");
}

// One iteration = one 2 ms period. The three modes take turns period by period (0, 1, 2, 0,
// ...) so that they see the same machine load; each endpoint therefore pushes every 3
// periods (its tick-synchronous TX is configured with that period). A sample is read one
// rotation after its send, so the sender never waits or polls (no interference).
void BM_OneWayPeriodic(benchmark::State& st) {
  start_echo_process();
  const int enc = static_cast<int>(st.range(0));
  static std::uint64_t seq_base[kModes][2] = {};
  std::vector<double> x(kValues, 0.25), v(kValues, -0.5);
  std::vector<std::uint8_t> payload(enc ? kUdpPayload / 2 : kUdpPayload, 0x5A);
  std::vector<double> samples[kModes];
  std::uint64_t lost[kModes] = {};
  // The sender is the tick: SCHED_FIFO like the station's RT thread when we may (it preempts
  // a spinning SCHED_OTHER I/O thread at once, as in a station); restored afterwards.
  int old_policy = 0;
  sched_param old_param{};
  ::pthread_getschedparam(::pthread_self(), &old_policy, &old_param);
  const sched_param fifo{80};
  const bool rt = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &fifo) == 0;
  cpu_set_t old_affinity;
  ::pthread_getaffinity_np(::pthread_self(), sizeof old_affinity, &old_affinity);
  pin_self(1);
  const std::uint64_t tag = std::uint64_t{static_cast<unsigned>(enc)} << 62;
  auto send = [&](int mode, std::uint64_t seq) {
    if (mode == 0) {
      const std::int64_t stamp = monotonic_ns();
      std::memcpy(payload.data(), &seq, 8);
      std::memcpy(payload.data() + 8, &stamp, 8);
      ::sendto(g_oneway_udp, payload.data(), payload.size(), 0, reinterpret_cast<sockaddr*>(&g_oneway_addr),
               sizeof g_oneway_addr);
    } else {
      g_per_ep[mode][enc]->push_state(seq, monotonic_s(), x.data(), v.data());
    }
  };
  std::uint64_t pending[kModes] = {};  // sequence sent in the previous rotation, per mode
  auto collect = [&](int mode) {
    const std::uint64_t seq = pending[mode];
    if (seq == 0) return;
    OneWaySlot& slot = g_per->slot[mode][enc][seq % kSlots];
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
    send(static_cast<int>(k % kModes), tag | ++seq_base[k % kModes][enc]);
  }
  for (auto _ : st) {
    sleep_until_ns(next);
    next += kPeriodNs;
    const int mode = static_cast<int>(k++ % kModes);
    collect(mode);
    pending[mode] = tag | ++seq_base[mode][enc];
    send(mode, pending[mode]);
  }
  if (rt) ::pthread_setschedparam(::pthread_self(), old_policy, &old_param);
  ::pthread_setaffinity_np(::pthread_self(), sizeof old_affinity, &old_affinity);
  report_one_way(st, enc, rt, samples, lost);
}
BENCHMARK(BM_OneWayPeriodic)->Arg(0)->Arg(1)->ArgName("f32")->Iterations(4500)->Unit(benchmark::kMicrosecond);

[[noreturn]] void echo_process(int udp, std::unique_ptr<UdpTransport> stack_transport, int codec, int oneway_udp,
                               std::vector<std::unique_ptr<UdpTransport>> periodic_t) {
  std::vector<std::thread> periodic_threads;
  std::vector<std::unique_ptr<Endpoint>> periodic_eps;
  periodic_receivers(oneway_udp, std::move(periodic_t), periodic_threads, periodic_eps);
  std::thread codec_thread([codec] { codec_echo(codec); });
  // UDP echo on its own thread (blocking recv), the stack echo in this thread when phase 1.
  std::thread udp_echo([udp] {
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
  Endpoint ep(stack_config(1, 0), std::move(stack_transport));
  ep.start();
  while (g_phase->load(std::memory_order_acquire) != 2) {
    if (g_phase->load(std::memory_order_acquire) != 1) {
      ::usleep(2000);
      continue;
    }
    if (!ep.wait_rx(0.01)) continue;
    ep.drain([&](std::uint16_t, std::uint64_t seq, double, const double* x, const double* v, std::uint32_t) {
      ep.push_state(seq, -1.0, x, v);
    });
  }
  ep.stop();
  udp_echo.join();
  codec_thread.join();
  for (auto& t : periodic_threads) t.join();
  for (auto& e : periodic_eps) e->stop();
  std::_Exit(0);
}

void start_echo_process() {
  if (g_child > 0) return;
  void* mem = ::mmap(nullptr, sizeof(std::atomic<int>), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  g_phase = new (mem) std::atomic<int>(0);
  void* pm = ::mmap(nullptr, sizeof(PeriodicShared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  g_per = new (pm) PeriodicShared();
  std::uint16_t parent_oneway_port = 0, child_oneway_port = 0;
  g_oneway_udp = udp_socket(parent_oneway_port);
  const int child_oneway = udp_socket(child_oneway_port);
  g_oneway_addr.sin_family = AF_INET;
  g_oneway_addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  g_oneway_addr.sin_port = htons(child_oneway_port);
  std::vector<std::unique_ptr<UdpTransport>> per_parent, per_child;
  for (int i = 0; i < 4; ++i) {
    per_parent.push_back(std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{}));
    per_child.push_back(std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{}));
    per_parent.back()->set_peer({1, lo(per_child.back()->local_port())});
    per_child.back()->set_peer({0, lo(per_parent.back()->local_port())});
  }
  std::uint16_t parent_udp_port = 0;
  g_udp = udp_socket(parent_udp_port);
  int child_udp = udp_socket(g_port_child_udp);
  std::uint16_t parent_codec_port = 0;
  g_codec = udp_socket(parent_codec_port);
  int child_codec = udp_socket(g_port_child_codec);
  auto parent_t = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  auto child_t = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  parent_t->set_peer({1, lo(child_t->local_port())});
  child_t->set_peer({0, lo(parent_t->local_port())});
  g_child = ::fork();
  if (g_child == 0) {
    parent_t.reset();
    per_parent.clear();
    echo_process(child_udp, std::move(child_t), child_codec, child_oneway, std::move(per_child));
  }
  ::close(child_oneway);
  per_child.clear();
  {
    std::size_t t = 0;
    for (int mode = 1; mode <= 2; ++mode)
      for (int enc = 0; enc < 2; ++enc) {
        EndpointConfig c = stack_config(0, 1, enc ? ValueEncoding::float32 : ValueEncoding::float64);
        c.tx_spin = mode == 2;
        c.io_cpu = g_pin ? 0 : -1;
        c.tx_period_s = static_cast<double>(kModes * kPeriodNs) * 1e-9;  // it pushes every kModes periods
        g_per_ep[mode][enc] = std::make_unique<Endpoint>(c, std::move(per_parent[t++]));
        g_per_ep[mode][enc]->start();
      }
  }
  ::close(child_udp);
  ::close(child_codec);
  g_codec_addr.sin_family = AF_INET;
  g_codec_addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  g_codec_addr.sin_port = htons(g_port_child_codec);
  child_t.reset();
  g_echo_addr.sin_family = AF_INET;
  g_echo_addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  g_echo_addr.sin_port = htons(g_port_child_udp);
  g_ep = std::make_unique<Endpoint>(stack_config(0, 1), std::move(parent_t));
  g_ep->start();
}

void BM_OneWayLatency_MinimalUdpPingPong(benchmark::State& st) {
  start_echo_process();
  g_phase->store(0, std::memory_order_release);
  std::vector<std::uint8_t> b(kUdpPayload, 0x5A), r(65536);
  for (auto _ : st) {
    const auto t0 = std::chrono::steady_clock::now();
    ::sendto(g_udp, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&g_echo_addr), sizeof g_echo_addr);
    ::recv(g_udp, r.data(), r.size(), 0);
    const auto t1 = std::chrono::steady_clock::now();
    st.SetIterationTime(std::chrono::duration<double>(t1 - t0).count() / 2.0);
  }
  st.SetLabel("one-way = round trip / 2, 1584-byte UDP payload, loopback, two processes");
}
BENCHMARK(BM_OneWayLatency_MinimalUdpPingPong)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

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

void BM_OneWayLatency_OurStack(benchmark::State& st) {
  start_echo_process();
  g_phase->store(1, std::memory_order_release);
  std::vector<double> x(kValues, 0.25), v(kValues, -0.5);
  static std::uint64_t seq = 0;  // across runs: the decoders reject replayed sequences
  std::uint64_t lost = 0;
  // Warm up the path.
  for (int i = 0; i < 20; ++i) {
    g_ep->push_state(++seq, -1.0, x.data(), v.data());
    ::usleep(1000);
    g_ep->drain([](auto...) {});
  }
  for (auto _ : st) {
    const std::uint64_t want = ++seq;
    bool got = false;
    const auto t0 = std::chrono::steady_clock::now();
    g_ep->push_state(want, -1.0, x.data(), v.data());
    auto t1 = t0;
    while (!got) {
      g_ep->drain([&](std::uint16_t, std::uint64_t s, double, const double*, const double*, std::uint32_t) {
        if (s == want) got = true;
      });
      t1 = std::chrono::steady_clock::now();
      if (!got) {
        if (t1 - t0 > std::chrono::seconds(1)) {
          ++lost;
          break;
        }
        g_ep->wait_rx(0.01);
      }
    }
    const double rt = std::chrono::duration<double>(t1 - t0).count();
    if (std::getenv("NET_BENCH_DEBUG") && rt > 0.01) std::fprintf(stderr, "slow round trip seq %llu: %.1f ms\n", (unsigned long long)want, rt * 1e3);
    st.SetIterationTime(rt / 2.0);
  }
  st.counters["lost"] = static_cast<double>(lost);
  const EndpointStats es = g_ep->stats();
  st.counters["drops"] = static_cast<double>(es.drops.total());
  st.counters["rx"] = static_cast<double>(es.peers[0].packets_received);
  st.counters["tx_overruns"] = static_cast<double>(es.tx_overruns);
  st.SetLabel("one-way = round trip / 2 via push_state/I-O thread/UDP/I-O thread/drain, 33-node state");
}
BENCHMARK(BM_OneWayLatency_OurStack)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

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
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (g_child > 0) {
    g_phase->store(2, std::memory_order_release);
    const char quit = 'q';
    ::sendto(g_udp, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_echo_addr), sizeof g_echo_addr);
    ::sendto(g_codec, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_codec_addr), sizeof g_codec_addr);
    ::sendto(g_oneway_udp, &quit, 1, 0, reinterpret_cast<sockaddr*>(&g_oneway_addr), sizeof g_oneway_addr);
    int status = 0;
    ::waitpid(g_child, &status, 0);
    g_ep->stop();
    for (auto& row : g_per_ep)
      for (auto& e : row)
        if (e) e->stop();
  }
  return 0;
}
