// Attacks on a station's receive path over real UDP loopback sockets: a forged
// packet from another address, a far-future sequence from an authentic peer, zero-length and
// flooding datagrams, non-finite and out-of-envelope states. Each test checks that the attack is
// dropped and counted by its reason AND that the genuine neighbour's packets still arrive
// unchanged (so the tick sees exactly what it would without the attack).
#include <CppUTest/TestHarness.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "net/transport_udp.hpp"
#include "tests/net/exchange_util.hpp"

using namespace haptic::net;
using namespace haptic::net::test;

namespace {

constexpr std::uint32_t kValues = 99;  // 33 nodes

// Station 0 (the victim, `a`) and its one neighbour, station 1 (`b`), on 127.0.0.1.
struct Link {
  std::unique_ptr<Endpoint> a, b;
  std::string addr_a, addr_b;
  explicit Link(EndpointConfig ca = exchange_config(0, 1, kValues)) {
    auto ta = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
    auto tb = std::make_unique<UdpTransport>("127.0.0.1:0", std::vector<UdpPeer>{});
    addr_a = "127.0.0.1:" + std::to_string(ta->local_port());
    addr_b = "127.0.0.1:" + std::to_string(tb->local_port());
    ta->set_peer({1, addr_b});
    tb->set_peer({0, addr_a});
    a = std::make_unique<Endpoint>(ca, std::move(ta));
    b = std::make_unique<Endpoint>(exchange_config(1, 0, kValues), std::move(tb));
    a->start();
    b->start();
  }
  ~Link() {
    a->stop();
    b->stop();
  }
};

// A socket on another loopback port: the attacker.
struct Attacker {
  int fd = -1;
  sockaddr_storage dst{};
  socklen_t len = 0;
  explicit Attacker(const std::string& to) {
    fd = ::socket(AF_INET, SOCK_DGRAM, 0);
    dst = parse_udp_address(to, "test", len);
  }
  ~Attacker() { ::close(fd); }
  void send(const std::uint8_t* d, std::size_t n) const { ::sendto(fd, d, n, 0, reinterpret_cast<const sockaddr*>(&dst), len); }
};

// Waits (bounded) until pred() holds.
template <class P>
bool wait_for(P pred, double timeout_s = 3.0) {
  const auto t0 = std::chrono::steady_clock::now();
  while (!pred()) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > timeout_s) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

struct Received {
  std::vector<std::uint64_t> seqs;
  std::uint64_t corrupt = 0;
};
void drain_into(Endpoint& e, Received& r) {
  std::vector<double> ex(kValues), ev(kValues);
  e.drain([&](std::uint16_t sender, std::uint64_t seq, double, const double* x, const double* v, std::uint32_t n) {
    fill_state(sender, seq, ex, ev);
    for (std::uint32_t i = 0; i < n; ++i)
      if (x[i] != ex[i] || v[i] != ev[i]) ++r.corrupt;
    r.seqs.push_back(seq);
  });
}

// b sends genuine states seq = from..to (one per ms); returns what a received (bounded wait).
Received genuine(Link& l, std::uint64_t from, std::uint64_t to) {
  std::vector<double> x(kValues), v(kValues);
  Received r;
  for (std::uint64_t k = from; k <= to; ++k) {
    fill_state(1, k, x, v);
    l.b->push_state(k, monotonic_s(), x.data(), v.data());
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    drain_into(*l.a, r);
  }
  wait_for([&] {
    drain_into(*l.a, r);
    return r.seqs.size() >= to - from + 1;
  });
  return r;
}

std::uint64_t drops(const Endpoint& e, DropReason r) { return e.stats().drops[r]; }

// Station 0's configuration with an envelope: rest positions = what fill_state(1, k) sends at k = 10
// (returned in rest_x), offset bound 0.5 m, speed bound 2000 m/s.
EndpointConfig envelope_config(std::vector<double>& rest_x) {
  EndpointConfig ca = exchange_config(0, 1, kValues);
  std::vector<double> rv(kValues);
  rest_x.assign(kValues, 0.0);
  fill_state(1, 10, rest_x, rv);
  ca.envelope_rest_x = rest_x;
  ca.envelope_max_offset_m = 0.5;
  ca.envelope_max_speed_m_per_s = 2000.0;
  return ca;
}

}  // namespace

TEST_GROUP(Attack){};

