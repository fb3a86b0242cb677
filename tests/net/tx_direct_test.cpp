// Direct TX (net/tx_direct.hpp, EndpointConfig::tx_direct): the tick sends its push itself; the
// I/O thread does the bookkeeping and sends what the kernel would not take. And the batch
// system calls of the transports (sendmmsg, recvmmsg). Driven without the I/O thread
// (Endpoint::step_without_thread) where the order of events must be exact, over UDP loopback
// with both threads where it must hold as a station runs.
#include <CppUTest/TestHarness.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <thread>
#include <utility>
#include <vector>

#include "net/endpoint.hpp"
#include "net/transport_udp.hpp"
#include "tests/net/exchange_util.hpp"

using namespace haptic::net;
using haptic::net::test::exchange;
using haptic::net::test::exchange_config;
using haptic::net::test::exchange_wire;

namespace {

constexpr std::uint32_t kValues = 99;  // 33 nodes: 2 datagrams per packet in float64

// Records every datagram handed to it, in order; accepts at most `budget` more datagrams, then
// says the socket would block (EAGAIN), as a full send buffer does.
class RecordingTransport final : public Transport {
 public:
  int fd() const override { return -1; }
  bool send_to(std::uint16_t dest, const std::uint8_t* d, std::size_t n) override {
    if (budget == 0) {
      errno = EAGAIN;
      return false;
    }
    --budget;
    sent.push_back({dest, std::vector<std::uint8_t>(d, d + n)});
    return true;
  }
  long receive(std::uint8_t*, std::size_t) override { return 0; }
  std::size_t max_datagram_bytes() const override { return 1472; }
  const char* name() const override { return "recording"; }
  std::size_t budget = 1u << 30;
  std::vector<std::pair<std::uint16_t, std::vector<std::uint8_t>>> sent;
};

EndpointConfig direct_config() {
  EndpointConfig c = exchange_config(0, 1, kValues);
  PeerLink second;
  second.station_id = 2;
  c.peers.push_back(second);
  c.wire.encoding = ValueEncoding::float64;
  c.tx_direct = true;
  return c;
}

struct Frag {
  std::uint64_t seq;
  std::uint16_t index;
};
// (sequence, fragment index) of each datagram the transport took for station dest, in order.
std::vector<Frag> frags_to(const RecordingTransport& t, std::uint16_t dest) {
  std::vector<Frag> out;
  for (const auto& [to, d] : t.sent) {
    if (to != dest) continue;
    std::uint64_t seq = 0;
    std::uint16_t index = 0;
    std::memcpy(&seq, d.data() + wire_offset::seq, 8);
    std::memcpy(&index, d.data() + wire_offset::frag_index, 2);
    out.push_back({seq, index});
  }
  return out;
}

// Every datagram of pushes 1..pushes to dest exactly once, in push order, fragments in order.
void check_each_once_in_order(const RecordingTransport& t, std::uint16_t dest, std::uint64_t pushes) {
  const std::vector<Frag> f = frags_to(t, dest);
  CHECK_EQUAL(2 * pushes, f.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    CHECK_EQUAL(i / 2 + 1, f[i].seq);
    CHECK_EQUAL(i % 2, f[i].index);
  }
}

// The station 1's receiving decoder takes every datagram for it: the packets it completes.
std::vector<std::uint64_t> completed_at_1(const RecordingTransport& t) {
  const std::uint16_t peers[] = {0};
  Decoder dec(exchange_wire(1), peers, kValues);
  std::vector<std::uint64_t> done;
  std::vector<double> x(kValues), v(kValues);
  for (const auto& [to, d] : t.sent) {
    if (to != 1) continue;
    DecodedState st;
    if (dec.decode(d.data(), d.size(), st) != DecodeStatus::complete) continue;
    st.copy_out(x.data(), v.data());
    std::vector<double> ex(kValues), ev(kValues);
    haptic::net::test::fill_state(0, st.seq, ex, ev);
    CHECK(x == ex && v == ev);  // float64: bit for bit
    done.push_back(st.seq);
  }
  return done;
}

// stamp < 0: the sender stamps it (the tick when it sends itself).
// Pushes 1..3 went to both neighbours, each datagram once and in order, and station 1 completes them.
void check_three_pushes_delivered(const RecordingTransport& t) {
  check_each_once_in_order(t, 1, 3);
  check_each_once_in_order(t, 2, 3);
  CHECK((std::vector<std::uint64_t>{1, 2, 3}) == completed_at_1(t));
}

void check_peers_sent(const EndpointStats& s, std::uint64_t packets, std::uint64_t datagrams) {
  for (const PeerStats& p : s.peers) {
    CHECK_EQUAL(packets, p.packets_sent);
    CHECK_EQUAL(datagrams, p.datagrams_sent);
    CHECK_EQUAL(0u, p.send_errors);
  }
}

void push(Endpoint& ep, std::uint64_t k, double stamp_s = 0.0) {
  std::vector<double> x(kValues), v(kValues);
  haptic::net::test::fill_state(0, k, x, v);
  CHECK(ep.push_state(k, stamp_s < 0.0 ? stamp_s : monotonic_s(), x.data(), v.data()));
}

}  // namespace

