// Wire format: round trip, every bad-input class dropped and counted without state change,
// fragmentation and allocation-free reassembly.
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <system_error>

#include <sodium.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <vector>

#include "net/impairment.hpp"
#include "net/wire.hpp"
#include "tests/support/alloc_counter.hpp"

using namespace haptic::net;

namespace {

SessionKey test_key(std::uint8_t salt = 0) {
  SessionKey k;
  for (std::size_t i = 0; i < k.bytes.size(); ++i) k.bytes[i] = static_cast<std::uint8_t>(i * 7 + 1 + salt);
  return k;
}

WireConfig cfg_for(std::uint16_t station, ValueEncoding enc = ValueEncoding::float64) {
  WireConfig c;
  c.session_id = 0xC0FFEE;
  c.station_id = station;
  c.encoding = enc;
  c.key = test_key();
  return c;
}

struct Scene {
  std::uint32_t count;
  std::vector<double> x, v;
  explicit Scene(std::uint32_t nodes) : count(3 * nodes), x(count), v(count) {
    for (std::uint32_t i = 0; i < count; ++i) {
      x[i] = 0.01 * i - 0.3 + 1e-9 * i * i;
      v[i] = -0.002 * i + 0.5;
    }
  }
  OutgoingState out(std::uint16_t dest, std::uint64_t seq) const {
    OutgoingState o;
    o.dest = dest;
    o.seq = seq;
    o.send_time_ns = 123456789 + static_cast<std::int64_t>(seq);
    o.has_echo = true;
    o.echo_seq = seq / 2;
    o.echo_hold_ns = 987654321;
    o.value_count = count;
    o.x_hat = x.data();
    o.v_hat = v.data();
    return o;
  }
};

// Encodes one packet into a list of datagrams.
std::vector<std::vector<std::uint8_t>> encode_all(const Encoder& e, const OutgoingState& o) {
  std::vector<std::vector<std::uint8_t>> out;
  for (std::size_t f = 0; f < e.fragment_count(o.value_count); ++f) {
    std::vector<std::uint8_t> d(kDefaultDatagramBytes);
    const std::size_t n = e.encode_fragment(o, f, d.data(), d.size());
    d.resize(n);
    out.push_back(d);
  }
  return out;
}

}  // namespace

TEST_GROUP(Wire) {
  const std::uint16_t peers[2] = {1, 2};
  Encoder enc{cfg_for(1)};
  Decoder dec{cfg_for(0), peers, 3 * 3000};
  Scene scene{33};
};

TEST(Wire, RoundTripOf33NodeSceneIsExactInFloat64) {
  const auto dgs = encode_all(enc, scene.out(0, 42));
  CHECK_EQUAL(2u, dgs.size());  // 1608 payload bytes need two 1400-byte datagrams
  DecodedState st;
  CHECK(dec.decode(dgs[0].data(), dgs[0].size(), st) == DecodeStatus::fragment_stored);
  CHECK(dec.decode(dgs[1].data(), dgs[1].size(), st) == DecodeStatus::complete);
  CHECK_EQUAL(1, st.sender);
  CHECK_EQUAL(42u, st.seq);
  CHECK_EQUAL(123456789 + 42, st.send_time_ns);
  CHECK(st.has_echo);
  CHECK_EQUAL(21u, st.echo_seq);
  CHECK_EQUAL(987654321, st.echo_hold_ns);
  std::vector<double> x(scene.count), v(scene.count);
  st.copy_out(x.data(), v.data());
  MEMCMP_EQUAL(scene.x.data(), x.data(), 8 * scene.count);
  MEMCMP_EQUAL(scene.v.data(), v.data(), 8 * scene.count);
  CHECK_EQUAL(0u, dec.drops().total());
}