TEST(Attack, AuthenticPacketFromAnotherAddressIsDroppedAsWrongSource) {
  Link l;
  // The attacker holds the key (a valid MAC) and claims to be station 1, from its own port.
  WireConfig w = exchange_wire(1);
  w.incarnation = l.b->incarnation();
  Encoder enc(w);
  std::vector<double> x(kValues, 0.05), v(kValues, 0.0);
  OutgoingState o;
  o.dest = 0;
  o.seq = 3;
  o.send_time_ns = monotonic_ns();
  o.value_count = kValues;
  o.x_hat = x.data();
  o.v_hat = v.data();
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  const std::size_t n = enc.encode_fragment(o, 0, d.data(), d.size());
  Attacker att(l.addr_a);
  att.send(d.data(), n);
  CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::wrong_source) == 1; }));
  const Received r = genuine(l, 1, 20);
  CHECK_EQUAL(20u, r.seqs.size());
  CHECK_EQUAL(0u, r.corrupt);
  CHECK_EQUAL(1u, l.a->stats().drops.total());
}

TEST(Attack, FarFutureSequenceFromAnAuthenticPeerIsDroppedAndGenuinePacketsStillArrive) {
  Link l;
  l.a->note_tick(100);  // the victim's own tick: the ceiling is 100 + 50
  Received r = genuine(l, 95, 100);
  CHECK_EQUAL(6u, r.seqs.size());
  std::vector<double> x(kValues), v(kValues);
  fill_state(1, 1'000'100, x, v);
  l.b->push_state(1'000'100, monotonic_s(), x.data(), v.data());  // valid MAC, far future
  const std::uint64_t frags = Encoder(exchange_wire(1)).fragment_count(kValues);  // every datagram of it
  CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::future_sequence) == frags; }));
  // Without the ceiling the forged sequence would move the replay window: every genuine packet
  // after it would be dropped as stale and the link frozen.
  r = genuine(l, 101, 130);
  CHECK_EQUAL(30u, r.seqs.size());
  CHECK_EQUAL(0u, r.corrupt);
  CHECK_EQUAL(0u, drops(*l.a, DropReason::stale));
  CHECK_EQUAL(frags, l.a->stats().drops.total());
}

TEST(Attack, ZeroLengthDatagramsAreCountedAndChangeNothing) {
  Link l;
  Attacker att(l.addr_a);
  std::uint8_t none = 0;
  for (int i = 0; i < 5; ++i) att.send(&none, 0);
  CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::zero_length) == 5; }));
  const Received r = genuine(l, 1, 10);
  CHECK_EQUAL(10u, r.seqs.size());
  CHECK_EQUAL(5u, l.a->stats().drops.total());
}

TEST(Attack, NonFiniteStateIsNeverSentTheSafeStateFlagIsInstead) {
  Link l;
  std::vector<double> x(kValues), v(kValues);
  fill_state(1, 7, x, v);
  x[5] = std::numeric_limits<double>::quiet_NaN();
  l.b->push_state(7, monotonic_s(), x.data(), v.data());
  CHECK_TRUE(wait_for([&] { return l.a->stats().peers[0].safe_state_packets == 1; }));
  Received r;
  drain_into(*l.a, r);
  CHECK_EQUAL(0u, r.seqs.size());  // nothing handed to the tick
  CHECK_TRUE(l.a->stats().peers[0].peer_safe_state);
  CHECK_EQUAL(1u, l.b->stats().tx_safe_state);
  // A station in safe state says so explicitly (finite state, flag set): not handed on either.
  fill_state(1, 8, x, v);
  l.b->push_state(8, monotonic_s(), x.data(), v.data(), /*safe_state=*/true);
  CHECK_TRUE(wait_for([&] { return l.a->stats().peers[0].safe_state_packets == 2; }));
  r = genuine(l, 9, 20);
  CHECK_EQUAL(12u, r.seqs.size());
  CHECK_EQUAL(0u, r.corrupt);
  CHECK_FALSE(l.a->stats().peers[0].peer_safe_state);
  CHECK_EQUAL(0u, l.a->stats().drops.total());
}