TEST_GROUP(TxDirect){};

TEST(TxDirect, TheTickSendsEveryPushItselfOnceAndTheIoThreadOnlyKeepsTheBooks) {
  auto owned = std::make_unique<RecordingTransport>();
  RecordingTransport& t = *owned;
  Endpoint ep(direct_config(), std::move(owned));
  for (std::uint64_t k = 1; k <= 3; ++k) {
    push(ep, k);
    CHECK_EQUAL(4 * k, t.sent.size());  // sent inside push_state: 2 neighbours x 2 fragments
  }
  ep.step_without_thread(monotonic_ns());  // the bookkeeping: nothing is sent again
  CHECK_EQUAL(12u, t.sent.size());
  check_three_pushes_delivered(t);
  const EndpointStats s = ep.stats();
  CHECK_EQUAL(3u, s.tx_packets);
  CHECK_EQUAL(3u, s.tx_direct);
  CHECK_EQUAL(0u, s.tx_direct_unfinished + s.tx_direct_declined + s.tx_direct_would_block);
  check_peers_sent(s, 3, 6);
  std::uint64_t bytes = 0;
  for (const auto& d : t.sent) bytes += d.second.size();
  CHECK_EQUAL(bytes, s.peers[0].bytes_sent + s.peers[1].bytes_sent);
}

TEST(TxDirect, ASendThatWouldBlockIsFinishedByTheIoThreadInOrderAndCounted) {
  auto owned = std::make_unique<RecordingTransport>();
  RecordingTransport& t = *owned;
  Endpoint ep(direct_config(), std::move(owned));
  t.budget = 3;  // push 1: the socket takes 3 of its 4 datagrams
  push(ep, 1);
  CHECK_EQUAL(3u, t.sent.size());
  t.budget = 1u << 30;
  push(ep, 2);  // push 1 is still owed by the I/O thread: the tick must not overtake it
  CHECK_EQUAL(3u, t.sent.size());
  ep.step_without_thread(monotonic_ns());  // the rest of push 1, then push 2
  CHECK_EQUAL(8u, t.sent.size());
  push(ep, 3);  // nothing owed any more: direct again
  CHECK_EQUAL(12u, t.sent.size());
  ep.step_without_thread(monotonic_ns());
  check_three_pushes_delivered(t);
  const EndpointStats s = ep.stats();
  CHECK_EQUAL(3u, s.tx_packets);
  CHECK_EQUAL(1u, s.tx_direct);
  CHECK_EQUAL(1u, s.tx_direct_unfinished);
  CHECK_EQUAL(1u, s.tx_direct_would_block);
  CHECK_EQUAL(1u, s.tx_direct_declined);
  check_peers_sent(s, 3, 6);
}

TEST(TxDirect, TheRestOfAnUnfinishedPacketCarriesTheHeaderTheTickChose) {
  auto owned = std::make_unique<RecordingTransport>();
  RecordingTransport& t = *owned;
  Endpoint ep(direct_config(), std::move(owned));
  t.budget = 1;  // fragment 0 to station 1 only
  push(ep, 1, -1.0);  // stamped by the tick
  t.budget = 1u << 30;
  ep.step_without_thread(monotonic_ns() + 5'000'000);  // the I/O thread's clock is later
  const std::vector<std::uint8_t>& f0 = t.sent[0].second;
  const std::vector<std::uint8_t>& f1 = t.sent[1].second;
  CHECK_EQUAL(1, t.sent[1].first);
  // Same header but for the fragment fields: stamp, echo, flags.
  CHECK_EQUAL(0, std::memcmp(f0.data(), f1.data(), wire_offset::frag_index));
}

TEST(TxDirect, TooLargeAPushOrAnImpairedLinkTakesTheIoThreadsPath) {
  {
    EndpointConfig c = direct_config();
    c.value_count = 3000 * 3;  // 3000 nodes: 2 x 110 datagrams
    auto owned = std::make_unique<RecordingTransport>();
    RecordingTransport& t = *owned;
    Endpoint ep(c, std::move(owned));
    std::vector<double> x(c.value_count, 0.1), v(c.value_count, 0.0);
    CHECK(ep.push_state(1, monotonic_s(), x.data(), v.data()));
    CHECK_EQUAL(0u, t.sent.size());
    ep.step_without_thread(monotonic_ns());
    CHECK(t.sent.size() > 100);
    CHECK_EQUAL(0u, ep.stats().tx_direct);
  }
  EndpointConfig c = direct_config();
  c.peers[1].impaired = true;  // the emulator's delay queue is the I/O thread's
  auto owned = std::make_unique<RecordingTransport>();
  RecordingTransport& t = *owned;
  Endpoint ep(c, std::move(owned));
  push(ep, 1);
  CHECK_EQUAL(0u, t.sent.size());
  ep.step_without_thread(monotonic_ns());
  CHECK_EQUAL(1u, ep.stats().tx_direct_declined);
  check_each_once_in_order(t, 1, 1);
}