TEST(Wire, Float32FitsOneDatagramAndKeepsSevenDigits) {
  Encoder e32{cfg_for(1, ValueEncoding::float32)};
  const auto dgs = encode_all(e32, scene.out(0, 1));
  CHECK_EQUAL(1u, dgs.size());
  CHECK_EQUAL(kHeaderBytes + (2 * 99 + kProxyValues) * 4 + kMacBytes, dgs[0].size());
  DecodedState st;
  CHECK(dec.decode(dgs[0].data(), dgs[0].size(), st) == DecodeStatus::complete);
  std::vector<double> x(scene.count), v(scene.count);
  st.copy_out(x.data(), v.data());
  for (std::uint32_t i = 0; i < scene.count; ++i) {
    DOUBLES_EQUAL(scene.x[i], x[i], 1e-7);
    DOUBLES_EQUAL(scene.v[i], v[i], 1e-7);
  }
}

TEST(Wire, ThreeThousandNodeSceneIsFragmentedAndReassembledWithoutAllocation) {
  Scene big(3000);
  const auto dgs = encode_all(enc, big.out(0, 7));
  CHECK_EQUAL((2u * 9000u * 8u + enc.stride() - 1) / enc.stride(), dgs.size());
  // Deliver out of order (reverse) to exercise the bitmap; count allocations in decode.
  DecodedState st;
  DecodeStatus last = DecodeStatus::dropped;
  std::uint64_t allocs = 0;
  {
    haptic::test::AllocationCounter counter;
    for (std::size_t i = dgs.size(); i-- > 0;) last = dec.decode(dgs[i].data(), dgs[i].size(), st);
    allocs = counter.allocations();
  }
  CHECK_EQUAL(0u, allocs);
  CHECK(last == DecodeStatus::complete);
  std::vector<double> x(big.count), v(big.count);
  st.copy_out(x.data(), v.data());
  MEMCMP_EQUAL(big.x.data(), x.data(), 8 * big.count);
  MEMCMP_EQUAL(big.v.data(), v.data(), 8 * big.count);
}

// The ~16k-node scene (the 16,703-node ball) in float32 takes more than 256 datagrams of 1400 bytes
// (306): every fragment index up to kMaxFragments - 1 is held by the reassembly bitmap, delivered
// in reverse order, without allocation.
TEST(Wire, ASixteenThousandNodeSceneTakesMoreThan256DatagramsAndIsReassembled) {
  Scene big(16703);
  Encoder e32{cfg_for(1, ValueEncoding::float32)};
  Decoder d{cfg_for(0), peers, big.count};
  const auto dgs = encode_all(e32, big.out(0, 9));
  CHECK_EQUAL(306u, dgs.size());
  DecodedState st;
  DecodeStatus last = DecodeStatus::dropped;
  std::uint64_t allocs = 0;
  {
    haptic::test::AllocationCounter counter;
    for (std::size_t i = dgs.size(); i-- > 0;) {
      last = d.decode(dgs[i].data(), dgs[i].size(), st);
      if (i > 0) CHECK(last == DecodeStatus::fragment_stored);
    }
    allocs = counter.allocations();
  }
  CHECK_EQUAL(0u, allocs);
  CHECK(last == DecodeStatus::complete);
  CHECK_EQUAL(0u, d.drops().total());
  std::vector<double> x(big.count), v(big.count);
  st.copy_out(x.data(), v.data());
  for (std::uint32_t i = 0; i < big.count; ++i) {
    CHECK_EQUAL(static_cast<double>(static_cast<float>(big.x[i])), x[i]);
    CHECK_EQUAL(static_cast<double>(static_cast<float>(big.v[i])), v[i]);
  }
}

TEST(Wire, EncodeDoesNotAllocate) {
  std::vector<std::uint8_t> buf(kDefaultDatagramBytes);
  const auto o = scene.out(0, 3);
  std::uint64_t allocs = 0;
  std::size_t n = 0;
  {
    haptic::test::AllocationCounter counter;
    n = enc.encode_fragment(o, 0, buf.data(), buf.size());
    allocs = counter.allocations();
  }
  CHECK(n > 0);
  CHECK_EQUAL(0u, allocs);
  CHECK_EQUAL(0u, enc.encode_fragment(o, 0, buf.data(), 100));  // too small a buffer
  CHECK_EQUAL(0u, enc.encode_fragment(o, 5, buf.data(), buf.size()));  // no such fragment
}

