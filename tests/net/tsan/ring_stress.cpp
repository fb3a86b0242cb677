// ThreadSanitizer stress of the endpoint's ring hand-offs (RT thread <-> I/O thread over UDP
// loopback; the rings are platform/spsc_ring.hpp, stressed alone by tests/platform/tsan).
// Bounded: fixed item counts. Exit code 0 = the packets arrived intact, and TSan reported no race.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "net/endpoint.hpp"
#include "net/transport_udp.hpp"

namespace {

// Two UDP transports on loopback that know each other as stations 0 and 1.
struct LoopbackPair {
  std::unique_ptr<haptic::net::UdpTransport> a, b;
};
LoopbackPair loopback_pair() {
  using haptic::net::UdpPeer;
  using haptic::net::UdpTransport;
  LoopbackPair p{std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{}),
                 std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{})};
  p.a->set_peer({1, "127.0.0.1:" + std::to_string(p.b->local_port())});
  p.b->set_peer({0, "127.0.0.1:" + std::to_string(p.a->local_port())});
  return p;
}
// A 33-node endpoint config of station `self` with one neighbor `peer`.
haptic::net::EndpointConfig stress_config(std::uint16_t self, std::uint16_t peer) {
  haptic::net::EndpointConfig c;
  c.wire.station_id = self;
  c.value_count = 99;
  haptic::net::PeerLink l;
  l.station_id = peer;
  c.peers.push_back(l);
  return c;
}

// The receiving station's "RT" side on its own thread: drains every 200 us and checks that
// x_hat[check_index] carries the sequence number the sender wrote there.
struct Drainer {
  std::atomic<bool> done{false};
  std::uint64_t got = 0, bad = 0;
  std::thread thread;
  Drainer(haptic::net::Endpoint& e, std::size_t check_index)
      : thread([this, &e, check_index] {
          while (!done.load(std::memory_order_acquire)) {
            e.drain([&](std::uint16_t, std::uint64_t seq, double, const double* xh, const double*, std::uint32_t) {
              ++got;
              if (xh[check_index] != static_cast<double>(seq)) ++bad;
            });
            std::this_thread::sleep_for(std::chrono::microseconds(200));
          }
        }) {}
  void stop() {
    done.store(true, std::memory_order_release);
    thread.join();
  }
};

