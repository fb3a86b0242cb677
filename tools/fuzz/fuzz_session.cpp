// libFuzzer target: a station's whole receive path at the session layer, the real net::Endpoint
// (decoder, incarnation rule, replay windows, key agreement, fingerprints, round trips, the hand-off
// to the tick) driven on the fuzzer's thread (Endpoint::step_without_thread) through an in-memory
// transport, with a clock the input plays.
//
// The endpoint is station 0 with two neighbours, 1 and 2, and fixed test key pairs (seeded, no
// secret), so the harness can be the neighbours: an input is a list of operations (one byte each,
// then its arguments, read from the front) that either inject raw bytes, or SEAL messages of every
// kind with the right keys (structure-aware): greetings (hellos, with the endpoint's nonce as the
// harness captured it from the endpoint's own hellos, or stale, zero or fuzzer nonces), fingerprints
// and state packets (1..3 fragments, any order or subset) under this run's traffic key, the static
// pair key or the shared key, from the current, a newer (restart) or an older incarnation; replay
// any datagram injected before; mutate the last one and re-seal it; push states from the tick side;
// drain; move the clock; probe. The first byte picks pairwise keys (most inputs) or the shared key.
// libsodium's randombytes is replaced by a per-input deterministic stream, so every input replays
// alike (the endpoint's run nonce included).
//
// Properties checked (abort on violation), beyond no crash / UB (ASan + UBSan):
//  - replays are refused and counted: a datagram byte-identical to one the endpoint accepted to the
//    end (a complete state packet, a fingerprint, a hello) is dropped when injected again, adds one
//    drop, and changes no acceptance counter;
//  - every state handed to the tick comes from a neighbour, has the scene's value count, is finite
//    and inside the envelope.
#include <sodium.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <memory>
#include <vector>

#include "net/endpoint.hpp"
#include "net/keys.hpp"
#include "net/wire.hpp"

using namespace haptic::net;