TEST(Wire, InterleavedPacketsReassembleIndependently) {
  const auto a = encode_all(enc, scene.out(0, 10));
  const auto b = encode_all(enc, scene.out(0, 11));
  DecodedState st;
  CHECK(dec.decode(a[0].data(), a[0].size(), st) == DecodeStatus::fragment_stored);
  CHECK(dec.decode(b[1].data(), b[1].size(), st) == DecodeStatus::fragment_stored);
  CHECK(dec.decode(b[0].data(), b[0].size(), st) == DecodeStatus::complete);
  CHECK_EQUAL(11u, st.seq);
  CHECK(dec.decode(a[1].data(), a[1].size(), st) == DecodeStatus::complete);  // reordered: still accepted
  CHECK_EQUAL(10u, st.seq);
}

TEST(Wire, PartialPacketsAreEvictedOldestFirstAndCounted) {
  DecodedState st;
  for (std::uint64_t s = 100; s < 105; ++s) {  // 5 partial packets, 4 slots per peer
    const auto d = encode_all(enc, scene.out(0, s));
    CHECK(dec.decode(d[0].data(), d[0].size(), st) == DecodeStatus::fragment_stored);
  }
  CHECK_EQUAL(1u, dec.drops()[DropReason::reassembly_evicted]);
  const auto first = encode_all(enc, scene.out(0, 100));  // its slot was reused
  CHECK(dec.decode(first[1].data(), first[1].size(), st) == DecodeStatus::fragment_stored);
  const auto last = encode_all(enc, scene.out(0, 104));
  CHECK(dec.decode(last[1].data(), last[1].size(), st) == DecodeStatus::complete);
}

// ---- bad input: each class dropped, counted under its reason, and no state change ----------

namespace {
// After a bad datagram, a fresh valid packet must still decode exactly.
void check_still_healthy(Decoder& dec, const Encoder& enc, const Scene& scene, std::uint64_t seq) {
  const auto dgs = encode_all(enc, scene.out(0, seq));
  DecodedState st;
  DecodeStatus s = DecodeStatus::dropped;
  for (const auto& d : dgs) s = dec.decode(d.data(), d.size(), st);
  CHECK(s == DecodeStatus::complete);
  std::vector<double> x(scene.count), v(scene.count);
  st.copy_out(x.data(), v.data());
  MEMCMP_EQUAL(scene.x.data(), x.data(), 8 * scene.count);
}

void expect_drop(Decoder& dec, const std::vector<std::uint8_t>& d, DropReason why) {
  const auto before = dec.drops();
  DecodedState st;
  CHECK(dec.decode(d.data(), d.size(), st) == DecodeStatus::dropped);
  CHECK_EQUAL(before[why] + 1, dec.drops()[why]);
  CHECK_EQUAL(before.total() + 1, dec.drops().total());
}
}  // namespace

TEST(Wire, TruncatedDatagramsAreDropped) {
  const auto d = encode_all(enc, scene.out(0, 1))[0];
  for (std::size_t n : {0ul, 1ul, 10ul, kHeaderBytes, kHeaderBytes + kMacBytes - 1, d.size() - 1}) {
    std::vector<std::uint8_t> t(d.begin(), d.begin() + static_cast<long>(n));
    expect_drop(dec, t, DropReason::truncated);
  }
  DecodedState st;
  CHECK(dec.decode(nullptr, 100, st) == DecodeStatus::dropped);
  check_still_healthy(dec, enc, scene, 1);
}

TEST(Wire, OversizedDatagramIsDropped) {
  std::vector<std::uint8_t> d = encode_all(enc, scene.out(0, 1))[0];
  d.resize(kDefaultDatagramBytes + 1);
  expect_drop(dec, d, DropReason::oversized);
  check_still_healthy(dec, enc, scene, 1);
}

