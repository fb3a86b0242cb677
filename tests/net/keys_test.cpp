// Station keys (net/keys.hpp): key files only their owner may read, created 0600
// and never overwritten, example keys refused outside demo mode (also in shipped configurations),
// the pair-key derivation, and the pairwise protocol between two in-process endpoints over a
// socketpair (no root, no ports): both ends agree on this run's traffic keys, no state leaves
// before they have, a third station cannot forge another's packets, a run's datagrams replayed
// into the next run are refused and change nothing, a forged far-future sequence while probing
// cannot move the replay window, and a restarted neighbour agrees again.
#include <CppUTest/TestHarness.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <functional>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "net/config.hpp"
#include "net/keys.hpp"
#include "tests/net/exchange_util.hpp"

using namespace haptic::net;
using namespace haptic::net::test;
namespace fs = std::filesystem;

namespace {

std::string temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("haptic-keys-" + name + "-" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d.string();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}


// One end of an AF_UNIX datagram socketpair: a transport between two in-process endpoints that
// records every datagram it sends (the attacker's capture) and can inject datagrams to the far
// end (the far end cannot tell where a datagram came from: the attacker spoofs any source).
class PairTransport final : public Transport {
 public:
  PairTransport(int fd, bool owns) : fd_(fd), owns_(owns) {}
  ~PairTransport() override {
    if (owns_) ::close(fd_);
  }
  int fd() const override { return fd_; }
  bool send_to(std::uint16_t, const std::uint8_t* d, std::size_t n) override {
    {
      std::lock_guard<std::mutex> g(m_);
      if (record_) sent_.emplace_back(d, d + n);
    }
    return send_patiently(d, n);
  }
  long receive(std::uint8_t* buf, std::size_t cap) override {
    const ssize_t n = ::recv(fd_, buf, cap, MSG_DONTWAIT | MSG_TRUNC);
    return n < 0 ? 0 : static_cast<long>(n);
  }
  std::size_t max_datagram_bytes() const override { return 1472; }
  const char* name() const override { return "socketpair"; }
  void inject(const std::vector<std::uint8_t>& d) const { send_patiently(d.data(), d.size()); }
  std::vector<std::vector<std::uint8_t>> sent() {
    std::lock_guard<std::mutex> g(m_);
    return sent_;
  }
  void record(bool on) {
    std::lock_guard<std::mutex> g(m_);
    record_ = on;
  }