// The sender's proxy position reaches the receiver's PeerStats (for its live view) with its packet's
// sequence; a non-finite one is not sent (the state goes without it), so the newest known stays.
TEST(Attack, TheSendersProxyReachesThePeerStatsAndANonFiniteOneIsNotSent) {
  Link l;
  std::vector<double> x(kValues), v(kValues);
  const double proxy[3] = {0.0123, -0.0234, 0.0345};
  fill_state(1, 5, x, v);
  l.b->push_state(5, monotonic_s(), x.data(), v.data(), false, proxy);
  CHECK_TRUE(wait_for([&] { return l.a->stats().peers[0].has_proxy; }));
  PeerStats ps = l.a->stats().peers[0];
  CHECK_EQUAL(5u, ps.proxy_seq);
  for (std::size_t a = 0; a < 3; ++a) DOUBLES_EQUAL(proxy[a], ps.proxy_m[a], 0.0);
  const double bad[3] = {0.01, std::numeric_limits<double>::infinity(), 0.02};
  fill_state(1, 6, x, v);
  l.b->push_state(6, monotonic_s(), x.data(), v.data(), false, bad);
  CHECK_TRUE(wait_for([&] { return l.a->stats().peers[0].packets_received == 2; }));
  ps = l.a->stats().peers[0];
  CHECK_EQUAL(5u, ps.proxy_seq);
  DOUBLES_EQUAL(proxy[1], ps.proxy_m[1], 0.0);
  CHECK_EQUAL(0u, l.a->stats().drops.total());
}

TEST(Attack, StatesOutsideThePhysicalEnvelopeAreDropped) {
  std::vector<double> rx;
  Link l(envelope_config(rx));
  Received r = genuine(l, 10, 10);  // at rest: inside
  CHECK_EQUAL(1u, r.seqs.size());
  std::vector<double> x(rx), v(kValues, 0.0);
  x[4] += 0.6;  // one node 0.6 m from rest
  l.b->push_state(11, monotonic_s(), x.data(), v.data());
  x = rx;
  v[7] = 2500.0;  // one node too fast
  l.b->push_state(12, monotonic_s(), x.data(), v.data());
  CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::out_of_envelope) == 2; }));
  drain_into(*l.a, r);
  CHECK_EQUAL(1u, r.seqs.size());
  x[4] += 0.4;  // 0.4 m: inside
  v[7] = 1500.0;
  l.b->push_state(13, monotonic_s(), x.data(), v.data());
  CHECK_TRUE(wait_for([&] {
    drain_into(*l.a, r);
    return r.seqs.size() == 2;
  }));
  CHECK_EQUAL(2u, l.a->stats().drops.total());
}

TEST(Attack, FloodFromAnUnknownAddressIsRateLimitedAndTheNeighbourGetsThrough) {
  EndpointConfig ca = exchange_config(0, 1, kValues);
  ca.rx_rate_limit_per_s = 1000.0;  // burst 100 datagrams
  Link l(ca);
  Attacker att(l.addr_a);
  std::vector<std::uint8_t> junk(200);
  for (std::size_t i = 0; i < junk.size(); ++i) junk[i] = static_cast<std::uint8_t>(i * 13 + 1);
  const auto t0 = std::chrono::steady_clock::now();
  for (int burst = 0; burst < 30; ++burst) {  // 3000 datagrams, paced so the kernel's buffer keeps them
    for (int i = 0; i < 100; ++i) att.send(junk.data(), junk.size());
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  const Received r = genuine(l, 1, 20);
  const std::uint64_t genuine_datagrams = 20 * Encoder(exchange_wire(1)).fragment_count(kValues);
  // Everything the endpoint received is accounted for: the genuine datagrams, and drops.
  CHECK_TRUE(wait_for([&] {
    const EndpointStats s = l.a->stats();
    return s.datagrams_received == s.drops.total() + genuine_datagrams;
  }));
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK_EQUAL(20u, r.seqs.size());
  CHECK_EQUAL(0u, r.corrupt);
  const EndpointStats s = l.a->stats();
  CHECK_EQUAL(s.drops.total(), s.drops[DropReason::rate_limited] + s.drops[DropReason::garbled]);
  CHECK(s.drops[DropReason::rate_limited] >= 1000);
  // The token bucket let through at most its burst plus rate x elapsed datagrams to the decoder.
  CHECK_TEXT(static_cast<double>(s.drops[DropReason::garbled]) <= 100.0 + 1000.0 * elapsed + 1.0,
             ("garbled " + std::to_string(s.drops[DropReason::garbled]) + " in " + std::to_string(elapsed) + " s").c_str());
  CHECK_EQUAL(0u, s.peers[0].rate_limited);
}

TEST(Attack, AnAuthenticStateOutsideTheEnvelopeDoesNotUseUpItsSequence) {
  std::vector<double> rx;
  Link l(envelope_config(rx));
  std::vector<double> x(rx), v(kValues, 0.0);
  x[4] += 0.6;  // one node 0.6 m from rest, at the sequence the genuine packet will carry
  l.b->push_state(11, monotonic_s(), x.data(), v.data());
  CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::out_of_envelope) == 1; }));
  x = rx;  // the genuine packet of sequence 11 (and 12) afterwards: delivered
  l.b->push_state(11, monotonic_s(), x.data(), v.data());
  l.b->push_state(12, monotonic_s(), x.data(), v.data());
  Received r;
  CHECK_TRUE(wait_for([&] {
    drain_into(*l.a, r);
    return r.seqs.size() == 2;
  }));
  CHECK_EQUAL(11u, r.seqs[0]);
  CHECK_EQUAL(0u, drops(*l.a, DropReason::replayed));
  CHECK_EQUAL(1u, l.a->stats().drops.total());
}