TEST(Wire, GarbledDatagramsAreDropped) {
  auto d = encode_all(enc, scene.out(0, 1))[0];
  auto bad_magic = d;
  bad_magic[0] ^= 0xFF;
  expect_drop(dec, bad_magic, DropReason::garbled);
  auto longer = encode_all(enc, scene.out(0, 1))[1];
  longer.push_back(0);  // length no longer matches frag_len
  expect_drop(dec, longer, DropReason::garbled);
  // Every single-bit flip anywhere must be dropped (by some check) and never accepted.
  DecodedState st;
  for (std::size_t byte = 0; byte < d.size(); ++byte) {
    auto g = d;
    g[byte] ^= 0x10;
    CHECK(dec.decode(g.data(), g.size(), st) == DecodeStatus::dropped);
  }
  check_still_healthy(dec, enc, scene, 1);
}

TEST(Wire, ForgedDatagramWithWrongKeyFailsMac) {
  WireConfig forger = cfg_for(1);
  forger.key = test_key(99);
  Encoder evil{forger};
  const auto d = encode_all(evil, scene.out(0, 1))[0];
  expect_drop(dec, d, DropReason::bad_mac);
  auto tampered = encode_all(enc, scene.out(0, 1))[0];
  tampered[kHeaderBytes + 5] ^= 1;  // payload bit
  expect_drop(dec, tampered, DropReason::bad_mac);
  check_still_healthy(dec, enc, scene, 1);
}

TEST(Wire, ReplayedAndStaleDatagramsAreDropped) {
  const auto p5 = encode_all(enc, scene.out(0, 5));
  DecodedState st;
  for (const auto& d : p5) dec.decode(d.data(), d.size(), st);
  expect_drop(dec, p5[0], DropReason::replayed);
  expect_drop(dec, p5[1], DropReason::replayed);
  // A fragment delivered twice while its packet is still partial.
  const auto p6 = encode_all(enc, scene.out(0, 6));
  dec.decode(p6[0].data(), p6[0].size(), st);
  expect_drop(dec, p6[0], DropReason::replayed);
  // Far ahead, then an old one beyond the window.
  check_still_healthy(dec, enc, scene, 5 + Decoder::kReplayWindow + 10);
  expect_drop(dec, encode_all(enc, scene.out(0, 7))[0], DropReason::stale);
  check_still_healthy(dec, enc, scene, 5 + Decoder::kReplayWindow + 9);  // reordered, inside window
}

TEST(Wire, WrongVersionSessionSenderAndDestinationAreDropped) {
  auto d = encode_all(enc, scene.out(0, 1))[0];
  auto v = d;
  v[wire_offset::version] = 1;  // a v1 station (no incarnation in its header)
  expect_drop(dec, v, DropReason::wrong_version);

  WireConfig other_session = cfg_for(1);
  other_session.session_id = 7;
  expect_drop(dec, encode_all(Encoder{other_session}, scene.out(0, 1))[0], DropReason::wrong_session);
  expect_drop(dec, encode_all(Encoder{cfg_for(9)}, scene.out(0, 1))[0], DropReason::unknown_sender);
  expect_drop(dec, encode_all(enc, scene.out(3, 1))[0], DropReason::wrong_destination);
  check_still_healthy(dec, enc, scene, 1);
}