 private:
  // A socketpair's queue holds only net.unix.max_dgram_qlen (10) datagrams: retry a full queue for
  // up to 20 ms (bounded) while the other end's I/O thread reads.
  bool send_patiently(const std::uint8_t* d, std::size_t n) const {
    for (int i = 0; i < 400; ++i) {
      if (::send(fd_, d, n, MSG_DONTWAIT) == static_cast<ssize_t>(n)) return true;
      if (errno != EAGAIN && errno != EWOULDBLOCK) return false;
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
    return false;
  }
  int fd_;
  bool owns_;
  std::mutex m_;
  bool record_ = true;
  std::vector<std::vector<std::uint8_t>> sent_;
};

struct KeyFiles {
  std::string dir;
  StationKeyPair k0, k1, k2;
  explicit KeyFiles(const std::string& name) : dir(temp_dir(name)) {
    for (const char* f : {"/s0.key", "/s1.key", "/s2.key"}) write_new_key_file(dir + f);
    k0 = read_key_file(dir + "/s0.key", "test", false);
    k1 = read_key_file(dir + "/s1.key", "test", false);
    k2 = read_key_file(dir + "/s2.key", "test", false);
  }
  ~KeyFiles() { fs::remove_all(dir); }
};

// Station `self` with its key pair, one neighbour `peer` whose public key it is told. The wire's
// shared key (exchange_wire) stays set: pairwise mode must never accept it.
EndpointConfig keyed(std::uint16_t self, const StationKeyPair& own, std::uint16_t peer, const PublicKey& theirs,
                     bool pairwise = true) {
  EndpointConfig c = exchange_config(self, peer, 99);
  c.pairwise_keys = pairwise;
  c.own_keys = own;
  c.peers[0].public_key = theirs;
  return c;
}

// A run: endpoints 0 and 1 over a socketpair (fds kept by the run, so station 1 can restart).
struct Run {
  int sv[2] = {-1, -1};
  PairTransport *t0 = nullptr, *t1 = nullptr;
  std::unique_ptr<Endpoint> e0, e1;
  EndpointConfig c0, c1;
  // station1_knows: the public key station 1 is told for station 0 (default: the right one).
  // start_station1 = false: station 1 starts later (start1()).
  Run(const KeyFiles& k, bool pairwise = true, const PublicKey* station1_knows = nullptr, bool start_station1 = true)
      : c0(keyed(0, k.k0, 1, k.k1.public_key, pairwise)),
        c1(keyed(1, k.k1, 0, station1_knows ? *station1_knows : k.k0.public_key, pairwise)) {
    CHECK_EQUAL(0, ::socketpair(AF_UNIX, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, sv));
    start0();
    if (start_station1) start1();
  }
  void start0() {
    auto a = std::make_unique<PairTransport>(sv[0], false);
    t0 = a.get();
    e0 = std::make_unique<Endpoint>(c0, std::move(a));
    e0->start();
  }
  void start1() {  // also a restart of station 1: a new process (incarnation, nonce)
    if (e1) {
      // A killed process is silent: its restart is accepted once the old one has been silent for
      // the quiet time (net.peer_silence_s, the incarnation rule), as a real restart takes longer.
      e1->stop();
      std::this_thread::sleep_for(std::chrono::duration<double>(c0.peer_silence_s + 0.05));
    }
    e1.reset();
    auto b = std::make_unique<PairTransport>(sv[1], false);
    t1 = b.get();
    e1 = std::make_unique<Endpoint>(c1, std::move(b));
    e1->start();
  }
  ~Run() {
    if (e0) e0->stop();
    if (e1) e1->stop();
    ::close(sv[0]);
    ::close(sv[1]);
  }
  // Both push seq0 .. seq0 + count - 1, one per ms; returns the sequences e0 delivered from
  // station 1 (content-checked: a payload that is not what station 1 sends at that sequence
  // counts in `corrupt`).
  std::vector<std::uint64_t> exchange(std::uint64_t seq0, int count, std::uint64_t& corrupt) {
    std::vector<double> x(99), v(99), ex(99), ev(99);
    std::vector<std::uint64_t> got;
    auto take = [&](std::uint16_t s, std::uint64_t q, double, const double* xh, const double* vh, std::uint32_t n) {
      fill_state(s, q, ex, ev);
      for (std::uint32_t j = 0; j < n; ++j)
        if (xh[j] != ex[j] || vh[j] != ev[j]) ++corrupt;
      got.push_back(q);
    };
    for (int i = 0; i < count; ++i) {
      const std::uint64_t k = seq0 + static_cast<std::uint64_t>(i);
      fill_state(0, k, x, v);
      e0->push_state(k, monotonic_s(), x.data(), v.data());
      fill_state(1, k, x, v);
      e1->push_state(k, monotonic_s(), x.data(), v.data());
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      e0->drain(take);
      e1->drain([](auto...) {});
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    e0->drain(take);
    return got;
  }
};

// A state packet (x, v: 99 values) to station 0 with sequence seq, for forging.
OutgoingState state_to_0(std::uint64_t seq, const std::vector<double>& x, const std::vector<double>& v) {
  OutgoingState o;
  o.dest = 0;
  o.seq = seq;
  o.value_count = 99;
  o.x_hat = x.data();
  o.v_hat = v.data();
  return o;
}

std::uint64_t kind_of(const std::vector<std::uint8_t>& d) { return d.size() > wire_offset::kind ? d[wire_offset::kind] : 0; }

// What a replay must not change at station 0 (its view of station 1).
struct Snapshot {
  std::uint64_t packets, newest, rtt_samples, agreements, incarnation, generation, hellos;
  double rtt_max, bound;
  bool agreed;
  explicit Snapshot(const EndpointStats& s)
      : packets(s.peers[0].packets_received), newest(s.peers[0].newest_seq), rtt_samples(s.peers[0].rtt_samples),
        agreements(s.peers[0].key_agreements), incarnation(s.peers[0].incarnation),
        generation(s.peers[0].rtt_bound_generation), hellos(s.peers[0].hellos_sent), rtt_max(s.peers[0].rtt_max_s),
        bound(s.peers[0].rtt_bound_s), agreed(s.peers[0].keys_agreed) {}
  bool operator==(const Snapshot&) const = default;
};

// Waits (bounded, 2 s) until station 0 has counted `n` more drops than `before`.
bool wait_drops(Endpoint& e, std::uint64_t before, std::uint64_t n) {
  for (int i = 0; i < 400; ++i) {
    if (e.stats().drops.total() >= before + n) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// Waits (bounded, 2 s) until station 0's I/O thread has read n more datagrams than `before`.
bool wait_datagrams(Endpoint& e, std::uint64_t before, std::uint64_t n) {
  for (int i = 0; i < 400; ++i) {
    if (e.stats().datagrams_received >= before + n) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

}  // namespace

TEST_GROUP(Keys){};

TEST(Keys, AKeyFileOthersCanReadIsRefusedNamingTheChmod) {
  const std::string dir = temp_dir("perm");
  const std::string pub = write_new_key_file(dir + "/s.key");
  struct stat st {};
  ::stat((dir + "/s.key").c_str(), &st);
  CHECK_EQUAL(0600u, st.st_mode & 0777u);  // created private whatever the umask
  const StationKeyPair kp = read_key_file(dir + "/s.key", "net.key_file", false);
  STRCMP_EQUAL(pub.c_str(), to_hex(kp.public_key.data(), kp.public_key.size()).c_str());
  ::chmod((dir + "/s.key").c_str(), 0640);
  const std::string e = error_of([&] { read_key_file(dir + "/s.key", "net.key_file", false); });
  STRCMP_CONTAINS("net.key_file", e.c_str());
  STRCMP_CONTAINS("chmod 600", e.c_str());
  CHECK(!error_of([&] { write_new_key_file(dir + "/s.key"); }).empty());  // never overwrites
  fs::remove_all(dir);
}

TEST(Keys, ExampleKeysAreRefusedOutsideDemoMode) {
  const std::string head = "[station]\nid = 1\n[net]\nbind = \"127.0.0.1:47001\"\n";
  const std::string peer = "[[net.peers]]\nid = 2\naddress = \"127.0.0.1:47002\"\n";
  for (const char* k : {"0000000000000000000000000000000000000000000000000000000000000000",
                        "00000000000000000000000000000000000000000000000000000000000000ff",
                        "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f"}) {
    const std::string doc = head + "shared_session_key = \"" + k + "\"\n" + peer;
    const std::string e = error_of([&] { parse_net_config(doc, 99); });
    STRCMP_CONTAINS("net.shared_session_key", e.c_str());
    STRCMP_CONTAINS("demo_keys", e.c_str());
    CHECK(error_of([&] { parse_net_config(head + "demo_keys = true\nshared_session_key = \"" + k + "\"\n" + peer, 99); }).empty());
  }
  // A random key is fine.
  CHECK(error_of([&] { parse_net_config(head + "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n" + peer, 99); })
            .empty());
}

// net.revoked_keys (a stolen key, revoked in the lab file): a station whose own key is revoked, or
// whose neighbour's public_key is, is refused at start-up with the key named as written.
TEST(Keys, ARevokedKeyIsRefusedAtStartUpNamingTheKeyAsWritten) {
  const std::string dir = temp_dir("revoked");
  const std::string own = write_new_key_file(dir + "/s.key");
  const std::string theirs = to_hex(generate_key_pair().public_key.data(), kPublicKeyBytes);
  const std::string other = to_hex(generate_key_pair().public_key.data(), kPublicKeyBytes);
  auto doc = [&](const std::string& revoked) {
    return "[station]\nid = 1\n[net]\nbind = \"127.0.0.1:47001\"\nkey_file = \"" + dir + "/s.key\"\nrevoked_keys = \"" + revoked +
           "\"\n[[net.peers]]\nid = 2\naddress = \"127.0.0.1:47002\"\npublic_key = \"" + theirs + "\"\n";
  };
  CHECK(error_of([&] { parse_net_config(doc(""), 99); }).empty());
  CHECK(error_of([&] { parse_net_config(doc(other), 99); }).empty());
  std::string e = error_of([&] { parse_net_config(doc(other + ", " + theirs), 99); });
  STRCMP_CONTAINS(("net.peers[0].public_key = \"" + theirs + "\"").c_str(), e.c_str());
  STRCMP_CONTAINS("revoked_keys", e.c_str());
  e = error_of([&] { parse_net_config(doc(own + " " + other), 99); });
  STRCMP_CONTAINS(("net.key_file = \"" + dir + "/s.key\"").c_str(), e.c_str());
  STRCMP_CONTAINS(own.c_str(), e.c_str());
  e = error_of([&] { parse_net_config(doc(other + " 12ab"), 99); });  // not a key: named with its place in the list
  STRCMP_CONTAINS("net.revoked_keys (key 2)", e.c_str());
  fs::remove_all(dir);
}

TEST(Keys, BothEndsOfAPairDeriveTheSameDirectedKeysAndEachRunItsOwn) {
  const StationKeyPair a = generate_key_pair(), b = generate_key_pair(), c = generate_key_pair();
  const PairKeys ab = pair_keys(a, 1, b.public_key, 2), ba = pair_keys(b, 2, a.public_key, 1), cb = pair_keys(c, 3, b.public_key, 2);
  CHECK(ab.tx.bytes == ba.rx.bytes);
  CHECK(ab.rx.bytes == ba.tx.bytes);
  CHECK(ab.tx.bytes != ab.rx.bytes);  // each direction its own key
  CHECK(cb.tx.bytes != ab.tx.bytes);  // a third station derives something else
  const RunNonce n1 = new_run_nonce(), n2 = new_run_nonce(), n3 = new_run_nonce();
  CHECK(traffic_key(ab.tx, n1, n2).bytes == traffic_key(ba.rx, n1, n2).bytes);
  CHECK(traffic_key(ab.tx, n1, n2).bytes != traffic_key(ab.tx, n3, n2).bytes);  // a new run, a new key
  CHECK_FALSE(is_example_key(ab.tx.bytes.data(), ab.tx.bytes.size()));
}

TEST(Keys, BothEndsAgreeOnThisRunsKeysAndEveryStateArrivesIntact) {
  KeyFiles k("agree");
  Run r(k);
  std::uint64_t corrupt = 0;
  const auto got = r.exchange(1, 200, corrupt);
  CHECK_TEXT(got.size() >= 150, std::to_string(got.size()).c_str());
  CHECK_EQUAL(0u, corrupt);
  const EndpointStats s0 = r.e0->stats(), s1 = r.e1->stats();
  CHECK_TRUE(s0.peers[0].keys_agreed);
  CHECK_TRUE(s1.peers[0].keys_agreed);
  CHECK_EQUAL(1u, s0.peers[0].key_agreements);
  CHECK_EQUAL(1u, s1.peers[0].key_agreements);
  CHECK_EQUAL(0u, s0.drops[DropReason::bad_mac]);
  CHECK_EQUAL(0u, s1.drops[DropReason::bad_mac]);
  // Hellos only until agreed (and on request): none once both ends hold the keys.
  const auto more = r.exchange(201, 100, corrupt);
  CHECK(more.size() >= 75);
  CHECK_EQUAL(s0.peers[0].hellos_sent, r.e0->stats().peers[0].hellos_sent);
  CHECK_EQUAL(s1.peers[0].hellos_sent, r.e1->stats().peers[0].hellos_sent);
}

TEST(Keys, NoStateLeavesOrIsAcceptedBeforeThePairHasAgreed) {
  // Station 1 is told a wrong public key for station 0 (station 2's): the pair can never agree.
  KeyFiles k("noagree");
  Run r(k, true, &k.k2.public_key);
  std::uint64_t corrupt = 0;
  const auto got = r.exchange(1, 60, corrupt);
  CHECK_EQUAL(0u, got.size());
  const EndpointStats s0 = r.e0->stats(), s1 = r.e1->stats();
  CHECK_FALSE(s0.peers[0].keys_agreed);
  CHECK_FALSE(s1.peers[0].keys_agreed);
  CHECK(s0.peers[0].tx_without_keys >= 60);
  CHECK(s0.drops[DropReason::bad_mac] > 0);  // station 1's hellos, under the wrong pair key
  std::size_t hellos = 0;
  for (const auto& d : r.t0->sent()) {
    CHECK_EQUAL(static_cast<std::uint64_t>(PayloadKind::hello), kind_of(d));  // nothing but hellos
    ++hellos;
  }
  CHECK(hellos >= 60);
}

TEST(Keys, AThirdStationCannotForgeAnothersPackets) {
  // Station 0 has neighbours 1 and 2; station 2 holds valid keys of its own and claims to be 1.
  KeyFiles k("forge");
  const RunNonce n0 = new_run_nonce(), n1 = new_run_nonce(), n2 = new_run_nonce();
  const std::uint16_t peers[] = {1, 2};
  Decoder dec(exchange_wire(0), peers, 99);
  const PairKeys p01 = pair_keys(k.k0, 0, k.k1.public_key, 1), p02 = pair_keys(k.k0, 0, k.k2.public_key, 2);
  const SessionKey rx1 = traffic_key(p01.rx, n1, n0), rx2 = traffic_key(p02.rx, n2, n0);
  dec.set_peer_keys(1, p01.rx, &rx1);
  dec.set_peer_keys(2, p02.rx, &rx2);
  // Everything station 2 can compute: its own pair keys with 0 and their traffic keys, and the
  // configured shared session key.
  const PairKeys p20 = pair_keys(k.k2, 2, k.k0.public_key, 0);
  const SessionKey tx20 = traffic_key(p20.tx, n2, n0);
  CHECK(tx20.bytes == rx2.bytes);  // the pair 2 -> 0 agrees
  const SessionKey shared = exchange_wire(0).key;
  std::vector<double> x(99, 0.01), v(99, 0.0);
  const OutgoingState o = state_to_0(5, x, v);
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  DecodedState st;
  std::uint64_t forged = 0;
  for (const SessionKey* key : {&tx20, &p20.tx, &shared}) {
    Encoder as1(exchange_wire(1));  // header says station 1
    for (std::size_t f = 0; f < as1.fragment_count(99); ++f, ++forged)
      CHECK(dec.decode(d.data(), as1.encode_fragment(o, f, d.data(), d.size(), key), st) == DecodeStatus::dropped);
    // a hello "from station 1" echoing 0's nonce, under every key station 2 has
    CHECK(dec.decode(d.data(), as1.encode_hello(0, 5, 0, n2, n0, true, *key, d.data(), d.size()), st) == DecodeStatus::dropped);
    ++forged;
  }
  CHECK_EQUAL(forged, dec.drops()[DropReason::bad_mac]);
  CHECK_EQUAL(forged, dec.drops().total());
  // As itself, station 2's packets verify: the forgeries failed for the claimed sender's key alone.
  Encoder as2(exchange_wire(2));
  DecodeStatus last = DecodeStatus::dropped;
  for (std::size_t f = 0; f < as2.fragment_count(99); ++f) last = dec.decode(d.data(), as2.encode_fragment(o, f, d.data(), d.size(), &tx20), st);
  CHECK(last == DecodeStatus::complete);
  CHECK_EQUAL(forged, dec.drops().total());
}

TEST(Keys, ARunsDatagramsReplayedIntoTheNextRunAreRefusedAndChangeNothing) {
  KeyFiles k("replay");
  std::vector<std::vector<std::uint8_t>> capture;
  {
    Run one(k);
    std::uint64_t corrupt = 0;
    one.e0->begin_probing();
    const auto got = one.exchange(1000, 150, corrupt);  // run 1 uses sequences 1000..1149
    CHECK(got.size() >= 100);
    capture = one.t1->sent();  // everything station 1 sent in run 1: hellos, fingerprints, states
  }
  std::size_t hellos = 0;
  for (const auto& d : capture) hellos += kind_of(d) == static_cast<std::uint64_t>(PayloadKind::hello);
  CHECK(hellos >= 1);
  CHECK(capture.size() >= hellos + 100);
  // Same key files, same session id, a new run (new processes, new nonces). Station 0 starts
  // first, and before station 1's new process says anything, run 1 is played into station 0:
  // its hellos are the first authentic datagrams station 0 sees from "station 1" (the incarnation
  // rule cannot refuse them yet), but they echo run 1's nonce, so none is adopted.
  Run two(k, true, nullptr, false);
  two.e0->begin_probing();
  {
    PairTransport attacker(two.sv[1], false);
    attacker.record(false);
    for (const auto& d : capture) attacker.inject(d);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const EndpointStats first = two.e0->stats();
  CHECK_EQUAL(hellos, first.peers[0].hellos_received);  // authentic (static pair key) hellos...
  CHECK_FALSE(first.peers[0].keys_agreed);               // ...but none adopted
  CHECK_EQUAL(0u, first.peers[0].key_agreements);
  CHECK_EQUAL(0u, first.peers[0].packets_received);
  two.start1();
  two.t1->record(false);
  for (const auto& d : capture) two.t1->inject(d);  // and again while probing, station 1 running
  std::uint64_t corrupt = 0;
  std::vector<std::uint64_t> got = two.exchange(1, 80, corrupt);
  CHECK_TRUE(two.e0->finish_probing());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // After agreement: run 1 again, into a quiet link; every datagram refused and nothing moves.
  const EndpointStats before = two.e0->stats();
  const Snapshot snap(before);
  for (const auto& d : capture) two.t1->inject(d);
  CHECK_TRUE(wait_drops(*two.e0, before.drops.total(), capture.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const EndpointStats after = two.e0->stats();
  CHECK_EQUAL(before.drops.total() + capture.size(), after.drops.total());  // each counted, once
  CHECK_EQUAL(before.drops[DropReason::bad_mac] + (capture.size() - hellos), after.drops[DropReason::bad_mac]);
  CHECK_EQUAL(before.drops[DropReason::old_incarnation] + hellos, after.drops[DropReason::old_incarnation]);
  CHECK(Snapshot(after) == snap);
  std::size_t late = 0;
  two.e0->drain([&](auto...) { ++late; });
  CHECK_EQUAL(0u, late);  // nothing reached the tick
  const auto more = two.exchange(81, 40, corrupt);
  got.insert(got.end(), more.begin(), more.end());
  for (auto s : got) CHECK_TEXT(s < 1000, "a packet of run 1 was accepted in run 2");
  CHECK_EQUAL(0u, corrupt);
  CHECK(got.size() >= 80);
  const EndpointStats s0 = two.e0->stats();
  CHECK_EQUAL(1u, s0.peers[0].key_agreements);  // run 1's hellos echo another nonce: never adopted
  // The bound comes from run 2's own round trips (loopback: milliseconds), not from run 1's stamps.
  CHECK_TEXT(s0.peers[0].rtt_bound_s < 0.5, std::to_string(s0.peers[0].rtt_bound_s).c_str());
}

namespace {
// Station 0 and 1 exchange without any sequence ceiling (no note_tick: probing); an attacker
// injects one packet "from station 1" with sequence 10^6, MAC'd with the shared session key (all
// a shared-key session needs) and with every key a third station holds. Returns how many of
// station 1's next 60 genuine packets station 0 still delivers.
std::size_t genuine_after_forged_future(bool pairwise) {
  KeyFiles k(pairwise ? "future-pair" : "future-shared");
  Run r(k, pairwise);
  r.e0->begin_probing();
  std::uint64_t corrupt = 0;
  const auto first = r.exchange(1, 60, corrupt);
  CHECK(first.size() >= 40);
  const PairKeys p20 = pair_keys(k.k2, 2, k.k0.public_key, 0);
  std::vector<double> x(99, 0.0), v(99, 0.0);
  const OutgoingState o = state_to_0(1000000, x, v);
  WireConfig w1 = r.c1.wire;
  w1.incarnation = r.e1->incarnation();  // station 1's header, even its incarnation
  Encoder as1(w1);
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  const SessionKey shared = r.c1.wire.key;
  for (const SessionKey* key : {&shared, &p20.tx, &p20.rx})
    for (std::size_t f = 0; f < as1.fragment_count(99); ++f) {
      const std::size_t n = as1.encode_fragment(o, f, d.data(), d.size(), key);
      r.t1->inject(std::vector<std::uint8_t>(d.begin(), d.begin() + static_cast<long>(n)));
    }
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  const auto after = r.exchange(61, 60, corrupt);
  std::size_t genuine = 0;
  for (auto q : after) genuine += q < 1000000;
  if (pairwise) CHECK_EQUAL(0u, corrupt);  // (the shared-key forgery itself is delivered: not station 1's data)
  return genuine;
}
}  // namespace

TEST(Keys, AForgedFarFutureSequenceWhileProbingCannotMoveTheReplayWindow) {
  // The shared-key baseline shows the gap (security.md): the forgery is accepted, moves the
  // window to 10^6, and every genuine packet after it is stale.
  CHECK_EQUAL(0u, genuine_after_forged_future(false));
  // Pairwise keys: the forgery fails the MAC, the genuine packets keep arriving.
  CHECK(genuine_after_forged_future(true) >= 45);
}

TEST(Keys, ARestartedNeighbourAgreesAgainWithItsNewNonce) {
  KeyFiles k("restart");
  Run r(k);
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1, 60, corrupt).size() >= 40);
  r.start1();  // station 1 restarts: new incarnation, new nonce; station 0 keeps running
  const auto got = r.exchange(61, 100, corrupt);
  CHECK_EQUAL(0u, corrupt);
  CHECK_TEXT(got.size() >= 60, std::to_string(got.size()).c_str());
  const EndpointStats s0 = r.e0->stats(), s1 = r.e1->stats();
  CHECK_EQUAL(2u, s0.peers[0].key_agreements);
  CHECK_TRUE(s0.peers[0].keys_agreed);
  CHECK_TRUE(s1.peers[0].keys_agreed);
  CHECK_EQUAL(1u, s0.peers[0].incarnation_changes);
}

// A stolen key (station 1's secret) announcing a restart while the real station 1 runs: the
// greeting is refused (no re-keying with the attacker), and the real one's next states make two
// live incarnations: both refused from then on, and station 0's statistics say so.
TEST(Keys, AStolenKeysRestartWhileTheRealStationTalksIsRefusedAndBothAreCutOff) {
  KeyFiles k("stolen");
  Run r(k);
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1, 60, corrupt).size() >= 40);
  const std::uint64_t real = r.e1->incarnation();
  WireConfig w1 = r.c1.wire;
  w1.incarnation = real + 1;  // "restarted"
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  const std::size_t n = Encoder(w1).encode_hello(0, 1, monotonic_ns(), new_run_nonce(), RunNonce{}, false,
                                                 pair_keys(k.k1, 1, k.k0.public_key, 0).tx, d.data(), d.size());
  const EndpointStats before = r.e0->stats();
  r.t1->inject(std::vector<std::uint8_t>(d.begin(), d.begin() + static_cast<long>(n)));
  const auto got = r.exchange(61, 60, corrupt);  // the real station 1 keeps talking
  const EndpointStats s = r.e0->stats();
  CHECK_TRUE(s.peers[0].key_compromise);
  CHECK_EQUAL(w1.incarnation, s.peers[0].refused_incarnation);
  CHECK_EQUAL(real, s.peers[0].incarnation);  // never replaced...
  CHECK_EQUAL(0u, s.peers[0].incarnation_changes);
  CHECK_EQUAL(1u, s.peers[0].key_agreements);  // ...nor re-keyed with the attacker
  CHECK_EQUAL(before.drops[DropReason::incarnation_while_live] + 1, s.drops[DropReason::incarnation_while_live]);
  CHECK(s.drops[DropReason::key_compromise] >= 50);  // every datagram after the real one's next state
  CHECK_TEXT(got.size() <= 5, std::to_string(got.size()).c_str());  // at most the states in flight at the hello
  CHECK_EQUAL(0u, corrupt);
}

// A stolen key within the real station's incarnation (here the shared session key, which any key
// holder signs with): the attacker sends station 1's next 20 sequences first, so the real ones would be
// dropped as replays. The first real one is authentic with another MAC: key compromise suspected,
// named with its sequence, and nothing of station 1 is taken any more.
TEST(Keys, AStolenKeyUsingUpTheRealStationsSequencesIsNamedAsAKeyCompromise) {
  KeyFiles k("burn");
  Run r(k, false);
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1, 60, corrupt).size() >= 40);
  WireConfig w1 = r.c1.wire;
  w1.incarnation = r.e1->incarnation();  // the real one's incarnation: no restart to refuse
  const Encoder as1(w1);
  const std::vector<double> x(99, 0.0), v(99, 0.0);
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  for (std::uint64_t q = 61; q <= 80; ++q)
    for (std::size_t f = 0; f < as1.fragment_count(99); ++f) {
      const std::size_t n = as1.encode_fragment(state_to_0(q, x, v), f, d.data(), d.size());
      r.t1->inject(std::vector<std::uint8_t>(d.begin(), d.begin() + static_cast<long>(n)));
    }
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  const auto got = r.exchange(61, 60, corrupt);  // the real station 1 reaches those sequences
  const EndpointStats s = r.e0->stats();
  CHECK_TRUE(s.peers[0].key_compromise);
  CHECK_TRUE(s.peers[0].key_compromise_conflict);
  CHECK(s.peers[0].key_compromise_seq >= 61 && s.peers[0].key_compromise_seq <= 80);
  CHECK_EQUAL(0u, s.peers[0].refused_incarnation);
  CHECK_EQUAL(0u, s.peers[0].incarnation_changes);
  CHECK(s.drops[DropReason::key_compromise] >= 50);  // the real one's datagrams from then on
  for (auto q : got) CHECK(q <= 80);  // only the forgeries (delivered before the proof) and nothing after
}

// A station's pushes pause (the set-up gap between probing and the run, ~0.5 s): its endpoint keeps
// its incarnation alive with fingerprints under this run's key, so a stolen key's "restart" in the
// gap is refused too, and the real one's first states after the gap name the compromise.
TEST(Keys, APauseInTheRealStationsPushesIsNoWindowForAStolenKeysRestart) {
  KeyFiles k("pause");
  Run r(k, true, nullptr, false);
  r.c1.fingerprint.scene_nodes = 33;  // a station's endpoint (fingerprints on)
  r.c1.fingerprint.period_ns = 2'000'000;
  r.start1();
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1, 60, corrupt).size() >= 40);
  std::this_thread::sleep_for(std::chrono::duration<double>(r.c0.peer_silence_s * 1.6));  // no pushes
  const std::uint64_t real = r.e1->incarnation();
  WireConfig w1 = r.c1.wire;
  w1.incarnation = real + 1;
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  const std::size_t n = Encoder(w1).encode_hello(0, 1, monotonic_ns(), new_run_nonce(), RunNonce{}, false,
                                                 pair_keys(k.k1, 1, k.k0.public_key, 0).tx, d.data(), d.size());
  r.t1->inject(std::vector<std::uint8_t>(d.begin(), d.begin() + static_cast<long>(n)));
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EndpointStats s = r.e0->stats();
  CHECK_EQUAL(real, s.peers[0].incarnation);
  CHECK_EQUAL(0u, s.peers[0].incarnation_changes);
  CHECK_EQUAL(w1.incarnation, s.peers[0].refused_incarnation);
  r.exchange(61, 30, corrupt);  // the gap ends
  s = r.e0->stats();
  CHECK_TRUE(s.peers[0].key_compromise);
  CHECK_EQUAL(1u, s.peers[0].key_agreements);
}

TEST(Keys, ANewIncarnationForgetsThePairsKeysAndReplayStateAndTheOldOneIsRefused) {
  KeyFiles k("incarnation");
  Run r(k);
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1000, 60, corrupt).size() >= 40);  // the old process: sequences 1000..1059
  const std::uint64_t old_incarnation = r.e1->incarnation();
  std::vector<std::vector<std::uint8_t>> old_states, old_hellos;
  for (const auto& d : r.t1->sent()) {
    if (kind_of(d) == static_cast<std::uint64_t>(PayloadKind::state)) old_states.push_back(d);
    if (kind_of(d) == static_cast<std::uint64_t>(PayloadKind::hello)) old_hellos.push_back(d);
  }
  CHECK(old_states.size() >= 40 && !old_hellos.empty());
  r.e1->stop();  // station 1's process dies (and is silent for longer than net.peer_silence_s)
  std::this_thread::sleep_for(std::chrono::duration<double>(r.c0.peer_silence_s + 0.05));
  // Its restarted process's first datagram: a hello of a new incarnation with a new nonce that
  // echoes nothing yet (it has not heard station 0's nonce), MAC'd with the static pair key.
  WireConfig w1 = r.c1.wire;
  w1.incarnation = old_incarnation + 1;
  std::vector<std::uint8_t> d(kDefaultDatagramBytes);
  const std::size_t n = Encoder(w1).encode_hello(0, 1, monotonic_ns(), new_run_nonce(), RunNonce{}, false,
                                                 pair_keys(k.k1, 1, k.k0.public_key, 0).tx, d.data(), d.size());
  r.t1->inject(std::vector<std::uint8_t>(d.begin(), d.begin() + static_cast<long>(n)));
  for (int i = 0; i < 400 && r.e0->stats().peers[0].incarnation != w1.incarnation; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EndpointStats s = r.e0->stats();
  CHECK_EQUAL(w1.incarnation, s.peers[0].incarnation);
  CHECK_EQUAL(1u, s.peers[0].incarnation_changes);
  CHECK_FALSE(s.peers[0].keys_agreed);  // the traffic keys are forgotten...
  CHECK_EQUAL(1u, s.peers[0].key_agreements);
  // ...on the send side: station 0 holds its states back (only hellos leave for the new process)...
  const std::size_t sent_before = r.t0->sent().size();
  const std::uint64_t held_before = s.peers[0].tx_without_keys;
  std::vector<double> x(99), v(99);
  for (std::uint64_t q = 1060; q < 1070; ++q) {
    fill_state(0, q, x, v);
    r.e0->push_state(q, monotonic_s(), x.data(), v.data());
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const auto sent = r.t0->sent();
  for (std::size_t i = sent_before; i < sent.size(); ++i)
    CHECK_EQUAL(static_cast<std::uint64_t>(PayloadKind::hello), kind_of(sent[i]));
  CHECK_EQUAL(held_before + 10, r.e0->stats().peers[0].tx_without_keys);
  // ...and on the receive side: the old process's states (under the old keys) and hellos are refused.
  s = r.e0->stats();
  for (const auto& o : old_states) r.t1->inject(o);
  for (const auto& o : old_hellos) r.t1->inject(o);
  CHECK_TRUE(wait_drops(*r.e0, s.drops.total(), old_states.size() + old_hellos.size()));
  EndpointStats t = r.e0->stats();
  CHECK_EQUAL(s.drops[DropReason::keys_not_agreed] + old_states.size(), t.drops[DropReason::keys_not_agreed]);
  CHECK_EQUAL(s.drops[DropReason::old_incarnation] + old_hellos.size(), t.drops[DropReason::old_incarnation]);
  std::size_t delivered = 0;
  r.e0->drain([&](auto...) { ++delivered; });
  CHECK_EQUAL(0u, delivered);
  // The real restarted process (an even newer incarnation) starts its sequences afresh, far below the
  // old newest (1059): delivered, because the replay window went with the old incarnation.
  r.start1();
  const auto got = r.exchange(1, 80, corrupt);
  CHECK_TEXT(got.size() >= 50, std::to_string(got.size()).c_str());
  for (auto q : got) CHECK(q < 1000);
  CHECK_EQUAL(0u, corrupt);
  CHECK_EQUAL(2u, r.e0->stats().peers[0].key_agreements);
  // The old process again, after the new agreement: its states fail the new keys, its hellos the
  // incarnation rule; nothing is delivered.
  s = r.e0->stats();
  for (const auto& o : old_states) r.t1->inject(o);
  for (const auto& o : old_hellos) r.t1->inject(o);
  CHECK_TRUE(wait_drops(*r.e0, s.drops.total(), old_states.size() + old_hellos.size()));
  t = r.e0->stats();
  CHECK_EQUAL(s.drops[DropReason::bad_mac] + old_states.size(), t.drops[DropReason::bad_mac]);
  CHECK_EQUAL(s.drops[DropReason::old_incarnation] + old_hellos.size(), t.drops[DropReason::old_incarnation]);
  delivered = 0;
  r.e0->drain([&](auto...) { ++delivered; });
  CHECK_EQUAL(0u, delivered);
}

// Within one run, every kind of a neighbour's datagrams replayed (its hellos, its fingerprints, its
// keep-alives among them, its state fragments) is refused and counted under its kind, and nothing it
// carries counts again: no hello, fingerprint or state is taken twice.
TEST(Keys, EveryKindOfThisRunsDatagramsReplayedIsRefusedAndCountedUnderItsKind) {
  KeyFiles k("replay-kinds");
  Run r(k, true, nullptr, false);
  r.c1.fingerprint.scene_nodes = 33;  // a station's endpoint: fingerprints, and keep-alives while pushes pause
  r.c1.fingerprint.period_ns = 2'000'000;
  r.start1();
  std::uint64_t corrupt = 0;
  CHECK(r.exchange(1, 60, corrupt).size() >= 40);
  std::this_thread::sleep_for(std::chrono::duration<double>(r.c1.peer_silence_s * 0.7));  // keep-alives
  r.e1->stop();  // nothing new from station 1 from here on
  const auto capture = r.t1->sent();
  std::uint64_t kinds[4] = {0, 0, 0, 0};
  for (const auto& d : capture) ++kinds[kind_of(d) & 3];
  const std::uint64_t states = kinds[1], fingerprints = kinds[2], hellos = kinds[3];
  // At least one of each kind (how many fingerprints and keep-alives leave depends on how often the
  // loaded host runs station 1's I/O thread: 12-13 fingerprints quiet, fewer than 10 seen at load 8-9).
  const std::string kinds_seen = "states " + std::to_string(states) + ", fingerprints " + std::to_string(fingerprints) +
                                 ", hellos " + std::to_string(hellos);
  CHECK_TEXT(states >= 40 && fingerprints >= 1 && hellos >= 1, kinds_seen.c_str());
  CHECK_EQUAL(capture.size(), states + fingerprints + hellos);
  // Once, so that what station 0 dropped the first time (sent before it had agreed) has been taken...
  const std::uint64_t d0 = r.e0->stats().datagrams_received;
  for (const auto& d : capture) r.t1->inject(d);
  CHECK_TRUE(wait_datagrams(*r.e0, d0, capture.size()));
  r.e0->drain([](auto...) {});
  // ...then again: every datagram refused, each counted once under its kind.
  const EndpointStats before = r.e0->stats();
  for (const auto& d : capture) r.t1->inject(d);
  CHECK_TRUE(wait_drops(*r.e0, before.drops.total(), capture.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const EndpointStats after = r.e0->stats();
  CHECK_EQUAL(before.drops.total() + capture.size(), after.drops.total());
  CHECK_EQUAL(before.drops[DropReason::replayed_hello] + hellos, after.drops[DropReason::replayed_hello]);
  CHECK_EQUAL(before.drops[DropReason::replayed_fingerprint] + fingerprints, after.drops[DropReason::replayed_fingerprint]);
  CHECK_EQUAL(before.drops[DropReason::replayed] + states, after.drops[DropReason::replayed]);
  CHECK_EQUAL(before.fingerprints_received, after.fingerprints_received);
  CHECK_EQUAL(before.peers[0].hellos_received, after.peers[0].hellos_received);
  CHECK_EQUAL(before.peers[0].packets_received, after.peers[0].packets_received);
  std::size_t late = 0;
  r.e0->drain([&](auto...) { ++late; });
  CHECK_EQUAL(0u, late);
}
