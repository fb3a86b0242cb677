// Lifecycle on the wire and in the endpoint: incarnations (a restarted
// neighbour is accepted afresh, an older incarnation is dropped), fingerprints exchanged and
// compared field by field, round trips from our own send records, the clock offset to a
// neighbour (NTP-style), neighbour down/up events, and statistics read while the I/O thread runs.
#include <CppUTest/TestHarness.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "net/transport_udp.hpp"
#include "net/wire.hpp"
#include "tests/net/exchange_util.hpp"

using namespace haptic::net;
using namespace haptic::net::test;

namespace {

std::vector<std::vector<std::uint8_t>> encode_state(const Encoder& e, std::uint16_t dest, std::uint64_t seq,
                                                    const std::vector<double>& x) {
  OutgoingState o;
  o.dest = dest;
  o.seq = seq;
  o.send_time_ns = 1000 + static_cast<std::int64_t>(seq);
  o.value_count = static_cast<std::uint32_t>(x.size());
  o.x_hat = x.data();
  o.v_hat = x.data();
  std::vector<std::vector<std::uint8_t>> out;
  for (std::size_t f = 0; f < e.fragment_count(o.value_count); ++f) {
    std::vector<std::uint8_t> d(kDefaultDatagramBytes);
    d.resize(e.encode_fragment(o, f, d.data(), d.size()));
    out.push_back(d);
  }
  return out;
}

DecodeStatus decode_all(Decoder& dec, const std::vector<std::vector<std::uint8_t>>& dgs, DecodedState& st) {
  DecodeStatus s = DecodeStatus::dropped;
  for (const auto& d : dgs) s = dec.decode(d.data(), d.size(), st);
  return s;
}

// decode_all at receive time now_ns with the incarnation rule's quiet time (net.peer_silence_s' default).
constexpr std::int64_t kQuietNs = 250'000'000;
DecodeStatus decode_at(Decoder& dec, const std::vector<std::vector<std::uint8_t>>& dgs, DecodedState& st, std::int64_t now_ns) {
  DecodeLimits lim;
  lim.now_ns = now_ns;
  lim.incarnation_quiet_ns = kQuietNs;
  DecodeStatus s = DecodeStatus::dropped;
  for (const auto& d : dgs) s = dec.decode(d.data(), d.size(), st, lim);
  return s;
}
constexpr std::int64_t ms(std::int64_t t) { return t * 1'000'000; }

// The decoder (neighbour 1) found two different authentic datagrams with sequence seq: named, one drop.
void check_one_conflict(const Decoder& dec, std::uint64_t seq) {
  CHECK_TRUE(dec.incarnations(1).conflicting_datagrams);
  CHECK_EQUAL(seq, dec.incarnations(1).conflict_seq);
  CHECK_EQUAL(1u, dec.drops()[DropReason::key_compromise]);
}

WireConfig wire_of(std::uint16_t station, std::uint64_t incarnation) {
  WireConfig w = exchange_wire(station);
  w.incarnation = incarnation;
  return w;
}

// A station's UDP socket driven by hand (an Encoder/Decoder pair), to play a neighbour that
// echoes with chosen stamps.
struct HandPeer {
  UdpTransport udp{"127.0.0.1:0", {}};
  Encoder enc;
  Decoder dec;
  HandPeer(std::uint16_t self, std::uint16_t peer, std::uint32_t values)
      : enc(wire_of(self, 7)), dec(wire_of(self, 7), std::vector<std::uint16_t>{peer}, values) {}
  void aim(std::uint16_t port) { udp.set_peer({0, "127.0.0.1:" + std::to_string(port)}); }
  // Newest state received (false when none waiting).
  bool receive(DecodedState& st) {
    std::uint8_t buf[2048];
    bool got = false;
    for (int i = 0; i < 256; ++i) {
      const long n = udp.receive(buf, sizeof buf);
      if (n <= 0) break;
      DecodedState s;
      if (dec.decode(buf, static_cast<std::size_t>(n), s) == DecodeStatus::complete) {
        st = s;
        got = true;
      }
    }
    return got;
  }
  void send(const OutgoingState& o) {
    std::vector<std::uint8_t> d(kDefaultDatagramBytes);
    for (std::size_t f = 0; f < enc.fragment_count(o.value_count); ++f)
      udp.send_to(0, d.data(), enc.encode_fragment(o, f, d.data(), d.size()));
  }
};

// A state to station 0 that echoes echo_seq after holding it hold_ns.
OutgoingState echo_state(std::uint64_t seq, std::int64_t send_ns, std::uint64_t echo_seq, std::int64_t hold_ns,
                         const std::vector<double>& x) {
  OutgoingState o;
  o.dest = 0;
  o.seq = seq;
  o.send_time_ns = send_ns;
  o.has_echo = true;
  o.echo_seq = echo_seq;
  o.echo_hold_ns = hold_ns;
  o.value_count = static_cast<std::uint32_t>(x.size());
  o.x_hat = x.data();
  o.v_hat = x.data();
  return o;
}

std::unique_ptr<UdpTransport> udp_on(std::uint16_t port) {
  return std::make_unique<UdpTransport>("127.0.0.1:" + std::to_string(port), std::vector<UdpPeer>{});
}

// Two endpoints on loopback UDP ports the kernel picks, each aimed at the other.
struct LoopbackPair {
  std::unique_ptr<Endpoint> a, b;
  LoopbackPair(const EndpointConfig& ca, const EndpointConfig& cb) {
    auto ta = udp_on(0), tb = udp_on(0);
    ta->set_peer({cb.wire.station_id, "127.0.0.1:" + std::to_string(tb->local_port())});
    tb->set_peer({ca.wire.station_id, "127.0.0.1:" + std::to_string(ta->local_port())});
    a = std::make_unique<Endpoint>(ca, std::move(ta));
    b = std::make_unique<Endpoint>(cb, std::move(tb));
    a->start();
    b->start();
  }
};

// Pushes from both endpoints every 1 ms for `ms` ms, counting what `b` delivers per sender.
std::uint64_t pump(Endpoint& a, Endpoint* b, std::uint64_t& ka, std::uint64_t& kb, int ms, std::uint64_t* b_got = nullptr) {
  std::vector<double> x(a.value_count(), 0.5), v(a.value_count(), -0.5);
  std::uint64_t a_got = 0;
  for (int i = 0; i < ms; ++i) {
    a.push_state(++ka, monotonic_s(), x.data(), v.data());
    if (b) b->push_state(++kb, monotonic_s(), x.data(), v.data());
    a_got += a.drain([](auto...) {});
    if (b) {
      const std::size_t n = b->drain([](auto...) {});
      if (b_got) *b_got += n;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return a_got;
}

}  // namespace

TEST_GROUP(Incarnation) {
  const std::uint16_t peers[1] = {1};
  Decoder dec{wire_of(0, 1), peers, 99};
  std::vector<double> x = std::vector<double>(99, 0.25);
};

TEST(Incarnation, RestartedSenderIsAcceptedAfreshAndItsOldIncarnationIsDropped) {
  Encoder first{wire_of(1, 100)}, restarted{wire_of(1, 200)};
  DecodedState st;
  CHECK(decode_all(dec, encode_state(first, 0, 5000, x), st) == DecodeStatus::complete);
  CHECK_EQUAL(100u, st.incarnation);
  // The restarted process counts from 0 again: far older than the window, yet accepted.
  CHECK(decode_all(dec, encode_state(restarted, 0, 3, x), st) == DecodeStatus::complete);
  CHECK_EQUAL(200u, st.incarnation);
  CHECK(st.new_incarnation);
  CHECK_EQUAL(1u, dec.incarnation_changes());
  CHECK(decode_all(dec, encode_state(restarted, 0, 4, x), st) == DecodeStatus::complete);
  CHECK_FALSE(st.new_incarnation);
  // Replay of the old incarnation (even with a fresh sequence number) is dropped and counted.
  CHECK(decode_all(dec, encode_state(first, 0, 6000, x), st) == DecodeStatus::dropped);
  CHECK_EQUAL(2u, dec.drops()[DropReason::old_incarnation]);  // both datagrams of the packet
  // And within the new incarnation the replay window works as before.
  CHECK(decode_all(dec, encode_state(restarted, 0, 4, x), st) == DecodeStatus::dropped);
  CHECK_EQUAL(2u, dec.drops()[DropReason::replayed]);  // both datagrams
}

TEST(Incarnation, IncarnationIsAuthenticated) {
  Encoder first{wire_of(1, 100)};
  DecodedState st;
  CHECK(decode_all(dec, encode_state(first, 0, 50, x), st) == DecodeStatus::complete);
  auto d = encode_state(Encoder{wire_of(1, 101)}, 0, 1, x)[0];
  d[wire_offset::incarnation] ^= 0x40;  // raise the incarnation without the key
  CHECK(dec.decode(d.data(), d.size(), st) == DecodeStatus::dropped);
  CHECK_EQUAL(1u, dec.drops()[DropReason::bad_mac]);
  CHECK_EQUAL(0u, dec.incarnation_changes());
}

// The incarnation rule (DecodeLimits::incarnation_quiet_ns): a stolen key's forged restart while the
// real station talks is refused, and the real one speaking again makes two live incarnations.
TEST(Incarnation, AForgedRestartWhileTheRealOneTalksRefusesBothForTheRestOfTheRun) {
  Encoder real{wire_of(1, 100)}, forged{wire_of(1, 200)};
  DecodedState st;
  CHECK(decode_at(dec, encode_state(real, 0, 10, x), st, ms(1000)) == DecodeStatus::complete);
  // The newer incarnation 2 ms after the real one spoke: refused (not taken for a restart)...
  CHECK(decode_at(dec, encode_state(forged, 0, 1, x), st, ms(1002)) == DecodeStatus::dropped);
  CHECK_EQUAL(2u, dec.drops()[DropReason::incarnation_while_live]);  // both datagrams of the packet
  IncarnationWatch w = dec.incarnations(1);
  CHECK_EQUAL(100u, w.current);
  CHECK_EQUAL(200u, w.refused);
  CHECK_FALSE(w.compromised);
  CHECK_EQUAL(0u, dec.incarnation_changes());
  // ...and the real one speaking again (a new sequence) while it is live: two live incarnations.
  CHECK(decode_at(dec, encode_state(real, 0, 11, x), st, ms(1004)) == DecodeStatus::dropped);
  w = dec.incarnations(1);
  CHECK_TRUE(w.compromised);
  CHECK_EQUAL(ms(1004), w.compromised_ns);
  // Both refused from then on, whatever comes and however long after.
  CHECK(decode_at(dec, encode_state(real, 0, 12, x), st, ms(9000)) == DecodeStatus::dropped);
  CHECK(decode_at(dec, encode_state(forged, 0, 2, x), st, ms(9500)) == DecodeStatus::dropped);
  CHECK(decode_at(dec, encode_state(Encoder{wire_of(1, 300)}, 0, 1, x), st, ms(20000)) == DecodeStatus::dropped);
  CHECK_EQUAL(2u + 2u + 2u + 2u, dec.drops()[DropReason::key_compromise]);  // packet 11, then 3 more
  CHECK_EQUAL(1u, dec.completed_packets());
  CHECK_EQUAL(0u, dec.incarnation_changes());
}

TEST(Incarnation, ARestartIsAcceptedOnceTheOldIncarnationHasBeenSilentForTheQuietTime) {
  Encoder first{wire_of(1, 100)}, restarted{wire_of(1, 200)};
  DecodedState st;
  CHECK(decode_at(dec, encode_state(first, 0, 5000, x), st, ms(1000)) == DecodeStatus::complete);
  // A restart 0.1 s after the old one's last packet: too early (it might still be live)...
  CHECK(decode_at(dec, encode_state(restarted, 0, 1, x), st, ms(1100)) == DecodeStatus::dropped);
  CHECK_EQUAL(2u, dec.drops()[DropReason::incarnation_while_live]);
  // ...accepted once the old one has been silent for more than the quiet time (0.25 s).
  CHECK(decode_at(dec, encode_state(restarted, 0, 2, x), st, ms(1260)) == DecodeStatus::complete);
  CHECK_TRUE(st.new_incarnation);
  CHECK_EQUAL(200u, st.incarnation);
  CHECK(decode_at(dec, encode_state(restarted, 0, 3, x), st, ms(1262)) == DecodeStatus::complete);
  const IncarnationWatch w = dec.incarnations(1);
  CHECK_EQUAL(200u, w.current);
  CHECK_FALSE(w.compromised);
  CHECK_EQUAL(1u, dec.incarnation_changes());
}

// Cross-run replays under a shared key, or a late datagram of the process that restarted: an old
// incarnation alone is refused as such and never suspected as a second live one (else a replay
// would be a denial of service).
TEST(Incarnation, AnOldIncarnationAloneNeverMakesTwoLiveIncarnations) {
  Encoder earlier_run{wire_of(1, 50)}, first{wire_of(1, 100)}, restarted{wire_of(1, 200)};
  DecodedState st;
  CHECK(decode_at(dec, encode_state(first, 0, 10, x), st, ms(1000)) == DecodeStatus::complete);
  for (std::uint64_t q = 11; q < 20; ++q)  // an earlier run, new sequences, while the current one talks
    CHECK(decode_at(dec, encode_state(earlier_run, 0, q, x), st, ms(1000) + static_cast<std::int64_t>(q)) == DecodeStatus::dropped);
  CHECK(decode_at(dec, encode_state(restarted, 0, 1, x), st, ms(2000)) == DecodeStatus::complete);  // a real restart
  for (std::uint64_t q = 11; q < 20; ++q) {  // the old process's (replayed) datagrams in between the new one's
    CHECK(decode_at(dec, encode_state(first, 0, q, x), st, ms(2000) + static_cast<std::int64_t>(q)) == DecodeStatus::dropped);
    CHECK(decode_at(dec, encode_state(restarted, 0, q, x), st, ms(2000) + static_cast<std::int64_t>(q)) == DecodeStatus::complete);
  }
  CHECK_EQUAL(2u * 9u * 2u, dec.drops()[DropReason::old_incarnation]);
  CHECK_EQUAL(0u, dec.drops()[DropReason::key_compromise]);
  CHECK_FALSE(dec.incarnations(1).compromised);
  CHECK_EQUAL(0u, dec.incarnations(1).refused);
}

// A replay of the current incarnation's own packets cannot play the live second incarnation: only a
// sequence never seen is a sign of life, so a real restart with replays around it is still accepted.
TEST(Incarnation, ReplaysOfTheCurrentIncarnationCannotMakeItLookLiveNextToARestart) {
  Encoder first{wire_of(1, 100)}, restarted{wire_of(1, 200)};
  DecodedState st;
  std::vector<std::vector<std::vector<std::uint8_t>>> captured;
  for (std::uint64_t q = 1; q <= 5; ++q) {
    captured.push_back(encode_state(first, 0, q, x));
    CHECK(decode_at(dec, captured.back(), st, ms(1000) + static_cast<std::int64_t>(q)) == DecodeStatus::complete);
  }
  // The restarted process (0.1 s later) is refused for now; the old one's packets replayed meanwhile.
  CHECK(decode_at(dec, encode_state(restarted, 0, 1, x), st, ms(1100)) == DecodeStatus::dropped);
  for (const auto& c : captured) CHECK(decode_at(dec, c, st, ms(1102)) == DecodeStatus::dropped);
  CHECK_EQUAL(2u * 5u, dec.drops()[DropReason::replayed]);
  CHECK_FALSE(dec.incarnations(1).compromised);
  CHECK(decode_at(dec, encode_state(restarted, 0, 2, x), st, ms(1300)) == DecodeStatus::complete);
  CHECK_EQUAL(200u, dec.incarnations(1).current);
  CHECK_EQUAL(0u, dec.drops()[DropReason::key_compromise]);
}

// A stolen key within the same incarnation: the attacker signs the next sequences first (using up
// the genuine ones, which the replay window would refuse as replays). Two different authentic
// datagrams with one sequence and fragment are proof of a second key holder: key compromise
// suspected, as with two live incarnations (every datagram of the sender refused from then on).
TEST(Incarnation, TwoDifferentAuthenticDatagramsWithOneSequenceAreAKeyCompromise) {
  Encoder real{wire_of(1, 100)};
  DecodedState st;
  CHECK(decode_at(dec, encode_state(real, 0, 10, x), st, ms(1000)) == DecodeStatus::complete);
  const std::vector<double> forged_x(99, 0.5);
  for (std::uint64_t q = 11; q <= 20; ++q)  // the attacker, ahead of the real station (same incarnation)
    CHECK(decode_at(dec, encode_state(real, 0, q, forged_x), st, ms(1001)) == DecodeStatus::complete);
  CHECK_FALSE(dec.incarnations(1).compromised);  // nothing to tell them apart yet
  // The real station's packet 11: its first datagram has the sequence and fragment of an authentic one
  // with other content. Named, and its second datagram is refused with everything after it.
  CHECK(decode_at(dec, encode_state(real, 0, 11, x), st, ms(1003)) == DecodeStatus::dropped);
  const IncarnationWatch w = dec.incarnations(1);
  CHECK_TRUE(w.compromised);
  CHECK_TRUE(w.conflicting_datagrams);
  CHECK_EQUAL(11u, w.conflict_seq);
  CHECK_EQUAL(ms(1003), w.compromised_ns);
  CHECK_EQUAL(100u, w.current);
  CHECK_EQUAL(0u, w.refused);
  CHECK(decode_at(dec, encode_state(real, 0, 21, x), st, ms(1005)) == DecodeStatus::dropped);
  CHECK_EQUAL(2u + 2u, dec.drops()[DropReason::key_compromise]);
  CHECK_EQUAL(0u, dec.drops()[DropReason::replayed]);
  CHECK_EQUAL(11u, dec.completed_packets());
}

// The other order: the real packet first, the attacker's (same sequence, other content) after it.
TEST(Incarnation, AnAuthenticDatagramDifferingFromADeliveredOneIsAKeyCompromise) {
  Encoder real{wire_of(1, 100)};
  DecodedState st;
  for (std::uint64_t q = 10; q <= 20; ++q)
    CHECK(decode_at(dec, encode_state(real, 0, q, x), st, ms(1000)) == DecodeStatus::complete);
  auto forged = encode_state(real, 0, 12, std::vector<double>(99, 0.5));
  CHECK(dec.decode(forged[1].data(), forged[1].size(), st, DecodeLimits{}) == DecodeStatus::dropped);  // fragment 1
  check_one_conflict(dec, 12);
}

// The same with packets of one datagram (float32: the paper scene's default), which skip reassembly.
TEST(Incarnation, ASingleDatagramPacketsSequenceUsedUpFirstIsAKeyCompromise) {
  WireConfig w = wire_of(1, 100);
  w.encoding = ValueEncoding::float32;
  Encoder real{w};
  DecodedState st;
  CHECK_EQUAL(1u, real.fragment_count(99));
  CHECK(decode_at(dec, encode_state(real, 0, 11, std::vector<double>(99, 0.5)), st, ms(1000)) == DecodeStatus::complete);
  CHECK(decode_at(dec, encode_state(real, 0, 11, x), st, ms(1002)) == DecodeStatus::dropped);
  check_one_conflict(dec, 11);
}

// A partial packet: the attacker's first fragment of a sequence waits in reassembly; the real one's
// first fragment of that sequence is no duplicate of it but a second signer.
TEST(Incarnation, AConflictingFragmentOfAPartialPacketIsAKeyCompromise) {
  Encoder real{wire_of(1, 100)};
  DecodedState st;
  CHECK(decode_at(dec, encode_state(real, 0, 10, x), st, ms(1000)) == DecodeStatus::complete);
  const auto forged = encode_state(real, 0, 11, std::vector<double>(99, 0.5));
  CHECK(dec.decode(forged[0].data(), forged[0].size(), st, DecodeLimits{}) == DecodeStatus::fragment_stored);
  const auto genuine = encode_state(real, 0, 11, x);
  CHECK(dec.decode(genuine[0].data(), genuine[0].size(), st, DecodeLimits{}) == DecodeStatus::dropped);
  check_one_conflict(dec, 11);
}

// Identical datagrams again (a replay, or a network duplicate) stay replays, delivered or partial.
TEST(Incarnation, AnIdenticalReplayOfAnAuthenticDatagramStaysAReplay) {
  Encoder real{wire_of(1, 100)};
  DecodedState st;
  const auto p10 = encode_state(real, 0, 10, x), p11 = encode_state(real, 0, 11, x);
  CHECK(decode_at(dec, p10, st, ms(1000)) == DecodeStatus::complete);
  CHECK(dec.decode(p11[0].data(), p11[0].size(), st, DecodeLimits{}) == DecodeStatus::fragment_stored);
  for (int i = 0; i < 3; ++i) {
    CHECK(decode_at(dec, p10, st, ms(1001)) == DecodeStatus::dropped);
    CHECK(dec.decode(p11[0].data(), p11[0].size(), st, DecodeLimits{}) == DecodeStatus::dropped);
  }
  CHECK_EQUAL(3u * 3u, dec.drops()[DropReason::replayed]);
  CHECK_EQUAL(0u, dec.drops()[DropReason::key_compromise]);
  CHECK_FALSE(dec.incarnations(1).compromised);
  CHECK(dec.decode(p11[1].data(), p11[1].size(), st, DecodeLimits{}) == DecodeStatus::complete);
}

// A restarted sender counts its sequences afresh with other content: its old incarnation's
// datagrams are no evidence against the new one's.
TEST(Incarnation, ARestartedSendersReusedSequencesAreNoConflict) {
  Encoder first{wire_of(1, 100)}, restarted{wire_of(1, 200)};
  DecodedState st;
  for (std::uint64_t q = 1; q <= 5; ++q)
    CHECK(decode_at(dec, encode_state(first, 0, q, x), st, ms(1000)) == DecodeStatus::complete);
  const std::vector<double> other(99, 0.5);
  for (std::uint64_t q = 1; q <= 5; ++q)  // after the quiet time: a restart
    CHECK(decode_at(dec, encode_state(restarted, 0, q, other), st, ms(2000)) == DecodeStatus::complete);
  CHECK_FALSE(dec.incarnations(1).compromised);
  CHECK_EQUAL(0u, dec.drops()[DropReason::key_compromise]);
}

// An attacker jumping beyond the sequence ceiling uses up nothing (future_sequence, before the window
// moves) and is not named: the ceiling is our own tick, a genuine sender can be ahead of it.
TEST(Incarnation, AJumpBeyondTheSequenceCeilingUsesUpNothingAndIsNotNamed) {
  Encoder real{wire_of(1, 100)};
  DecodedState st;
  DecodeLimits lim;
  lim.max_sequence = 60;
  auto at = [&](const std::vector<std::vector<std::uint8_t>>& p) {
    DecodeStatus r = DecodeStatus::dropped;
    for (const auto& d : p) r = dec.decode(d.data(), d.size(), st, lim);
    return r;
  };
  CHECK(at(encode_state(real, 0, 10, x)) == DecodeStatus::complete);
  CHECK(at(encode_state(real, 0, 61, std::vector<double>(99, 0.5))) == DecodeStatus::dropped);
  CHECK_EQUAL(2u, dec.drops()[DropReason::future_sequence]);
  CHECK(at(encode_state(real, 0, 11, x)) == DecodeStatus::complete);
  lim.max_sequence = 70;
  CHECK(at(encode_state(real, 0, 61, x)) == DecodeStatus::complete);  // the genuine 61, later
  CHECK_FALSE(dec.incarnations(1).compromised);
}

TEST(Incarnation, NewIncarnationsGrowAcrossCalls) {
  const std::uint64_t a = new_incarnation();
  std::this_thread::sleep_for(std::chrono::milliseconds(1));
  CHECK(new_incarnation() > a);
}

TEST_GROUP(Fingerprints) {};

TEST(Fingerprints, RoundTripAndFieldByFieldDifference) {
  Fingerprint f;
  f.scene_nodes = 33;
  f.scene_hash = fingerprint_hash("scene-a", 7);
  f.period_ns = 2'000'000;
  f.gains_hash = fingerprint_hash("gains", 5);
  f.consensus_law = kConsensusLawPspm;
  f.tx_predict = 1;
  f.tx_deadband_hash = 0xBEEF;
  const std::uint16_t peers[1] = {1};
  Decoder dec{wire_of(0, 1), peers, 99};
  Encoder enc{wire_of(1, 9)};
  std::vector<std::uint8_t> d(200);
  d.resize(enc.encode_fingerprint(0, 3, 44, f, d.data(), d.size(), 21'500'000));  // our probing's bound to station 0: 21.5 ms
  CHECK_EQUAL(kHeaderBytes + kFingerprintBytes + kMacBytes, d.size());
  DecodedState st;
  CHECK(dec.decode(d.data(), d.size(), st) == DecodeStatus::fingerprint);
  CHECK(st.kind == PayloadKind::fingerprint);
  CHECK_EQUAL(std::string(""), fingerprint_difference(f, st.fingerprint));
  CHECK_EQUAL(21'500'000u, st.round_trip_bound_ns);  // carried, not part of the fingerprint
  LONGS_EQUAL(-1, st.loss_allowance_ticks);           // none given: none carried
  std::vector<std::uint8_t> e(200);
  e.resize(enc.encode_fingerprint(0, 4, 45, f, e.data(), e.size(), 21'500'000, nullptr, 0));
  CHECK(dec.decode(e.data(), e.size(), st) == DecodeStatus::fingerprint);
  LONGS_EQUAL(0, st.loss_allowance_ticks);  // an allowance of 0 is not "none"
  e.resize(200);
  e.resize(enc.encode_fingerprint(0, 5, 46, f, e.data(), e.size(), 21'500'000, nullptr, 7));
  CHECK(dec.decode(e.data(), e.size(), st) == DecodeStatus::fingerprint);
  LONGS_EQUAL(7, st.loss_allowance_ticks);  // our loss allowance travels with the bound
  Fingerprint g = f;
  g.scene_nodes = 27;
  g.scene_hash = fingerprint_hash("scene-b", 7);
  STRCMP_EQUAL("scene nodes: 33 here, 27 at the peer; scene data (hash) differs", fingerprint_difference(f, g).c_str());
  g = f;
  g.period_ns = 1'000'000;
  STRCMP_EQUAL("period_ns: 2000000 here, 1000000 at the peer", fingerprint_difference(f, g).c_str());
  g = f;
  g.gains_hash ^= 1;
  STRCMP_EQUAL("gains or shared station options (hash) differs", fingerprint_difference(f, g).c_str());
  g = f;
  g.protocol_version = kWireVersion + 1;
  STRCMP_EQUAL(("protocol version: " + std::to_string(kWireVersion) + " here, " + std::to_string(kWireVersion + 1) + " at the peer").c_str(),
               fingerprint_difference(f, g).c_str());
  // The coupling law travels and is compared field by field (a decoded copy of f matched above).
  g = f;
  g.consensus_law = kConsensusLawEq18;
  STRCMP_EQUAL("consensus passivity (station.consensus_passivity): pspm here, eq18 at the peer", fingerprint_difference(f, g).c_str());
  g = f;
  g.tx_predict = 0;
  STRCMP_EQUAL("predictive deadband (station.tx_predict): on here, off at the peer", fingerprint_difference(f, g).c_str());
  g = f;
  g.tx_deadband_hash = 0;
  STRCMP_EQUAL("transmission deadband (station.tx_deadband_mm, station.tx_max_interval_ticks; hash) differs", fingerprint_difference(f, g).c_str());
  // A changed field without the key fails the MAC.
  auto bad = d;
  bad[kHeaderBytes + 4] ^= 1;
  CHECK(dec.decode(bad.data(), bad.size(), st) == DecodeStatus::dropped);
  CHECK_EQUAL(1u, dec.drops()[DropReason::bad_mac]);
}

TEST(Fingerprints, StationsWithDifferentScenesSeeWhichFieldDiffers) {
  // Two endpoints over loopback with 33- and 27-node scenes: their state packets never reach
  // the other's tick (wrong size), but each learns the other's fingerprint and can say why.
  auto ca = exchange_config(0, 1, 99), cb = exchange_config(1, 0, 81);
  ca.fingerprint.scene_nodes = 33;
  ca.fingerprint.scene_hash = fingerprint_hash("33-node ball", 12);
  ca.fingerprint.period_ns = 2'000'000;
  cb.fingerprint = ca.fingerprint;
  cb.fingerprint.scene_nodes = 27;
  cb.fingerprint.scene_hash = fingerprint_hash("27-node ball", 12);
  LoopbackPair pair(ca, cb);
  Endpoint &a = *pair.a, &b = *pair.b;
  std::vector<double> xa(99, 1.0), xb(81, 1.0);
  for (std::uint64_t k = 1; k <= 60; ++k) {
    a.push_state(k, monotonic_s(), xa.data(), xa.data());
    b.push_state(k, monotonic_s(), xb.data(), xb.data());
    a.drain([](auto...) {});
    b.drain([](auto...) {});
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  a.stop();
  b.stop();
  const EndpointStats sa = a.stats(), sb = b.stats();
  CHECK(sa.peers[0].has_fingerprint);
  CHECK(sb.peers[0].has_fingerprint);
  STRCMP_EQUAL("scene nodes: 33 here, 27 at the peer; scene data (hash) differs",
               fingerprint_difference(ca.fingerprint, sa.peers[0].fingerprint).c_str());
  STRCMP_EQUAL("scene nodes: 27 here, 33 at the peer; scene data (hash) differs",
               fingerprint_difference(cb.fingerprint, sb.peers[0].fingerprint).c_str());
}

TEST_GROUP(Lifecycle) {};

TEST(Lifecycle, RestartedNeighbourIsAcceptedAndItsSilenceAndReturnAreCounted) {
  auto ta = udp_on(0), tb = udp_on(0);
  const std::uint16_t port_b = tb->local_port();
  ta->set_peer({1, "127.0.0.1:" + std::to_string(port_b)});
  tb->set_peer({0, "127.0.0.1:" + std::to_string(ta->local_port())});
  auto ca = exchange_config(0, 1, 99), cb = exchange_config(1, 0, 99);
  ca.peer_silence_s = cb.peer_silence_s = 0.1;
  Endpoint a(ca, std::move(ta));
  a.start();
  std::uint64_t ka = 0, kb = 0;
  std::uint64_t got_from_first = 0, got_from_second = 0;
  {
    auto b = std::make_unique<Endpoint>(cb, std::move(tb));
    b->start();
    kb = 5000;  // the first incarnation has been running a while
    got_from_first = pump(a, b.get(), ka, kb, 150);
    b->stop();
  }  // "SIGKILL": gone without a word
  pump(a, nullptr, ka, kb, 250);  // silence: a marks it down
  const EndpointStats mid = a.stats();
  // Restart on the same address: sequence numbers from 1 again, a new incarnation.
  auto tb3 = udp_on(port_b);
  // a's port: ask the kernel through the fd a's transport owns.
  sockaddr_in sa{};
  socklen_t sl = sizeof sa;
  ::getsockname(a.transport().fd(), reinterpret_cast<sockaddr*>(&sa), &sl);
  tb3->set_peer({0, "127.0.0.1:" + std::to_string(ntohs(sa.sin_port))});
  Endpoint b2(cb, std::move(tb3));
  b2.start();
  kb = 0;
  got_from_second = pump(a, &b2, ka, kb, 200);
  b2.stop();
  a.stop();
  const EndpointStats s = a.stats();
  CHECK(got_from_first > 100);
  CHECK(got_from_second > 150);  // accepted although its sequence numbers are 5000 lower
  CHECK_EQUAL(1u, s.peers[0].incarnation_changes);
  CHECK_EQUAL(0u, s.drops[DropReason::stale]);
  CHECK_FALSE(mid.peers[0].up);
  CHECK_EQUAL(1u, mid.peers[0].down_events);
  CHECK(s.peers[0].up);
  CHECK_EQUAL(2u, s.peers[0].up_events);
  CHECK(s.peers[0].rtt_samples > 100);
}

TEST(Lifecycle, RoundTripsComeFromOurOwnSendRecordsAndGiveTheClockOffset) {
  // A hand-driven neighbour whose clock runs 0.3 s ahead and which claims an absurd echo
  // stamp cannot shorten our round trip; the offset comes out as 0.3 s.
  HandPeer h(1, 0, 99);
  auto ta = udp_on(0);
  ta->set_peer({1, "127.0.0.1:" + std::to_string(h.udp.local_port())});
  h.aim(ta->local_port());
  Endpoint a(exchange_config(0, 1, 99), std::move(ta));
  a.start();
  std::vector<double> x(99, 0.1);
  const std::int64_t ahead_ns = 300'000'000;
  std::uint64_t replies = 0;
  for (std::uint64_t k = 1; k <= 300; ++k) {
    a.push_state(k, monotonic_s(), x.data(), x.data());
    a.drain([](auto...) {});
    DecodedState st;
    const auto deadline = monotonic_ns() + 20'000'000;
    bool got = false;
    while (!(got = h.receive(st)) && monotonic_ns() < deadline) std::this_thread::sleep_for(std::chrono::microseconds(50));
    if (got) {
      const std::int64_t hold_ns = 200'000;  // "we held it 0.2 ms"
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      h.send(echo_state(k, monotonic_ns() + ahead_ns, st.seq, hold_ns, x));
      ++replies;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  // An echo of a sequence we never sent: no sample.
  h.send(echo_state(10'000, monotonic_ns(), 77'777, 0, x));
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  a.stop();
  const PeerStats p = a.stats().peers[0];
  CHECK(replies > 250);
  CHECK(p.rtt_samples > 200);
  CHECK_EQUAL(1u, p.echoes_unmatched);
  CHECK(p.rtt_min_s >= 200e-6);  // covers at least the hold we slept: measured on our clock
  CHECK(p.rtt_max_s < 0.25);     // and was never computed from the neighbour's clock (0.3 s off)
  DOUBLES_EQUAL(0.3, p.clock_offset_s, 0.002);
  CHECK(p.clock_offset_samples > 200);
}

TEST(Lifecycle, TwoStationsOnOneHostSeeNoClockOffset) {
  LoopbackPair pair(exchange_config(0, 1, 99), exchange_config(1, 0, 99));
  Endpoint &a = *pair.a, &b = *pair.b;
  std::uint64_t ka = 0, kb = 0;
  pump(a, &b, ka, kb, 200);
  a.stop();
  b.stop();
  const PeerStats p = a.stats().peers[0];
  CHECK(p.clock_offset_samples > 100);
  // Same CLOCK_MONOTONIC: the estimate's error is at most half its sample's path time.
  CHECK(std::abs(p.clock_offset_s) <= p.clock_offset_rtt_s / 2 + 1e-6);
  CHECK(std::abs(p.clock_offset_s) < 0.002);
}

TEST(Lifecycle, StatisticsAreReadWhileTheIoThreadRunsWithoutStoppingIt) {
  // stats() from another thread, as fast as it can, while the exchange goes on: every packet
  // still arrives (the reader never holds the I/O thread) and counters only grow.
  LoopbackPair pair(exchange_config(0, 1, 99), exchange_config(1, 0, 99));
  Endpoint &a = *pair.a, &b = *pair.b;
  std::atomic<bool> done{false};
  std::uint64_t reads = 0, went_back = 0;
  std::thread reader([&] {
    std::uint64_t last = 0;
    while (!done.load()) {
      const EndpointStats s = a.stats();
      if (s.peers[0].packets_received < last) ++went_back;
      last = s.peers[0].packets_received;
      ++reads;
    }
  });
  const ExchangeResult r = exchange(a, b, 0, 1, 300);
  done = true;
  reader.join();
  a.stop();
  b.stop();
  CHECK(r.received[0] >= 300);
  CHECK_EQUAL(0u, r.corrupt[0]);
  CHECK(reads > 100);
  CHECK_EQUAL(0u, went_back);
  CHECK(a.stats().peers[0].packets_received >= 300);
}