TEST(Wire, AuthenticButInconsistentFieldsAreGarbled) {
  // A key holder writing nonsense in the fragment fields: edit, then re-MAC with the real key.
  const auto d = encode_all(enc, scene.out(0, 1))[0];
  auto remac = [](std::vector<std::uint8_t> g) {
    const std::size_t body = g.size() - kMacBytes;
    const auto k = test_key();
    crypto_generichash(g.data() + body, kMacBytes, g.data(), body, k.bytes.data(), k.bytes.size());
    return g;
  };
  auto edit16 = [&](std::size_t off, std::uint16_t val) {
    auto g = d;
    std::memcpy(g.data() + off, &val, 2);
    return remac(g);
  };
  auto edit32 = [&](std::size_t off, std::uint32_t val) {
    auto g = d;
    std::memcpy(g.data() + off, &val, 4);
    return remac(g);
  };
  expect_drop(dec, edit16(wire_offset::frag_index, 2), DropReason::garbled);    // index >= count
  expect_drop(dec, edit16(wire_offset::frag_count, 0), DropReason::garbled);
  expect_drop(dec, edit16(wire_offset::frag_count, 3), DropReason::garbled);    // disagrees with size
  expect_drop(dec, edit16(wire_offset::frag_stride, 7), DropReason::garbled);   // not whole values
  expect_drop(dec, edit32(wire_offset::frag_offset, 8), DropReason::garbled);   // not index*stride
  expect_drop(dec, edit32(wire_offset::value_count, 0), DropReason::garbled);
  expect_drop(dec, edit32(wire_offset::value_count, 3 * 3001), DropReason::too_large);
  auto kind = d;
  kind[wire_offset::kind] = 9;
  expect_drop(dec, remac(kind), DropReason::garbled);
  auto flags = d;
  flags[wire_offset::flags] |= 0x80;
  expect_drop(dec, remac(flags), DropReason::garbled);
  // Second fragment of a packet whose first fragment declared another layout.
  const auto p2 = encode_all(enc, scene.out(0, 2));
  DecodedState st;
  CHECK(dec.decode(p2[0].data(), p2[0].size(), st) == DecodeStatus::fragment_stored);
  WireConfig c32 = cfg_for(1, ValueEncoding::float32);
  const auto other = encode_all(Encoder{c32}, Scene(200).out(0, 2));
  CHECK(other.size() >= 2);
  expect_drop(dec, other[1], DropReason::garbled);
  CHECK(dec.decode(p2[1].data(), p2[1].size(), st) == DecodeStatus::complete);
  MEMCMP_EQUAL(d.data() + kHeaderBytes, p2[0].data() + kHeaderBytes, 8);  // payload identical across seqs
  check_still_healthy(dec, enc, scene, 3);
}

TEST(Wire, SessionKeyParsesHexAndRejectsGarbage) {
  const auto k = SessionKey::from_hex("000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1F");
  CHECK_EQUAL(0x1F, k.bytes[31]);
  CHECK_THROWS(std::invalid_argument, SessionKey::from_hex("00"));
  CHECK_THROWS(std::invalid_argument,
               SessionKey::from_hex("zz0102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f"));
}

TEST(Wire, ReplayWindowMatchesAReferenceModelOnRandomArrivals) {
  // Single-datagram packets (float32, 33 nodes); random jumps forward and back, duplicates.
  Encoder e32{cfg_for(1, ValueEncoding::float32)};
  std::vector<std::uint8_t> buf(kDefaultDatagramBytes);
  std::set<std::uint64_t> seen;
  std::uint64_t newest = 0, mismatches = 0;
  bool any = false;
  haptic::net::Rng rng(2024);
  std::uint64_t cursor = 5000;
  for (int i = 0; i < 20000; ++i) {
    const std::uint64_t r = rng.next() % 100;
    if (r < 60) cursor += 1;
    else if (r < 70) cursor += rng.next() % 1500;                        // jump ahead (maybe past the window)
    const std::uint64_t back = r >= 70 ? rng.next() % 1300 : 0;          // late or duplicate
    const std::uint64_t seq = cursor > back ? cursor - back : cursor;
    const std::size_t n = e32.encode_fragment(scene.out(0, seq), 0, buf.data(), buf.size());
    DecodedState st;
    const bool accepted = dec.decode(buf.data(), n, st) == DecodeStatus::complete;
    const bool model = !seen.count(seq) && (!any || seq > newest || newest - seq < Decoder::kReplayWindow);
    if (accepted != model) ++mismatches;
    if (model) {
      seen.insert(seq);
      if (!any || seq > newest) newest = seq;
      any = true;
    }
  }
  CHECK_EQUAL(0u, mismatches);
  std::printf("\n  replay model: %llu accepted, %llu replayed, %llu stale\n", (unsigned long long)dec.completed_packets(), (unsigned long long)dec.drops()[DropReason::replayed], (unsigned long long)dec.drops()[DropReason::stale]);
  CHECK(dec.drops()[DropReason::replayed] > 50);
  CHECK(dec.drops()[DropReason::stale] > 200);
  CHECK(dec.completed_packets() > 10000);
}

