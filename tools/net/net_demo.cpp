// haptic-net-demo: a short, bounded state exchange between two endpoints of this process over
// UDP loopback (IPv4 or IPv6), for looking at the wire (tools/wireshark/test_dissector.sh) and
// as a smoke test. Only loopback addresses. Usage:
//   haptic-net-demo [--port-a P] [--port-b Q] [--packets N] [--nodes N] [--float32] [--ipv6]
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "net/endpoint.hpp"
#include "net/transport_udp.hpp"

using namespace haptic::net;

int main(int argc, char** argv) {
  int port_a = 47001, port_b = 47002, packets = 20, nodes = 33;
  bool f32 = false, v6 = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> int {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::atoi(argv[++i]);
    };
    if (a == "--port-a") port_a = next();
    else if (a == "--port-b") port_b = next();
    else if (a == "--packets") packets = next();
    else if (a == "--nodes") nodes = next();
    else if (a == "--float32") f32 = true;
    else if (a == "--ipv6") v6 = true;
    else {
      std::fprintf(stderr, "usage: %s [--port-a P] [--port-b Q] [--packets N] [--nodes N] [--float32] [--ipv6]\n", argv[0]);
      return 2;
    }
  }
  if (packets < 1 || packets > 100000 || nodes < 1 || nodes > 3000) {
    std::fprintf(stderr, "--packets must be in [1, 100000], --nodes in [1, 3000]\n");
    return 2;
  }
  auto addr = [&](int p) { return (v6 ? std::string("[::1]:") : std::string("127.0.0.1:")) + std::to_string(p); };
  try {
    auto cfg = [&](std::uint16_t self, std::uint16_t peer) {
      EndpointConfig c;
      c.wire.station_id = self;
      c.wire.session_id = 0xDE30;
      c.wire.encoding = f32 ? ValueEncoding::float32 : ValueEncoding::float64;
      c.value_count = static_cast<std::uint32_t>(3 * nodes);
      PeerLink l;
      l.station_id = peer;
      c.peers.push_back(l);
      return c;
    };
    Endpoint a(cfg(0, 1), std::make_unique<UdpTransport>(addr(port_a), std::vector<UdpPeer>{{1, addr(port_b)}}));
    Endpoint b(cfg(1, 0), std::make_unique<UdpTransport>(addr(port_b), std::vector<UdpPeer>{{0, addr(port_a)}}));
    a.start();
    b.start();
    std::vector<double> x(3 * nodes), v(3 * nodes);
    std::uint64_t got_a = 0, got_b = 0;
    for (int k = 1; k <= packets; ++k) {
      for (std::size_t i = 0; i < x.size(); ++i) {
        x[i] = 0.001 * k + 1e-6 * static_cast<double>(i);
        v[i] = -x[i];
      }
      a.push_state(static_cast<std::uint64_t>(k), monotonic_s(), x.data(), v.data());
      b.push_state(static_cast<std::uint64_t>(k), monotonic_s(), x.data(), v.data());
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      got_a += a.drain([](auto...) {});
      got_b += b.drain([](auto...) {});
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    got_a += a.drain([](auto...) {});
    got_b += b.drain([](auto...) {});
    a.stop();
    b.stop();
    const auto sa = a.stats();
    std::printf("haptic-net-demo: %d packets each way, %d nodes, %s, %s: received a=%llu b=%llu, drops=%llu, "
                "rtt max %.3f ms, datagrams sent a->b %llu\n",
                packets, nodes, f32 ? "float32" : "float64", v6 ? "udp6" : "udp4",
                static_cast<unsigned long long>(got_a), static_cast<unsigned long long>(got_b),
                static_cast<unsigned long long>(sa.drops.total()), sa.peers[0].rtt_max_s * 1e3,
                static_cast<unsigned long long>(sa.peers[0].datagrams_sent));
    return (got_a == static_cast<std::uint64_t>(packets) && got_b == static_cast<std::uint64_t>(packets)) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-net-demo: %s\n", e.what());
    return 1;
  }
}