int endpoint_stress(std::uint64_t count) {
  using namespace haptic::net;
  LoopbackPair t = loopback_pair();
  auto cfg = [](std::uint16_t self, std::uint16_t peer) {
    EndpointConfig c = stress_config(self, peer);
    c.peers[0].impaired = true;
    c.peers[0].impairment = LinkImpairment::paper(0.002);
    c.peers[0].seed = self + 1;
    c.rtt.min_probe_samples = 1;
    return c;
  };
  Endpoint a(cfg(0, 1), std::move(t.a)), b(cfg(1, 0), std::move(t.b));
  a.start();
  b.start();
  a.begin_probing();
  std::vector<double> x(99), v(99);
  // The "RT" side of b runs in its own thread, a's in this one.
  Drainer rt_b(b, 5);
  for (std::uint64_t k = 1; k <= count; ++k) {
    for (auto& e : x) e = static_cast<double>(k);
    a.push_state(k, monotonic_s(), x.data(), v.data());
    b.push_state(k, monotonic_s(), x.data(), v.data());
    a.drain([](auto...) {});
    if (k == count / 2) a.finish_probing();
    (void)a.stats();  // monitoring reads from a third party while the I/O thread runs
    std::this_thread::sleep_for(std::chrono::microseconds(300));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  rt_b.stop();
  const std::uint64_t got = rt_b.got, bad = rt_b.bad;
  a.stop();
  b.stop();
  std::printf("endpoint stress: %llu sent with paper impairment, %llu delivered, %llu corrupt\n",
              static_cast<unsigned long long>(count), static_cast<unsigned long long>(got),
              static_cast<unsigned long long>(bad));
  return (bad == 0 && got > count / 2) ? 0 : 1;
}

// Tick-synchronous TX under TSan: pushes on and off the spin window's grid, with pauses that
// make the I/O thread stop spinning and re-arm; every push must be handed to the transport.
int spin_stress(std::uint64_t count) {
  using namespace haptic::net;
  LoopbackPair t = loopback_pair();
  EndpointConfig ca = stress_config(0, 1);
  ca.tx_spin = true;
  ca.tx_period_s = 500e-6;
  ca.tx_spin_lead_s = 100e-6;
  ca.tx_spin_tail_s = 150e-6;
  Endpoint a(ca, std::move(t.a)), b(stress_config(1, 0), std::move(t.b));
  a.start();
  b.start();
  std::vector<double> x(99), v(99);
  Drainer rt_b(b, 7);
  std::uint64_t lcg = 12345, refused = 0;
  for (std::uint64_t k = 1; k <= count; ++k) {
    for (auto& e : x) e = static_cast<double>(k);
    if (!a.push_state(k, monotonic_s(), x.data(), v.data())) ++refused;  // TX ring full: a starved I/O thread (counted)
    lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
    const auto jitter = static_cast<long>((lcg >> 33) % 400);  // 0..399 us around the period
    std::this_thread::sleep_for(std::chrono::microseconds(k % 500 == 0 ? 5000 : 300 + jitter));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  rt_b.stop();
  const std::uint64_t got = rt_b.got, bad = rt_b.bad;
  const EndpointStats s = a.stats();
  a.stop();
  b.stop();
  // Every push the endpoint accepted is handed to the transport (the spin's Dekker pair loses no wake-up);
  // a push refused because the TX ring was full (the I/O thread starved on a loaded host) is the
  // endpoint's counted overrun, not a lost push.
  std::printf("spin stress: %llu pushed, %llu refused (TX ring full, %llu overruns counted), %llu handed to the transport (%llu caught spinning, "
              "%llu windows), %llu delivered, %llu corrupt\n",
              static_cast<unsigned long long>(count), static_cast<unsigned long long>(refused), static_cast<unsigned long long>(s.tx_overruns),
              static_cast<unsigned long long>(s.tx_packets),
              static_cast<unsigned long long>(s.tx_caught_spinning), static_cast<unsigned long long>(s.tx_spin_windows),
              static_cast<unsigned long long>(got), static_cast<unsigned long long>(bad));
  // refused <= 5 %: a loaded CI host refused 3 of 2000; lost wake-ups (push_state without io_.wake())
  // fill the ring and refuse about a quarter (539 of 2000 measured), which this fails.
  return (s.tx_packets == count - refused && s.tx_overruns == refused && refused <= count / 20 && bad == 0 && got > count / 2) ? 0 : 1;
}

// Direct TX under TSan: both ends' ticks send themselves while their I/O threads receive and
// publish the tickets the ticks read (keys, echoes); every push is counted once, sent once, and
// the echoes still match the send records the I/O thread keeps after the fact.
int direct_stress(std::uint64_t count) {
  using namespace haptic::net;
  LoopbackPair t = loopback_pair();
  EndpointConfig ca = stress_config(0, 1), cb = stress_config(1, 0);
  ca.tx_direct = cb.tx_direct = true;
  Endpoint a(ca, std::move(t.a)), b(cb, std::move(t.b));
  a.start();
  b.start();
  Drainer rt_b(b, 7);
  std::atomic<bool> done{false};
  std::thread tick_b([&] {  // b's tick pushes too: a's I/O thread publishes echoes while a's tick reads them
    std::vector<double> x(99, 0.5), v(99);
    for (std::uint64_t k = 1; !done.load(std::memory_order_acquire); ++k) {
      b.push_state(k, monotonic_s(), x.data(), v.data());
      std::this_thread::sleep_for(std::chrono::microseconds(400));
    }
  });
  std::vector<double> x(99), v(99);
  std::uint64_t refused = 0;
  for (std::uint64_t k = 1; k <= count; ++k) {
    for (auto& e : x) e = static_cast<double>(k);
    if (!a.push_state(k, monotonic_s(), x.data(), v.data())) ++refused;
    std::this_thread::sleep_for(std::chrono::microseconds(k % 500 == 0 ? 5000 : 300));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  done.store(true, std::memory_order_release);
  tick_b.join();
  rt_b.stop();
  a.stop();  // after stop, every push's bookkeeping is done
  b.stop();
  const EndpointStats s = a.stats();
  const std::uint64_t pushed = count - refused;
  std::printf("direct stress: %llu pushed (%llu refused), %llu counted: %llu sent by the tick, %llu finished by the I/O thread, "
              "%llu declined; %llu packets sent, %llu round trips, %llu delivered, %llu corrupt\n",
              static_cast<unsigned long long>(count), static_cast<unsigned long long>(refused),
              static_cast<unsigned long long>(s.tx_packets), static_cast<unsigned long long>(s.tx_direct),
              static_cast<unsigned long long>(s.tx_direct_unfinished), static_cast<unsigned long long>(s.tx_direct_declined),
              static_cast<unsigned long long>(s.peers[0].packets_sent), static_cast<unsigned long long>(s.peers[0].rtt_samples),
              static_cast<unsigned long long>(rt_b.got), static_cast<unsigned long long>(rt_b.bad));
  return (s.tx_packets == pushed && s.tx_direct + s.tx_direct_unfinished + s.tx_direct_declined == pushed &&
          s.peers[0].packets_sent == pushed && s.tx_direct > pushed / 2 && s.peers[0].rtt_samples > 0 &&
          rt_b.bad == 0 && rt_b.got > count / 2)
             ? 0
             : 1;
}

}  // namespace

int main() {
  int rc = endpoint_stress(2000);
  rc |= spin_stress(2000);
  rc |= direct_stress(2000);
  return rc;
}