// The sender's proxy position travels after x_hat and v_hat (flag kFlagProxy): exact in float64,
// to float precision in float32; a push without one (probing) or in safe state carries no flag.
TEST(Wire, TheProxyPositionTravelsWithTheStateWhenGiven) {
  const double proxy[3] = {0.0123456789012345, -0.0345678901234567, 0.0234567890123456};
  for (ValueEncoding e : {ValueEncoding::float64, ValueEncoding::float32}) {
    Encoder en{cfg_for(1, e)};
    Decoder de{cfg_for(0, e), peers, 3 * 3000};
    OutgoingState o = scene.out(0, 7);
    o.proxy = proxy;
    DecodedState st;
    DecodeStatus last = DecodeStatus::dropped;
    for (const auto& d : encode_all(en, o)) last = de.decode(d.data(), d.size(), st);
    CHECK(last == DecodeStatus::complete);
    CHECK(st.has_proxy);
    for (std::size_t a = 0; a < 3; ++a)
      DOUBLES_EQUAL(e == ValueEncoding::float64 ? proxy[a] : static_cast<double>(static_cast<float>(proxy[a])), st.proxy(a), 0.0);
    std::vector<double> x(scene.count), v(scene.count);  // x_hat and v_hat unchanged by the proxy after them
    st.copy_out(x.data(), v.data());
    for (std::uint32_t i = 0; i < scene.count; ++i) {
      DOUBLES_EQUAL(e == ValueEncoding::float64 ? scene.x[i] : static_cast<float>(scene.x[i]), x[i], 0.0);
      DOUBLES_EQUAL(e == ValueEncoding::float64 ? scene.v[i] : static_cast<float>(scene.v[i]), v[i], 0.0);
    }
    for (const auto& d : encode_all(en, scene.out(0, 8))) last = de.decode(d.data(), d.size(), st);
    CHECK(last == DecodeStatus::complete);
    CHECK_FALSE(st.has_proxy);
    o.seq = 9;
    o.safe_state = true;
    for (const auto& d : encode_all(en, o)) last = de.decode(d.data(), d.size(), st);
    CHECK(last == DecodeStatus::complete);
    CHECK(st.safe_state);
    CHECK_FALSE(st.has_proxy);
    for (std::size_t a = 0; a < 3; ++a) DOUBLES_EQUAL(0.0, st.proxy(a), 0.0);
    CHECK_EQUAL(0u, de.drops().total());
  }
}

TEST(Wire, NonFinitePayloadIsDroppedBeforeItsSequenceEntersTheWindow) {
  for (ValueEncoding e : {ValueEncoding::float64, ValueEncoding::float32}) {
    Encoder en{cfg_for(1, e)};
    Decoder de{cfg_for(0, e), peers, 3 * 3000};
    Scene s{33};  // 2 fragments in float64, 1 in float32
    const double good_x = s.x[40];
    s.x[40] = std::numeric_limits<double>::quiet_NaN();
    DecodedState st;
    const auto bad = encode_all(en, s.out(0, 4));
    for (const auto& d : bad) de.decode(d.data(), d.size(), st);
    CHECK_EQUAL(1u, de.drops()[DropReason::non_finite]);
    CHECK_EQUAL(0u, de.completed_packets());
    s.x[40] = good_x;
    s.v[3] = -std::numeric_limits<double>::infinity();
    const auto bad_v = encode_all(en, s.out(0, 4));
    for (const auto& d : bad_v) de.decode(d.data(), d.size(), st);
    CHECK_EQUAL(2u, de.drops()[DropReason::non_finite]);
    s.v[3] = 0.25;
    const double bad_proxy[3] = {0.01, std::numeric_limits<double>::quiet_NaN(), 0.02};  // the proxy is payload too
    OutgoingState o = s.out(0, 4);
    o.proxy = bad_proxy;
    for (const auto& d : encode_all(en, o)) de.decode(d.data(), d.size(), st);
    CHECK_EQUAL(3u, de.drops()[DropReason::non_finite]);
    // The same sequence with finite values is still accepted: nothing was marked.
    DecodeStatus last = DecodeStatus::dropped;
    for (const auto& d : encode_all(en, s.out(0, 4))) last = de.decode(d.data(), d.size(), st);
    CHECK(last == DecodeStatus::complete);
    CHECK_EQUAL(3u, de.drops().total());
  }
}