TEST(TxDirect, TickSpinAndDirectTogetherAreRefusedNamingBoth) {
  EndpointConfig c = direct_config();
  c.tx_spin = true;
  c.tx_period_s = 0.002;
  std::string what;
  try {
    Endpoint ep(c, std::make_unique<RecordingTransport>());
  } catch (const std::invalid_argument& e) {
    what = e.what();
  }
  CHECK(what.find("net.tx_spin") != std::string::npos && what.find("net.tx_direct") != std::string::npos);
}

TEST(TxDirect, TwoStationsExchangeOverUdpWithTheTickSending) {
  auto ta = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  auto tb = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
  ta->set_peer({1, "127.0.0.1:" + std::to_string(tb->local_port())});
  tb->set_peer({0, "127.0.0.1:" + std::to_string(ta->local_port())});
  EndpointConfig ca = exchange_config(0, 1, kValues), cb = exchange_config(1, 0, kValues);
  ca.tx_direct = cb.tx_direct = true;
  Endpoint a(ca, std::move(ta)), b(cb, std::move(tb));
  a.start();
  b.start();
  const auto r = exchange(a, b, 0, 1, 300);
  a.stop();
  b.stop();
  CHECK(r.received[0] >= 300 && r.received[1] >= 300);
  CHECK_EQUAL(0u, r.corrupt[0] + r.corrupt[1]);
  CHECK_EQUAL(0u, r.out_of_order[0] + r.out_of_order[1]);
  for (const Endpoint* e : {&a, &b}) {
    const EndpointStats s = e->stats();  // after stop(): every push's bookkeeping is done
    CHECK(s.tx_direct > 0);
    CHECK_EQUAL(s.tx_packets, s.tx_direct + s.tx_direct_unfinished + s.tx_direct_declined);
    CHECK_EQUAL(s.tx_packets, s.peers[0].packets_sent);
    CHECK(s.peers[0].datagrams_sent >= s.tx_packets);  // at least one datagram per packet
    CHECK(s.peers[0].rtt_samples > 0);         // the lazily kept send records match the echoes
  }
}

TEST_GROUP(BatchTransport){};

TEST(BatchTransport, UdpSendsABatchInOrderAndReceivesItInOneCallWithSourcesAndRealSizes) {
  UdpTransport a("127.0.0.1:0", {}), b("127.0.0.1:0", {});
  a.set_peer({1, "127.0.0.1:" + std::to_string(b.local_port())});
  b.set_peer({0, "127.0.0.1:" + std::to_string(a.local_port())});
  std::vector<std::vector<std::uint8_t>> data;
  std::vector<TxDatagram> out;
  for (std::uint8_t i = 0; i < 20; ++i) data.push_back(std::vector<std::uint8_t>(100 + i, i));
  for (const auto& d : data) out.push_back({1, d.data(), d.size()});
  int error = -1;
  CHECK_EQUAL(20u, a.send_batch(out.data(), out.size(), error));  // two sendmmsg calls of at most 16
  CHECK_EQUAL(0, error);
  std::vector<std::uint8_t> store(20 * 110);
  RxDatagram in[16];
  std::size_t got = 0;
  for (int tries = 0; got < 20 && tries < 1000; ++tries) {
    for (std::size_t i = 0; i < 16; ++i) in[i] = RxDatagram{store.data() + i * 110, 110, 0, -2};
    const long n = b.receive_batch(in, 16);
    CHECK(n >= 0);
    if (n == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    for (long i = 0; i < n; ++i, ++got) {
      CHECK_EQUAL(100u + got, in[i].len);  // the real size, also of the truncated ones (>= 110)
      CHECK_EQUAL(0, in[i].source);
      CHECK_EQUAL(got, in[i].buf[0]);
    }
  }
  CHECK_EQUAL(20u, got);
  // A station that is not configured: what comes before it is sent, then EINVAL.
  TxDatagram bad[2] = {{1, data[0].data(), 10}, {7, data[0].data(), 10}};
  CHECK_EQUAL(1u, a.send_batch(bad, 2, error));
  CHECK_EQUAL(EINVAL, error);
  // From an address that is not a peer: source -1.
  UdpTransport stranger("127.0.0.1:0", {});
  stranger.set_peer({1, "127.0.0.1:" + std::to_string(b.local_port())});
  CHECK(stranger.send_to(1, data[3].data(), 50));
  int source = -2;
  for (int tries = 0; source == -2 && tries < 1000; ++tries) {
    in[0] = RxDatagram{store.data(), 110, 0, -2};
    in[1] = RxDatagram{store.data() + 110, 110, 0, -2};
    const long n = b.receive_batch(in, 2);
    for (long i = 0; i < n; ++i)
      if (in[i].len == 50) source = in[i].source;
    if (n == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK_EQUAL(-1, source);
}