namespace {

// ---------------------------------------------------------------- deterministic randombytes
std::uint64_t g_rand_state = 0;
std::uint64_t splitmix() {
  std::uint64_t z = (g_rand_state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
const char* rb_name() { return "fuzz-deterministic"; }
std::uint32_t rb_random() { return static_cast<std::uint32_t>(splitmix()); }
void rb_buf(void* const buf, const std::size_t size) {
  auto* p = static_cast<std::uint8_t*>(buf);
  for (std::size_t i = 0; i < size; ++i) p[i] = static_cast<std::uint8_t>(splitmix());
}
randombytes_implementation g_rb = {rb_name, rb_random, nullptr, nullptr, rb_buf, nullptr};

// ---------------------------------------------------------------- the scene and the keys
constexpr std::uint32_t kValues = 12;      // 4 nodes
constexpr std::size_t kMaxDatagram = 160;  // stride 72 bytes: 3 float64 / 2 float32 fragments per packet
constexpr std::uint16_t kSelf = 0;
constexpr std::uint16_t kPeers[2] = {1, 2};
constexpr std::uint64_t kSelfIncarnation = 1'000'000;
constexpr std::uint64_t kPeerIncarnation = 5'000'000;

StationKeyPair seeded_pair(std::uint8_t tag) {
  std::array<std::uint8_t, crypto_kx_SEEDBYTES> seed{};
  for (std::size_t i = 0; i < seed.size(); ++i) seed[i] = static_cast<std::uint8_t>(tag * 31 + i * 7 + 1);
  StationKeyPair kp;
  crypto_kx_seed_keypair(kp.public_key.data(), kp.secret_key.data(), seed.data());
  return kp;
}

struct Keys {
  StationKeyPair self = seeded_pair(0);
  StationKeyPair peer[2] = {seeded_pair(1), seeded_pair(2)};
  PairKeys to_self[2];  // each neighbour's static pair keys with station 0 (tx: neighbour -> 0)
  SessionKey shared{};
  Keys() {
    for (int i = 0; i < 2; ++i) to_self[i] = pair_keys(peer[i], kPeers[i], self.public_key, kSelf);
    for (std::size_t i = 0; i < shared.bytes.size(); ++i) shared.bytes[i] = static_cast<std::uint8_t>(5 * i + 3);
  }
};
const Keys& keys() {
  static const Keys k;
  return k;
}

double rest(std::size_t i) { return 0.01 * static_cast<double>(i % 3) + 0.1 * static_cast<double>(i / 3); }

EndpointConfig config(bool pairwise) {
  EndpointConfig c;
  c.wire.session_id = 0x5EED;
  c.wire.station_id = kSelf;
  c.wire.incarnation = kSelfIncarnation;
  c.wire.max_datagram_bytes = kMaxDatagram;
  c.wire.key = keys().shared;
  c.value_count = kValues;
  for (int i = 0; i < 2; ++i) {
    PeerLink l;
    l.station_id = kPeers[i];
    l.public_key = keys().peer[i].public_key;
    c.peers.push_back(l);
  }
  c.delay_queue_datagrams = 16;
  c.tx_period_s = 0.002;
  c.pairwise_keys = pairwise;
  c.own_keys = keys().self;
  c.fingerprint.scene_nodes = kValues / 3;
  c.fingerprint.scene_hash = 0x1234;
  c.fingerprint.period_ns = 2'000'000;
  c.rtt.min_probe_samples = 2;
  for (std::size_t i = 0; i < kValues; ++i) c.envelope_rest_x.push_back(rest(i));
  c.envelope_max_offset_m = 0.1;
  c.envelope_max_speed_m_per_s = 10.0;
  return c;
}

// ---------------------------------------------------------------- transport and input
struct Datagram {
  std::vector<std::uint8_t> bytes;
  int source = kSourceUnchecked;
  bool accepted = false;  // accepted to the end when injected (a complete state, a fingerprint, a hello)
};

class FuzzTransport final : public Transport {
 public:
  int fd() const override { return -1; }
  // Keeps only the hellos (their nonces are all the harness reads): no copy of every state sent.
  bool send_to(std::uint16_t dest, const std::uint8_t* d, std::size_t n) override {
    if (n > wire_offset::kind && d[wire_offset::kind] == static_cast<std::uint8_t>(PayloadKind::hello))
      sent.push_back({dest, std::vector<std::uint8_t>(d, d + n)});
    return true;
  }
  long receive(std::uint8_t*, std::size_t) override { return 0; }
  long receive_from(std::uint8_t* buf, std::size_t cap, int& source) override {
    if (pending == nullptr) return kNoDatagram;
    const Datagram* d = pending;
    pending = nullptr;
    source = d->source;
    const std::size_t n = std::min(cap, d->bytes.size());
    if (n) std::memcpy(buf, d->bytes.data(), n);
    return static_cast<long>(d->bytes.size());
  }
  std::size_t max_datagram_bytes() const override { return 1472; }
  const char* name() const override { return "fuzz"; }
  const Datagram* pending = nullptr;
  struct Sent {
    std::uint16_t dest;
    std::vector<std::uint8_t> bytes;
  };
  std::vector<Sent> sent;
};

class Input {
 public:
  Input(const std::uint8_t* d, std::size_t n) : d_(d), n_(n) {}
  bool empty() const { return pos_ >= n_; }
  std::uint8_t u8() { return pos_ < n_ ? d_[pos_++] : 0; }
  std::uint16_t u16() { return static_cast<std::uint16_t>(u8() | (u8() << 8)); }
  std::uint64_t u64() {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= std::uint64_t{u8()} << (8 * i);
    return v;
  }
  void bytes(std::uint8_t* out, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) out[i] = u8();
  }

 private:
  const std::uint8_t* d_;
  std::size_t n_, pos_ = 0;
};

// ---------------------------------------------------------------- the harness: the two neighbours
struct Neighbour {
  std::uint64_t incarnation = kPeerIncarnation;
  RunNonce nonce{};            // our (the neighbour's) run nonce
  RunNonce endpoint_nonce{};   // the endpoint's, from its newest hello to us
  RunNonce old_endpoint_nonce{};
  RunNonce old_nonce{};
  std::uint64_t control_seq = 0;
};

class Harness {
 public:
  explicit Harness(bool pairwise) : pairwise_(pairwise) {
    auto t = std::make_unique<FuzzTransport>();
    transport_ = t.get();
    endpoint_ = std::make_unique<Endpoint>(config(pairwise), std::move(t));
    for (int i = 0; i < 2; ++i) {
      randombytes_buf(nb_[i].nonce.data(), kRunNonceBytes);
      nb_[i].nonce[0] |= 1;  // never all zero
    }
    now_ns_ = 1'000'000'000;
  }

  void run(Input& in) {
    for (int ops = 0; ops < 256 && !in.empty(); ++ops) {
      switch (in.u8() % 12) {
        case 0: raw(in); break;
        case 1: hello(in); break;
        case 2: fingerprint(in); break;
        case 3: state(in); break;
        case 4: replay(in); break;
        case 5: push(in); break;
        case 6: now_ns_ += std::int64_t{in.u16()} * 100'000; break;  // up to 6.5 s
        case 7: drain(); break;
        case 8: endpoint_->note_tick(static_cast<std::int64_t>(tick_) + static_cast<std::int8_t>(in.u8())); break;
        case 9:
          if (in.u8() & 1) endpoint_->begin_probing();
          else endpoint_->finish_probing();
          break;
        case 10: mutate_last(in); break;
        default: step(); break;
      }
    }
    drain();
  }

 private:
  Neighbour& neighbour(Input& in, int& index) {
    index = in.u8() & 1;
    return nb_[index];
  }
  static int source_of(int index, std::uint8_t choice) {
    switch (choice & 3) {
      case 0: return kPeers[index];                    // its configured address
      case 1: return kSourceUnchecked;                 // a transport that cannot tell
      case 2: return kPeers[1 - index];                // the other neighbour's address
      default: return kSourceUnknown;                  // anywhere else
    }
  }
  std::uint64_t incarnation(Neighbour& n, std::uint8_t choice, Input& in) {
    switch (choice & 3) {
      case 0: return n.incarnation;
      case 1: return ++n.incarnation;  // a restart: it becomes the neighbour's current one
      case 2: return n.incarnation - 1;
      default: return in.u64();
    }
  }
  // The key a neighbour's non-hello datagram is MAC'd with: this run's traffic key, one from stale
  // nonces, the static pair key, or the shared key.
  SessionKey key_for(int index, std::uint8_t choice) const {
    const Neighbour& n = nb_[index];
    if (!pairwise_) return choice == 3 ? keys().to_self[index].tx : keys().shared;
    switch (choice & 3) {
      case 0: return traffic_key(keys().to_self[index].tx, n.nonce, n.endpoint_nonce);
      case 1: return traffic_key(keys().to_self[index].tx, n.old_nonce, n.old_endpoint_nonce);
      case 2: return keys().to_self[index].tx;
      default: return keys().shared;
    }
  }
  WireConfig wire(int index, std::uint64_t inc) const {
    WireConfig w;
    w.session_id = 0x5EED;
    w.station_id = kPeers[index];
    w.incarnation = inc;
    w.max_datagram_bytes = kMaxDatagram;
    w.key = keys().shared;
    return w;
  }

  // One datagram into the endpoint, one step. Returns whether it was accepted to the end.
  // Only a received datagram moves the drop and acceptance counters (pushes and timers do not).
  bool inject(Datagram& d) {
    transport_->pending = &d;
    step();
    transport_->pending = nullptr;
    const EndpointStats after = endpoint_->stats();
    const std::uint64_t terminal_now = terminal(after), drops_now = after.drops.total();
    const bool accepted = terminal_now != terminal_;
    if (d.accepted) {
      // The property: a datagram accepted to the end before is a replay now, refused and counted.
      if (accepted || drops_now != drops_ + 1) std::abort();
    }
    terminal_ = terminal_now;
    drops_ = drops_now;
    return accepted;
  }
  static std::uint64_t terminal(const EndpointStats& s) {
    std::uint64_t t = s.fingerprints_received + s.wrong_scene_size;
    for (const auto& p : s.peers) t += p.hellos_received + p.packets_received;
    return t;
  }
  void add(std::vector<std::uint8_t> bytes, int source) {
    history_.push_back({std::move(bytes), source, false});
    if (history_.size() > 64) history_.pop_front();
    Datagram& d = history_.back();
    d.accepted = inject(d);
  }

  void step() {
    transport_->sent.clear();
    endpoint_->step_without_thread(now_ns_);
    learn_from_sent();
  }
  // The endpoint's hellos carry its run nonce: a neighbour echoes the newest.
  void learn_from_sent() {
    for (const auto& s : transport_->sent) {
      HeaderView h{};
      if (!peek_header(s.bytes.data(), s.bytes.size(), h) || h.kind != static_cast<std::uint8_t>(PayloadKind::hello)) continue;
      for (int i = 0; i < 2; ++i) {
        if (h.dest != kPeers[i] || s.bytes.size() < kHeaderBytes + kRunNonceBytes) continue;
        RunNonce n{};
        std::memcpy(n.data(), s.bytes.data() + kHeaderBytes, kRunNonceBytes);
        if (n != nb_[i].endpoint_nonce) {
          nb_[i].old_endpoint_nonce = nb_[i].endpoint_nonce;
          nb_[i].endpoint_nonce = n;
        }
      }
    }
  }

  void raw(Input& in) {
    const int src = source_of(in.u8() & 1, in.u8());
    std::vector<std::uint8_t> b(in.u16() % 400);
    in.bytes(b.data(), b.size());
    add(std::move(b), src);
  }

  void hello(Input& in) {
    int i = 0;
    Neighbour& n = neighbour(in, i);
    const std::uint8_t c = in.u8();
    const int src = source_of(i, in.u8());
    RunNonce mine = n.nonce, echo = n.endpoint_nonce;
    switch (c & 3) {
      case 1:  // a new nonce (as a restarted process would bring)
        n.old_nonce = n.nonce;
        ++n.nonce[1];
        mine = n.nonce;
        break;
      case 2: in.bytes(mine.data(), mine.size()); break;
      case 3: mine = RunNonce{}; break;
      default: break;
    }
    switch ((c >> 2) & 3) {
      case 1: echo = RunNonce{}; break;
      case 2: in.bytes(echo.data(), echo.size()); break;
      case 3: echo = n.old_endpoint_nonce; break;
      default: break;
    }
    const std::uint64_t inc = incarnation(n, c >> 5, in);
    const std::uint64_t seq = (c & 0x80) ? in.u64() : ++n.control_seq;
    const SessionKey& key = pairwise_ ? keys().to_self[i].tx : keys().shared;
    std::vector<std::uint8_t> d(kMaxDatagram);
    d.resize(Encoder(wire(i, inc)).encode_hello(kSelf, seq, static_cast<std::int64_t>(now_ns_), mine, echo, (c & 0x10) != 0,
                                                key, d.data(), d.size()));
    add(std::move(d), src);
  }

  void fingerprint(Input& in) {
    int i = 0;
    Neighbour& n = neighbour(in, i);
    const std::uint8_t c = in.u8();
    const int src = source_of(i, in.u8());
    const std::uint64_t inc = incarnation(n, c >> 2, in);
    const std::uint64_t seq = (c & 0x10) ? in.u64() : ++n.control_seq;
    Fingerprint f;
    f.scene_nodes = kValues / 3;
    f.scene_hash = 0x1234;
    f.period_ns = 2'000'000;
    if (c & 0x20) {
      f.scene_nodes = in.u8();
      f.scene_hash = in.u64();
      f.consensus_law = in.u8();
      f.tx_predict = in.u8();
    }
    const std::uint64_t bound = (c & 0x40) ? in.u64() : 0;
    const std::int32_t allowance = static_cast<std::int8_t>(in.u8());
    const SessionKey key = key_for(i, c & 3);
    std::vector<std::uint8_t> d(kMaxDatagram);
    d.resize(Encoder(wire(i, inc)).encode_fingerprint(kSelf, seq, static_cast<std::int64_t>(now_ns_), f, d.data(), d.size(),
                                                      bound, &key, allowance));
    add(std::move(d), src);
  }

  void state(Input& in) {
    int i = 0;
    Neighbour& n = neighbour(in, i);
    const std::uint8_t c = in.u8();
    const std::uint8_t frags = in.u8();  // bits 0-2: which fragments; bit 3: reversed; bits 4-5: source
    const int src = source_of(i, frags >> 4);
    const std::uint64_t inc = incarnation(n, c >> 2, in);
    WireConfig w = wire(i, inc);
    w.encoding = (c & 0x10) ? ValueEncoding::float32 : ValueEncoding::float64;
    OutgoingState o;
    o.dest = kSelf;
    o.seq = tick_ + static_cast<std::uint64_t>(static_cast<std::int8_t>(in.u8()));
    o.send_time_ns = static_cast<std::int64_t>(now_ns_);
    o.has_echo = (c & 0x20) != 0;
    o.echo_seq = tick_ - (in.u8() & 7);  // one of our recent pushes (the round trip)
    o.echo_hold_ns = 100'000;
    o.value_count = kValues;
    o.safe_state = (c & 0x40) != 0;
    double x[kValues], v[kValues];
    for (std::size_t k = 0; k < kValues; ++k) {
      x[k] = rest(k);
      v[k] = 0.0;
    }
    if (c & 0x80) {  // fuzzer values: any bit pattern (NaN, inf, outside the envelope)
      const std::size_t k = in.u8() % kValues;
      std::uint64_t bits = in.u64();
      std::memcpy((in.u8() & 1) ? &v[k] : &x[k], &bits, 8);
    }
    o.x_hat = x;
    o.v_hat = v;
    const SessionKey key = key_for(i, c & 3);
    const Encoder enc(w);
    const std::size_t count = enc.fragment_count(kValues);
    for (std::size_t j = 0; j < count; ++j) {
      const std::size_t f = (frags & 8) ? count - 1 - j : j;
      if (((frags >> f) & 1) == 0 && (frags & 7) != 0) continue;  // 0: all of them
      std::vector<std::uint8_t> d(kMaxDatagram);
      d.resize(enc.encode_fragment(o, f, d.data(), d.size(), &key));
      add(std::move(d), src);
    }
  }

  void replay(Input& in) {
    if (history_.empty()) return;
    const std::size_t k = in.u16() % history_.size();
    Datagram d = history_[k];  // the same bytes from the same place
    const bool accepted = inject(d);
    history_[k].accepted = history_[k].accepted || accepted;
  }

  // The last datagram with one byte changed, re-sealed with a chosen key where its MAC goes.
  void mutate_last(Input& in) {
    if (history_.empty()) return;
    std::vector<std::uint8_t> b = history_.back().bytes;
    const int src = history_.back().source;
    const std::size_t at = in.u16();
    const std::uint8_t x = in.u8();
    const std::uint8_t c = in.u8();
    if (!b.empty()) b[at % b.size()] ^= x;
    HeaderView h{};
    if (peek_header(b.data(), b.size(), h) && kHeaderBytes + std::size_t{h.frag_len} + kMacBytes == b.size()) {
      const int i = h.sender == kPeers[1] ? 1 : 0;
      const SessionKey key = h.kind == static_cast<std::uint8_t>(PayloadKind::hello) && pairwise_ && (c & 4) == 0
                                 ? keys().to_self[i].tx
                                 : key_for(i, c & 3);
      crypto_generichash(b.data() + kHeaderBytes + h.frag_len, kMacBytes, b.data(), kHeaderBytes + h.frag_len,
                         key.bytes.data(), key.bytes.size());
    }
    add(std::move(b), src);
  }

  void push(Input& in) {
    const std::uint8_t c = in.u8();
    ++tick_;
    double x[kValues], v[kValues];
    for (std::size_t k = 0; k < kValues; ++k) {
      x[k] = rest(k);
      v[k] = 0.0;
    }
    if (c & 2) x[c % kValues] = NAN;  // a non-finite state is never sent: the safe-state flag instead
    endpoint_->push_state(tick_, static_cast<double>(now_ns_) * 1e-9, x, v, (c & 1) != 0);
    step();
  }

  void drain() {
    endpoint_->drain_packets([](const RxPacket& p) {
      if (p.sender != kPeers[0] && p.sender != kPeers[1]) std::abort();
      if (p.count != kValues) std::abort();
      for (std::uint32_t k = 0; k < p.count; ++k) {
        if (!std::isfinite(p.x_hat[k]) || !std::isfinite(p.v_hat[k])) std::abort();
        if (std::fabs(p.x_hat[k] - rest(k)) > 0.1 + 1e-6 || std::fabs(p.v_hat[k]) > 10.0 + 1e-6) std::abort();
      }
    });
  }

  bool pairwise_;
  FuzzTransport* transport_ = nullptr;
  std::unique_ptr<Endpoint> endpoint_;
  Neighbour nb_[2];
  std::deque<Datagram> history_;
  std::uint64_t terminal_ = 0, drops_ = 0;  // after the newest injection (a new endpoint: none)
  std::uint64_t tick_ = 100;
  std::int64_t now_ns_ = 0;
};

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  randombytes_set_implementation(&g_rb);  // before sodium_init (the endpoint's first call)
  if (sodium_init() < 0) std::abort();
  keys();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  g_rand_state = 0x5EED;  // every input sees the same random stream
  Input in(data, size);
  const bool pairwise = (in.u8() & 0x0F) != 0;  // 15 in 16: pairwise keys
  Harness h(pairwise);
  h.run(in);
  return 0;
}