TEST(Wire, SequenceBeyondTheCeilingIsDroppedAndMovesNothing) {
  DecodeLimits lim;
  lim.max_sequence = 150;
  DecodedState st;
  for (const auto& d : encode_all(enc, scene.out(0, 100))) dec.decode(d.data(), d.size(), st, lim);
  const auto far = encode_all(enc, scene.out(0, 1'000'100));
  const auto before = dec.drops();
  for (const auto& d : far) CHECK(dec.decode(d.data(), d.size(), st, lim) == DecodeStatus::dropped);
  CHECK_EQUAL(before[DropReason::future_sequence] + far.size(), dec.drops()[DropReason::future_sequence]);
  DecodeStatus last = DecodeStatus::dropped;
  for (const auto& d : encode_all(enc, scene.out(0, 101))) last = dec.decode(d.data(), d.size(), st, lim);
  CHECK(last == DecodeStatus::complete);  // not stale: the window did not move
  // From a source address configured for another station: wrong_source, before the MAC.
  DecodeLimits other;
  other.source_station = 2;
  const auto p = encode_all(enc, scene.out(0, 102));
  const auto b = dec.drops();
  CHECK(dec.decode(p[0].data(), p[0].size(), st, other) == DecodeStatus::dropped);
  CHECK_EQUAL(b[DropReason::wrong_source] + 1, dec.drops()[DropReason::wrong_source]);
  DecodeLimits unknown;
  unknown.source_station = kSourceUnknown;
  CHECK(dec.decode(p[0].data(), p[0].size(), st, unknown) == DecodeStatus::dropped);
  CHECK_EQUAL(b[DropReason::wrong_source] + 2, dec.drops()[DropReason::wrong_source]);
  DecodeLimits right;
  right.source_station = 1;
  for (const auto& d : p) last = dec.decode(d.data(), d.size(), st, right);
  CHECK(last == DecodeStatus::complete);
}

namespace {
// One datagram written by `write` into a buffer of the default size, cut to the size it returns.
template <class F>
std::vector<std::uint8_t> datagram(F&& write) {
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  d.resize(write(d.data(), d.size()));
  return d;
}
}  // namespace