TEST(Attack, WithACommonEpochTheSequenceCeilingHoldsBeforeTheFirstTick) {
  // Without a common epoch (baseline, same test): before note_tick an authentic far-future sequence
  // is accepted and every genuine packet after it is stale. With the session's epoch (start_at) the
  // ceiling follows the clock from the start: (now - epoch) / T + 50 ticks.
  for (const bool epoch : {false, true}) {
    EndpointConfig ca = exchange_config(0, 1, kValues);
    ca.tx_period_s = 0.002;
    if (epoch) ca.sequence_epoch_ns = monotonic_ns();  // sequence 0 now; the ceiling is ~50 for 0.1 s
    Link l(ca);
    std::vector<double> x(kValues), v(kValues);
    fill_state(1, 1'000'000, x, v);
    l.b->push_state(1'000'000, monotonic_s(), x.data(), v.data());
    const std::uint64_t frags = Encoder(exchange_wire(1)).fragment_count(kValues);
    if (epoch) {
      CHECK_TRUE(wait_for([&] { return drops(*l.a, DropReason::future_sequence) == frags; }));
    } else {
      Received r;
      CHECK_TRUE(wait_for([&] {
        drain_into(*l.a, r);
        return r.seqs.size() == 1;
      }));
    }
    const Received r = genuine(l, 1, 20);
    CHECK_EQUAL(epoch ? 20u : 0u, r.seqs.size());
    CHECK_EQUAL(0u, r.corrupt);
  }
}

namespace {
// A transport with `junk` datagrams already waiting (always readable: an eventfd holding 1) that
// records how many it had handed out when each send happened.
class BacklogTransport final : public Transport {
 public:
  explicit BacklogTransport(int junk) : left_(junk), fd_(::eventfd(1, EFD_NONBLOCK | EFD_CLOEXEC)) {}
  ~BacklogTransport() override { ::close(fd_); }
  int fd() const override { return fd_; }
  bool send_to(std::uint16_t, const std::uint8_t*, std::size_t) override {
    if (first_send_after_ < 0) first_send_after_ = read_.load();
    return true;
  }
  long receive(std::uint8_t* buf, std::size_t cap) override {
    if (left_ == 0 || cap < 100) return 0;
    --left_;
    ++read_;
    for (std::size_t i = 0; i < 100; ++i) buf[i] = static_cast<std::uint8_t>(i * 7 + 3);  // garbage
    return 100;
  }
  std::size_t max_datagram_bytes() const override { return 1400; }
  const char* name() const override { return "backlog"; }
  std::atomic<long> first_send_after_{-1};  // receives handed out before the first send

 private:
  std::atomic<int> left_;
  std::atomic<long> read_{0};
  int fd_;
};
}  // namespace

TEST(Attack, APushWaitingWhileAFloodIsReceivedIsSentAfterOneDatagramNotAfterTheBatch) {
  // 3000 junk datagrams are waiting when the I/O thread starts and a push is already queued: the
  // push leaves after at most the first datagram (before: after the whole batch of up to 4096, so a
  // flood held our own states back: echoes missing, round trips longer).
  auto t = std::make_unique<BacklogTransport>(3000);
  BacklogTransport* tp = t.get();
  Endpoint e(exchange_config(0, 1, kValues), std::move(t));
  std::vector<double> x(kValues, 0.0), v(kValues, 0.0);
  CHECK_TRUE(e.push_state(1, monotonic_s(), x.data(), v.data()));
  e.start();
  CHECK_TRUE(wait_for([&] { return tp->first_send_after_.load() >= 0; }));
  e.stop();
  CHECK_TEXT(tp->first_send_after_.load() <= 1, std::to_string(tp->first_send_after_.load()).c_str());
}