// Replays of every message kind (a state of one datagram and of several, a fingerprint under the
// shared key and under a pair's traffic key, a hello under the pair's static key) are refused and
// each is counted under its own reason; nothing a replay carries is accepted twice. Fresh messages
// of each kind (a new sequence, also a lower one never seen: reordered) still pass, a fingerprint
// identical but for its sequence (a keep-alive) included.
TEST(Wire, AReplayOfEveryMessageKindIsRefusedAndCountedUnderItsKind) {
  // Station 1 with pairwise keys (hello key, this run's traffic key), station 2 on the shared key.
  const SessionKey hello_key = test_key(40), traffic = test_key(80);
  dec.set_peer_keys(1, hello_key, &traffic);
  Encoder enc2{cfg_for(2)}, enc2_32{cfg_for(2, ValueEncoding::float32)};
  Fingerprint f;
  f.scene_nodes = 33;
  f.period_ns = 2'000'000;
  const RunNonce n1{1, 2, 3}, n0{9, 8, 7};
  auto fp1 = [&](std::uint64_t seq) {
    return datagram([&](std::uint8_t* d, std::size_t n) { return enc.encode_fingerprint(0, seq, 5, f, d, n, 0, &traffic); });
  };
  auto fp2 = [&](std::uint64_t seq) {
    return datagram([&](std::uint8_t* d, std::size_t n) { return enc2.encode_fingerprint(0, seq, 5, f, d, n); });
  };
  auto hello1 = [&](std::uint64_t seq) {
    return datagram([&](std::uint8_t* d, std::size_t n) { return enc.encode_hello(0, seq, 5, n1, n0, true, hello_key, d, n); });
  };
  const auto single = encode_all(enc2_32, scene.out(0, 10));  // one datagram
  CHECK_EQUAL(1u, single.size());
  std::vector<std::vector<std::uint8_t>> multi;                // two datagrams, station 1's traffic key
  for (std::size_t i = 0; i < 2; ++i)
    multi.push_back(datagram([&](std::uint8_t* d, std::size_t n) { return enc.encode_fragment(scene.out(0, 10), i, d, n, &traffic); }));
  struct Case {
    const char* what;
    std::vector<std::uint8_t> first, fresh, reordered;
    DecodeStatus accepted;
    DropReason replay;
  };
  const Case cases[] = {
      {"hello", hello1(20), hello1(21), hello1(19), DecodeStatus::hello, DropReason::replayed_hello},
      {"fingerprint (pair key)", fp1(30), fp1(31), fp1(29), DecodeStatus::fingerprint, DropReason::replayed_fingerprint},
      {"fingerprint (shared key)", fp2(30), fp2(31), fp2(29), DecodeStatus::fingerprint, DropReason::replayed_fingerprint},
      {"state, one datagram", single[0], encode_all(enc2_32, scene.out(0, 11))[0], encode_all(enc2_32, scene.out(0, 9))[0],
       DecodeStatus::complete, DropReason::replayed},
  };
  DecodedState st;
  for (const Case& c : cases) {
    CHECK_TEXT(dec.decode(c.first.data(), c.first.size(), st) == c.accepted, c.what);
    const std::uint64_t accepted = dec.accepted_datagrams();
    for (int again = 1; again <= 3; ++again) {
      const auto before = dec.drops();
      CHECK_TEXT(dec.decode(c.first.data(), c.first.size(), st) == DecodeStatus::dropped, c.what);
      CHECK_EQUAL_TEXT(before[c.replay] + 1, dec.drops()[c.replay], c.what);
      CHECK_EQUAL_TEXT(before.total() + 1, dec.drops().total(), c.what);
    }
    CHECK_EQUAL_TEXT(accepted, dec.accepted_datagrams(), c.what);  // nothing accepted twice
    CHECK_TEXT(dec.decode(c.fresh.data(), c.fresh.size(), st) == c.accepted, c.what);
    CHECK_TEXT(dec.decode(c.reordered.data(), c.reordered.size(), st) == c.accepted, c.what);
  }
  // A state of two datagrams: each fragment replayed after completion is refused as a state replay.
  CHECK(dec.decode(multi[0].data(), multi[0].size(), st) == DecodeStatus::fragment_stored);
  CHECK(dec.decode(multi[1].data(), multi[1].size(), st) == DecodeStatus::complete);
  for (const auto& d : multi) expect_drop(dec, d, DropReason::replayed);
  // The control window is its own: a state and a fingerprint may share a sequence number.
  const auto f11 = fp2(11);
  CHECK(dec.decode(f11.data(), f11.size(), st) == DecodeStatus::fingerprint);
  CHECK_EQUAL(3u, dec.drops()[DropReason::replayed_hello]);
  CHECK_EQUAL(6u, dec.drops()[DropReason::replayed_fingerprint]);
  CHECK_EQUAL(5u, dec.drops()[DropReason::replayed]);
  STRCMP_EQUAL("replayed_fingerprint", to_string(DropReason::replayed_fingerprint));
  STRCMP_EQUAL("replayed_hello", to_string(DropReason::replayed_hello));
}
