// haptic-flood: the attacker of the four-process flood run (tools/flood/flood_run.py).
// Sends a bounded flood (count AND time) of every attack class at the stations of one lab on
// loopback, as fast as this machine sends (or at --rate), and prints one JSON object: datagrams
// sent per class, the achieved rate, what it sniffed. Traffic goes only to 127.0.0.0/8.
//
// What each class needs (the threat model, net/README.md "Receive-path sanity"):
// - no privilege, no key (from the attacker's own UDP socket): garbage, truncated, bad MAC,
//   oversized, zero-length, forged far-future sequence (claiming a neighbour, wrong address),
//   and, with --sniff, live replay of captured genuine datagrams from the attacker's address.
// - root, no key (an on-path attacker: sniffs loopback with AF_PACKET, spoofs the neighbour's
//   source address and port with a raw IPv4 socket): live replay and cross-run replay (--replay
//   FILE, datagrams recorded with --record in an earlier run of the same station files: same
//   session id, keys and ports), bad MAC and forged future sequence from the right address.
// - root + a stolen station key (--stolen-key S=FILE, --public-key J=HEX: the attacker holds
//   station S's secret, e.g. a compromised PC; it learns the run nonces from the hellos it
//   sniffs, which travel in the clear, and derives S's traffic keys like S does): authentic
//   (valid MAC, S's incarnation, from S's address) states with NaN, far out of the physical
//   envelope, or a sequence 10^6 ahead, each at the sequence S's next genuine packet will carry.
//   keyed_restart (only when named in --classes: it is a takeover attempt, not a flood class): a
//   hello in S's name from a newer incarnation (S's sniffed one + 1, a fresh nonce), as a second
//   process holding S's key would announce itself while S runs (net/README.md "Incarnations and
//   restarts": refused, and S's next states make two live incarnations).
//   keyed_sequence_burn (only when named, as keyed_restart): within S's own incarnation, a captured
//   genuine state of S (plausible values) re-sent with a sequence a few ticks beyond S's newest and a
//   valid MAC, so S's own packet with that sequence would be dropped as a replay (net/README.md "Two
//   signers in one incarnation": S's packet then proves a second holder of the key).
// --record FILE: sniff only (send nothing) and store every genuine station datagram (bounded).
#include <arpa/inet.h>
#include <sodium.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <netinet/in.h>
#include <netinet/ip.h>
#include <netinet/udp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "net/keys.hpp"
#include "net/wire.hpp"

using namespace haptic::net;

namespace {

enum Class : int {
  garbage,
  truncated,
  bad_mac,
  oversized,
  zero_length,
  future_wrong_addr,
  replay_wrong_addr,
  spoof_bad_mac,
  spoof_future,
  live_replay,
  cross_run_replay,
  keyed_nan,
  keyed_envelope,
  keyed_future,
  keyed_restart,
  keyed_burn,
  class_count
};
const char* kNames[class_count] = {"garbage",     "truncated",     "bad_mac",       "oversized",  "zero_length",
                                   "future_sequence_wrong_address",  "live_replay_wrong_address", "spoofed_bad_mac",
                                   "spoofed_future_sequence",        "live_replay",   "cross_run_replay",
                                   "keyed_nan",   "keyed_out_of_envelope",          "keyed_future_sequence", "keyed_restart",
                                   "keyed_sequence_burn"};
bool needs_root(int c) { return c >= spoof_bad_mac; }
bool needs_sniff(int c) { return c == replay_wrong_addr || c == live_replay || c >= keyed_nan; }

constexpr std::uint8_t kAttackTos = 0x04;  // marks our spoofed packets so the sniffer skips them

struct Station {
  std::uint16_t id = 0;
  std::uint16_t port = 0;  // on 127.0.0.1
};

// One captured datagram between two stations (ports identify them).
struct Captured {
  std::uint16_t src_port = 0, dst_port = 0;
  std::vector<std::uint8_t> bytes;
};

// What the sniffer learned about one directed link S -> J (for the keyed classes).
struct LinkView {
  RunNonce nonce{};  // S's run nonce, from its hellos to J
  bool have_nonce = false;
  std::uint64_t incarnation = 0, newest_seq = 0;
  std::uint32_t value_count = 0;
  std::uint8_t flags = 0;
  bool have_state = false;
};

template <class T>
T get(const std::uint8_t* p, std::size_t off) {
  T v;
  std::memcpy(&v, p + off, sizeof v);
  return v;
}

struct Shared {
  std::mutex m;
  std::vector<Captured> recent;  // ring of recent genuine datagrams (live replay)
  std::size_t recent_next = 0;
  std::map<std::pair<std::uint16_t, std::uint16_t>, LinkView> links;  // (sender id, dest id)
  std::vector<Captured> recorded;
  std::uint64_t sniffed = 0;
};

[[noreturn]] void usage(const char* why, int code = 2) {
  std::fprintf(stderr,
               "haptic-flood: %s\n"
               "usage: haptic-flood --station ID=PORT... --link I-J... --session N --duration S --max-datagrams N\n"
               "         [--rate R (datagrams/s, 0 = as fast as possible)] [--spoof-rate-per-link R (default 5000)]\n"
               "         [--classes a,b,...] [--sniff] [--replay FILE] [--record FILE] [--stolen-key S=FILE]\n"
               "         [--public-key ID=HEX]... [--start-after S] [--json FILE]\n"
               "classes: ",
               why);
  for (int c = 0; c < class_count; ++c) std::fprintf(stderr, "%s%s", kNames[c], c + 1 < class_count ? "," : "\n");
  std::exit(code);
}

sockaddr_in loopback(std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return a;
}

// The sniffer: every UDP datagram on lo between two station ports that carries the wire magic
// and is not ours. Runs until `stop`; bounded by the caller's duration.
void sniff(int fd, const std::map<std::uint16_t, std::uint16_t>& id_of_port, Shared& sh, bool record,
           std::size_t record_max, const std::atomic<bool>& stop) {
  std::vector<std::uint8_t> buf(70000);
  while (!stop.load()) {
    sockaddr_ll from{};
    socklen_t fl = sizeof from;
    const ssize_t n = ::recvfrom(fd, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &fl);
    if (n < 0) continue;  // timeout (SO_RCVTIMEO): check stop
    if (from.sll_pkttype == PACKET_OUTGOING) continue;  // lo shows each packet twice
    if (n < 28 || (buf[0] >> 4) != 4 || buf[9] != IPPROTO_UDP) continue;
    if ((buf[1] & 0xFC) == kAttackTos) continue;
    const std::size_t ihl = std::size_t{buf[0] & 0x0Fu} * 4;
    if (static_cast<std::size_t>(n) < ihl + 8) continue;
    const std::uint8_t* udp = buf.data() + ihl;
    const std::uint16_t sp = ntohs(get<std::uint16_t>(udp, 0)), dp = ntohs(get<std::uint16_t>(udp, 2));
    if (!id_of_port.count(sp) || !id_of_port.count(dp)) continue;
    const std::uint8_t* d = udp + 8;
    const std::size_t len = static_cast<std::size_t>(n) - ihl - 8;
    if (len < kHeaderBytes || get<std::uint32_t>(d, wire_offset::magic) != kWireMagic) continue;
    Captured c{sp, dp, std::vector<std::uint8_t>(d, d + len)};
    const std::uint16_t s = id_of_port.at(sp), j = id_of_port.at(dp);
    std::lock_guard<std::mutex> lk(sh.m);
    ++sh.sniffed;
    LinkView& v = sh.links[{s, j}];
    const std::uint8_t kind = d[wire_offset::kind];
    if (kind == static_cast<std::uint8_t>(PayloadKind::hello) && len >= kHeaderBytes + kHelloBytes) {
      std::memcpy(v.nonce.data(), d + kHeaderBytes, kRunNonceBytes);
      v.have_nonce = true;
    } else if (kind == static_cast<std::uint8_t>(PayloadKind::state)) {
      const std::uint64_t inc = get<std::uint64_t>(d, wire_offset::incarnation);
      const std::uint64_t seq = get<std::uint64_t>(d, wire_offset::seq);
      if (inc != v.incarnation) v.newest_seq = 0;
      v.incarnation = inc;
      v.newest_seq = std::max(v.newest_seq, seq);
      v.value_count = get<std::uint32_t>(d, wire_offset::value_count);
      v.flags = d[wire_offset::flags];
      v.have_state = true;
    }
    if (record) {
      if (sh.recorded.size() < record_max) sh.recorded.push_back(c);
      continue;
    }
    if (sh.recent.size() < 512) sh.recent.push_back(std::move(c));
    else sh.recent[sh.recent_next++ % sh.recent.size()] = std::move(c);
  }
}

void write_capture(const std::string& path, const std::vector<Captured>& v) {
  std::ofstream f(path, std::ios::binary);
  for (const auto& c : v) {
    const std::uint32_t len = static_cast<std::uint32_t>(c.bytes.size());
    f.write(reinterpret_cast<const char*>(&c.src_port), 2);
    f.write(reinterpret_cast<const char*>(&c.dst_port), 2);
    f.write(reinterpret_cast<const char*>(&len), 4);
    f.write(reinterpret_cast<const char*>(c.bytes.data()), len);
  }
  if (!f) throw std::runtime_error("cannot write " + path);
}

std::vector<Captured> read_capture(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  std::vector<Captured> v;
  for (;;) {
    Captured c;
    std::uint32_t len = 0;
    if (!f.read(reinterpret_cast<char*>(&c.src_port), 2)) break;
    f.read(reinterpret_cast<char*>(&c.dst_port), 2);
    f.read(reinterpret_cast<char*>(&len), 4);
    if (!f || len > kMaxDatagramBytes) throw std::runtime_error(path + ": not a capture file");
    c.bytes.resize(len);
    if (!f.read(reinterpret_cast<char*>(c.bytes.data()), len)) throw std::runtime_error(path + ": truncated");
    v.push_back(std::move(c));
  }
  return v;
}

// Spoofed IPv4/UDP on loopback through a raw socket (root): source 127.0.0.1:src_port.
struct Spoofer {
  int fd = -1;
  std::vector<std::uint8_t> pkt = std::vector<std::uint8_t>(65535);
  Spoofer() {
    fd = ::socket(AF_INET, SOCK_RAW, IPPROTO_RAW);
    if (fd < 0) throw std::runtime_error(std::string("raw socket (needs root): ") + std::strerror(errno));
  }
  ~Spoofer() {
    if (fd >= 0) ::close(fd);
  }
  bool send(std::uint16_t src_port, std::uint16_t dst_port, const std::uint8_t* d, std::size_t n) {
    if (n + 28 > pkt.size()) return false;
    std::memset(pkt.data(), 0, 28);
    pkt[0] = 0x45;
    pkt[1] = kAttackTos;
    const std::uint16_t tot = htons(static_cast<std::uint16_t>(n + 28)), ulen = htons(static_cast<std::uint16_t>(n + 8));
    std::memcpy(&pkt[2], &tot, 2);
    pkt[8] = 64;
    pkt[9] = IPPROTO_UDP;
    const std::uint32_t lo = htonl(INADDR_LOOPBACK);
    std::memcpy(&pkt[12], &lo, 4);
    std::memcpy(&pkt[16], &lo, 4);
    const std::uint16_t sp = htons(src_port), dp = htons(dst_port);
    std::memcpy(&pkt[20], &sp, 2);
    std::memcpy(&pkt[22], &dp, 2);
    std::memcpy(&pkt[24], &ulen, 2);  // UDP checksum 0: none (IPv4)
    std::memcpy(&pkt[28], d, n);
    const sockaddr_in to = loopback(dst_port);
    return ::sendto(fd, pkt.data(), n + 28, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) >= 0;
  }
};

struct Options {
  std::vector<Station> stations;
  std::vector<std::pair<std::uint16_t, std::uint16_t>> links;  // directed, both ways
  std::uint32_t session = 0;
  double duration_s = 0, rate = 0, spoof_rate_per_link = 5000, start_after_s = 0;
  std::uint64_t max_datagrams = 0;
  std::vector<bool> classes = std::vector<bool>(class_count, false);
  bool classes_given = false, sniff = false;
  std::string replay_file, record_file, json_file;
  int stolen_id = -1;
  std::string stolen_file;
  std::map<std::uint16_t, PublicKey> public_keys;
};

// One option (and its value) at argv[i]; advances i past the value. Not RT-safe.
void parse_one(Options& o, const std::string& a, int argc, char** argv, int& i) {
  auto next = [&]() -> std::string {
    if (i + 1 >= argc) usage((a + " needs a value").c_str());
    return argv[++i];
  };
  auto id_eq = [&](const std::string& v, std::string& rest) {
    const auto eq = v.find('=');
    if (eq == std::string::npos) usage((a + " needs ID=VALUE, got " + v).c_str());
    rest = v.substr(eq + 1);
    return static_cast<std::uint16_t>(std::stoul(v.substr(0, eq)));
  };
  std::string rest;
  if (a == "--station") {
    const std::uint16_t id = id_eq(next(), rest);
    o.stations.push_back({id, static_cast<std::uint16_t>(std::stoul(rest))});
  } else if (a == "--link") {
    const std::string v = next();
    const auto dash = v.find('-');
    if (dash == std::string::npos) usage("--link needs I-J");
    const auto x = static_cast<std::uint16_t>(std::stoul(v.substr(0, dash))), y = static_cast<std::uint16_t>(std::stoul(v.substr(dash + 1)));
    o.links.push_back({x, y});
    o.links.push_back({y, x});
  } else if (a == "--session") o.session = static_cast<std::uint32_t>(std::stoul(next()));
  else if (a == "--duration") o.duration_s = std::stod(next());
  else if (a == "--max-datagrams") o.max_datagrams = std::stoull(next());
  else if (a == "--rate") o.rate = std::stod(next());
  else if (a == "--spoof-rate-per-link") o.spoof_rate_per_link = std::stod(next());
  else if (a == "--start-after") o.start_after_s = std::stod(next());
  else if (a == "--sniff") o.sniff = true;
  else if (a == "--replay") o.replay_file = next();
  else if (a == "--record") o.record_file = next();
  else if (a == "--json") o.json_file = next();
  else if (a == "--stolen-key") {
    o.stolen_id = id_eq(next(), o.stolen_file);
  } else if (a == "--public-key") {
    const std::uint16_t id = id_eq(next(), rest);
    o.public_keys[id] = public_key_from_hex(rest, "--public-key");
  } else if (a == "--classes") {
    o.classes_given = true;
    std::string v = next() + ",";
    for (std::size_t p = 0, q; (q = v.find(',', p)) != std::string::npos; p = q + 1) {
      const std::string name = v.substr(p, q - p);
      if (name.empty()) continue;
      int c = 0;
      while (c < class_count && name != kNames[c]) ++c;
      if (c == class_count) usage(("unknown class " + name).c_str());
      o.classes[static_cast<std::size_t>(c)] = true;
    }
  } else if (a == "-h" || a == "--help") usage("the attacker of tools/flood/flood_run.py (see the comment at the top of tools/net/flood.cpp)", 0);
  else usage(("unknown option " + a).c_str());
}

// The checks after all options were read; fills in the default classes. Not RT-safe.
Options finish(Options o) {
  if (o.stations.empty() || o.links.empty() || o.session == 0) usage("need --station, --link and --session");
  if (!(o.duration_s > 0 && o.duration_s <= 600)) usage("--duration must be in (0, 600] s");
  if (o.record_file.empty() && (o.max_datagrams == 0 || o.max_datagrams > 1'000'000'000))
    usage("--max-datagrams must be in [1, 1e9]");
  if (!(o.rate >= 0) || !(o.spoof_rate_per_link >= 0) || !(o.start_after_s >= 0 && o.start_after_s < o.duration_s))
    usage("--rate, --spoof-rate-per-link >= 0; --start-after in [0, duration)");
  if (!o.classes_given) {  // every class this run can send
    const bool root = ::geteuid() == 0;
    for (int c = 0; c < class_count; ++c) {
      bool ok = (!needs_root(c) || root) && (!needs_sniff(c) || o.sniff);
      if (c == cross_run_replay) ok = ok && !o.replay_file.empty();
      if (c >= keyed_nan) ok = ok && o.stolen_id >= 0;
      if (c == keyed_restart || c == keyed_burn) ok = false;  // attempts to take a link over: only when named
      o.classes[static_cast<std::size_t>(c)] = ok;
    }
  }
  return o;
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    try {
      parse_one(o, a, argc, argv, i);
    } catch (const std::logic_error& e) {  // std::stoul / std::stod (invalid_argument, out_of_range), a bad key
      const std::string what = e.what();
      usage((a + " " + (i < argc ? argv[i] : "") + ": " +
             (what.rfind("sto", 0) == 0 ? std::string("not a valid number (or out of range)") : what)).c_str());
    }
  }
  return finish(o);
}

// The report: stdout, and `path` when given.
void emit(const std::string& js, const std::string& path) {
  std::fputs(js.c_str(), stdout);
  if (path.empty()) return;
  std::ofstream f(path);
  f << js;
  if (!f) throw std::runtime_error("cannot write " + path);
}

// One run of the attacker: the sniffer (with --sniff or --record), the sockets, the datagrams it
// forges and what it counted. The steps, in order: start_sniffer, then record (--record) or
// prepare, send_all, stop and report. Not RT-safe.
class Flood {
 public:
  static constexpr std::uint32_t kValues = 99;
  static constexpr std::uint64_t kBurnAhead = 5;  // keyed_sequence_burn: ticks beyond the newest sniffed

  // Which port each station listens on; every --link must name two --station.
  explicit Flood(const Options& o) : o_(o) {
    for (const auto& s : o_.stations) {
      id_of_port_[s.port] = s.id;
      port_of_[s.id] = s.port;
    }
    for (const auto& l : o_.links)
      if (!port_of_.count(l.first) || !port_of_.count(l.second)) usage("--link names a station without --station");
  }

  // The AF_PACKET sniffer on lo (--sniff, --record); the run's clock starts after it.
  void start_sniffer() {
    const bool recording = !o_.record_file.empty();
    if (o_.sniff || recording) {
      sniff_fd_ = ::socket(AF_PACKET, SOCK_DGRAM, htons(ETH_P_IP));
      if (sniff_fd_ < 0) throw std::runtime_error(std::string("AF_PACKET socket (needs root): ") + std::strerror(errno));
      sockaddr_ll ll{};
      ll.sll_family = AF_PACKET;
      ll.sll_protocol = htons(ETH_P_IP);
      ll.sll_ifindex = static_cast<int>(if_nametoindex("lo"));
      if (ll.sll_ifindex == 0 || ::bind(sniff_fd_, reinterpret_cast<sockaddr*>(&ll), sizeof ll) != 0)
        throw std::runtime_error("cannot bind the sniffer to lo");
      timeval tv{0, 100000};
      ::setsockopt(sniff_fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      int big = 8 << 20;
      ::setsockopt(sniff_fd_, SOL_SOCKET, SO_RCVBUFFORCE, &big, sizeof big);
      sniffer_ = std::thread(sniff, sniff_fd_, std::cref(id_of_port_), std::ref(sh_), recording, std::size_t{200000}, std::cref(stop_));
    }
    t0_ = std::chrono::steady_clock::now();
  }

  // --record: sniff for --duration, store the genuine datagrams, report how many.
  void record() {
    while (elapsed() < o_.duration_s) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop_ = true;
    sniffer_.join();
    ::close(sniff_fd_);
    write_capture(o_.record_file, sh_.recorded);
    emit("{\"recorded\": " + std::to_string(sh_.recorded.size()) + ", \"sniffed\": " + std::to_string(sh_.sniffed) + "}\n",
         o_.json_file);
  }

  // Everything the flood sends from: the old run's capture, the stolen key, the sockets, the
  // random bytes, the classes to send and a template datagram per directed link.
  void prepare() {
    if (o_.classes[cross_run_replay]) {
      old_run_ = read_capture(o_.replay_file);
      if (old_run_.empty()) throw std::runtime_error(o_.replay_file + " holds no datagram");
    }
    if (o_.stolen_id >= 0) stolen_ = read_key_file(o_.stolen_file, "--stolen-key", false);
    bool any_root = false;
    for (int c = 0; c < class_count; ++c) any_root = any_root || (o_.classes[static_cast<std::size_t>(c)] && needs_root(c));
    if (any_root) spoof_ = std::make_unique<Spoofer>();
    udp_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    if (udp_ < 0) throw std::runtime_error("udp socket");
    int sndbuf = 4 << 20;
    ::setsockopt(udp_, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf);

    for (auto& b : big_) b = static_cast<std::uint8_t>(rng_());
    x_nan_[7] = std::numeric_limits<double>::quiet_NaN();
    SessionKey random_key{};
    for (auto& b : random_key.bytes) b = static_cast<std::uint8_t>(rng_());

    for (int c = 0; c < class_count; ++c)
      if (o_.classes[static_cast<std::size_t>(c)]) active_.push_back(c);
    if (active_.empty()) usage("no class to send (spoofed and replay classes need root and --sniff)");
    // One well-formed datagram per directed link, MAC'd with a key no station holds: the keyless
    // classes patch its sequence (the MAC fails either way), so they cost a copy, not a MAC.
    for (const auto& l : o_.links) {
      const std::size_t n = forge(l.first, l.second, 1, 1, x_.data(), ValueEncoding::float32, random_key);
      tmpl_.emplace_back(d_.begin(), d_.begin() + static_cast<std::ptrdiff_t>(n));
    }
  }

  // The flood: the active classes in turn over the directed links, until --max-datagrams were
  // sent or --duration is over; at most --rate datagrams/s, spoofed ones within each link's budget.
  void send_all() {
    double last_refill = 0.0;
    std::uint64_t iter = 0;
    while (total_ < o_.max_datagrams) {
      const double t = elapsed();
      if (t >= o_.duration_s) break;
      if (t < o_.start_after_s) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        continue;
      }
      if (flood_start_ < 0) flood_start_ = last_refill = t;
      if (o_.rate > 0 && static_cast<double>(total_) > (t - flood_start_) * o_.rate) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        continue;
      }
      for (std::size_t k = 0; k < tokens_.size(); ++k)
        tokens_[k] = std::min(o_.spoof_rate_per_link * 0.01, tokens_[k] + (t - last_refill) * o_.spoof_rate_per_link);
      last_refill = t;
      const int c = active_[iter % active_.size()];
      const std::size_t li = (iter / active_.size()) % o_.links.size();
      ++iter;
      bool spoofed = needs_root(c);
      if (spoofed) {
        if (tokens_[li] < 1.0) {
          ++skipped_[c];
          continue;
        }
      }
      Datagram dg = build(c, li, iter);
      if (dg.n == 0 && c != zero_length) {
        ++skipped_[c];  // nothing captured / learned yet
        continue;
      }
      if (spoofed) tokens_[li] -= 1.0;
      bool ok;
      if (spoofed) ok = spoof_->send(dg.src_port, ntohs(dg.to.sin_port), dg.payload, dg.n);
      else ok = ::sendto(udp_, dg.payload, dg.n, 0, reinterpret_cast<const sockaddr*>(&dg.to), sizeof dg.to) >= 0;
      if (ok) {
        ++sent_[c];
        ++total_;
        flood_end_ = elapsed();
      } else {
        ++errors_[c];
      }
    }
  }

  void stop() {
    stop_ = true;
    if (sniffer_.joinable()) sniffer_.join();
    if (sniff_fd_ >= 0) ::close(sniff_fd_);
    ::close(udp_);
  }

  // The JSON report: totals, the achieved rate, what was sniffed, and per class.
  void report() const {
    const double span = flood_start_ >= 0 ? flood_end_ - flood_start_ : 0.0;
    std::string js = "{\n  \"sent_total\": " + std::to_string(total_) + ",\n  \"flood_s\": " + std::to_string(span) +
                     ",\n  \"rate_per_s\": " + std::to_string(span > 0 ? static_cast<double>(total_) / span : 0.0) +
                     ",\n  \"sniffed\": " + std::to_string(sh_.sniffed) + ",\n  \"classes\": {";
    for (std::size_t i = 0; i < active_.size(); ++i) {
      const int c = active_[i];
      js += std::string(i ? "," : "") + "\n    \"" + kNames[c] + "\": {\"sent\": " + std::to_string(sent_[c]) +
            ", \"send_errors\": " + std::to_string(errors_[c]) + ", \"skipped\": " + std::to_string(skipped_[c]) +
            ", \"spoofed\": " + (needs_root(c) ? "true" : "false") + "}";
    }
    js += "\n  }\n}\n";
    emit(js, o_.json_file);
  }

 private:
  // One datagram to send: n bytes at payload, from 127.0.0.1:src_port (spoofed classes) to `to`.
  struct Datagram {
    sockaddr_in to{};
    std::size_t n = 0;
    const std::uint8_t* payload = nullptr;
    std::uint16_t src_port = 0;
  };

  double elapsed() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count(); }

  // A datagram with a valid format claiming sender s -> dest j, MAC'd with `key`.
  std::size_t forge(std::uint16_t s, std::uint16_t j, std::uint64_t seq, std::uint64_t incarnation, const double* xs,
                    ValueEncoding enc, const SessionKey& key) {
    WireConfig w;
    w.session_id = o_.session;
    w.station_id = s;
    w.incarnation = incarnation;
    w.encoding = enc;
    Encoder e(w);
    OutgoingState st;
    st.dest = j;
    st.seq = seq;
    st.send_time_ns = static_cast<std::int64_t>(elapsed() * 1e9);
    st.value_count = kValues;
    st.x_hat = xs;
    st.v_hat = v_.data();
    return e.encode_fragment(st, 0, d_.data(), d_.size(), &key);
  }

  std::size_t from_template(std::size_t li, std::uint64_t seq) {
    std::memcpy(d_.data(), tmpl_[li].data(), tmpl_[li].size());
    std::memcpy(d_.data() + wire_offset::seq, &seq, sizeof seq);
    return tmpl_[li].size();
  }

  // A replayed datagram (live or from the old run) into d_: sent to where it went, from where it came.
  void replay(const Captured& cap, Datagram& dg) {
    dg.n = cap.bytes.size();
    std::memcpy(d_.data(), cap.bytes.data(), dg.n);
    dg.src_port = cap.src_port;
    dg.to = loopback(cap.dst_port);
  }

  // An authentic state from the stolen station s to j (NaN, out of the envelope, or far ahead),
  // at the sequence s's next genuine one carries; 0 when s is not the stolen station or the
  // sniffer has not learned the link's nonces and state yet.
  std::size_t keyed(int c, std::uint16_t s, std::uint16_t j) {
    if (static_cast<int>(s) != o_.stolen_id || !o_.public_keys.count(j)) return 0;
    LinkView sv, jv;
    {
      std::lock_guard<std::mutex> lk(sh_.m);
      sv = sh_.links[{s, j}];
      jv = sh_.links[{j, s}];
    }
    if (!sv.have_nonce || !jv.have_nonce || !sv.have_state) return 0;
    const SessionKey k = traffic_key(pair_keys(stolen_, s, o_.public_keys.at(j), j).tx, sv.nonce, jv.nonce);
    const ValueEncoding enc = (sv.flags & kFlagFloat32) ? ValueEncoding::float32 : ValueEncoding::float64;
    if (c == keyed_burn) return burn(s, j, sv.newest_seq + kBurnAhead, k);
    const std::uint64_t seq = sv.newest_seq + 1 + (c == keyed_future ? 1'000'000ull : 0);
    return forge(s, j, seq, sv.incarnation, c == keyed_nan ? x_nan_.data() : c == keyed_envelope ? x_bad_.data() : x_.data(),
                 enc, k);
  }

  // keyed_sequence_burn: a captured genuine state datagram of s to j (its values, incarnation and layout)
  // with sequence seq and a valid MAC under s's traffic key k; 0 before one was captured.
  std::size_t burn(std::uint16_t s, std::uint16_t j, std::uint64_t seq, const SessionKey& k) {
    std::lock_guard<std::mutex> lk(sh_.m);
    for (const Captured& c : sh_.recent) {
      const std::uint8_t* d = c.bytes.data();
      if (c.src_port != port_of_[s] || c.dst_port != port_of_[j] || d[wire_offset::kind] != static_cast<std::uint8_t>(PayloadKind::state))
        continue;
      const std::size_t body = kHeaderBytes + get<std::uint16_t>(d, wire_offset::frag_len);
      if (c.bytes.size() != body + kMacBytes || c.bytes.size() > d_.size()) continue;
      std::memcpy(d_.data(), d, c.bytes.size());
      std::memcpy(d_.data() + wire_offset::seq, &seq, sizeof seq);
      crypto_generichash(d_.data() + body, kMacBytes, d_.data(), body, k.bytes.data(), k.bytes.size());
      return c.bytes.size();
    }
    return 0;
  }

  // A hello in the stolen station s's name to j from a newer incarnation than the one sniffed, with a
  // fresh nonce (a second process holding s's key); 0 before the sniffer saw s's states to j.
  std::size_t keyed_hello(std::uint16_t s, std::uint16_t j) {
    if (static_cast<int>(s) != o_.stolen_id || !o_.public_keys.count(j)) return 0;
    LinkView sv;
    {
      std::lock_guard<std::mutex> lk(sh_.m);
      sv = sh_.links[{s, j}];
    }
    if (!sv.have_state) return 0;
    if (forged_nonce_ == RunNonce{}) forged_nonce_ = new_run_nonce();
    WireConfig w;
    w.session_id = o_.session;
    w.station_id = s;
    w.incarnation = sv.incarnation + 1;
    const SessionKey hello_key = pair_keys(stolen_, s, o_.public_keys.at(j), j).tx;
    return Encoder(w).encode_hello(j, sv.newest_seq + 1, static_cast<std::int64_t>(elapsed() * 1e9), forged_nonce_, RunNonce{}, false,
                                   hello_key, d_.data(), d_.size());
  }

  // The datagram of class c on directed link li (the iter-th of the flood); n = 0: nothing to
  // send yet (nothing captured or learned), except for zero_length.
  Datagram build(int c, std::size_t li, std::uint64_t iter) {
    const std::uint16_t s = o_.links[li].first, j = o_.links[li].second;  // claimed sender, victim
    Datagram dg;
    dg.to = loopback(port_of_[j]);
    dg.payload = d_.data();
    dg.src_port = port_of_[s];
    switch (c) {
      case garbage:
        dg.n = 1 + rng_() % kDefaultDatagramBytes;
        dg.payload = big_.data() + rng_() % 60000;
        break;
      case truncated:
        from_template(li, 1 + iter);
        dg.n = rng_() % (kHeaderBytes + kMacBytes);
        if (dg.n == 0) dg.n = 1;
        break;
      case bad_mac:
      case spoof_bad_mac: dg.n = from_template(li, 1 + iter % 100000); break;
      case oversized:
        dg.n = kDefaultDatagramBytes + 1 + rng_() % (big_.size() - kDefaultDatagramBytes - 1);
        dg.payload = big_.data();
        break;
      case zero_length: dg.n = 0; break;
      case future_wrong_addr:
      case spoof_future: dg.n = from_template(li, 1'000'000'000ull + iter); break;
      case replay_wrong_addr:
      case live_replay: {
        std::lock_guard<std::mutex> lk(sh_.m);
        if (sh_.recent.empty()) break;
        replay(sh_.recent[rng_() % sh_.recent.size()], dg);
        break;
      }
      case cross_run_replay: replay(old_run_[rng_() % old_run_.size()], dg); break;
      case keyed_nan:
      case keyed_envelope:
      case keyed_future:
      case keyed_burn: dg.n = keyed(c, s, j); break;
      case keyed_restart: dg.n = keyed_hello(s, j); break;
      default: break;
    }
    return dg;
  }

  const Options& o_;
  std::map<std::uint16_t, std::uint16_t> id_of_port_, port_of_;
  Shared sh_;
  std::atomic<bool> stop_{false};
  int sniff_fd_ = -1;
  std::chrono::steady_clock::time_point t0_;

  std::vector<Captured> old_run_;
  StationKeyPair stolen_{};
  RunNonce forged_nonce_{};  // keyed_restart: the forged process's run nonce
  std::unique_ptr<Spoofer> spoof_;
  int udp_ = -1;
  std::mt19937_64 rng_{0x464c4f4f44ull};  // "FLOOD": the same flood every run
  std::vector<std::uint8_t> big_ = std::vector<std::uint8_t>(65000), d_ = std::vector<std::uint8_t>(kMaxDatagramBytes);
  std::vector<double> x_ = std::vector<double>(kValues, 0.01), v_ = std::vector<double>(kValues, 0.0),
                      x_bad_ = std::vector<double>(kValues, 1.0e3), x_nan_ = std::vector<double>(kValues, 0.01);
  std::vector<int> active_;
  std::vector<std::uint64_t> sent_ = std::vector<std::uint64_t>(class_count, 0), errors_ = std::vector<std::uint64_t>(class_count, 0),
                             skipped_ = std::vector<std::uint64_t>(class_count, 0);
  // Spoofed datagrams per directed link: a token bucket each (they share the real neighbour's
  // per-source budget at the receiver, net.rx_rate_limit_per_s).
  std::vector<double> tokens_ = std::vector<double>(o_.links.size(), 0.0);
  double flood_start_ = -1.0, flood_end_ = 0.0;
  std::uint64_t total_ = 0;
  std::vector<std::vector<std::uint8_t>> tmpl_;
  std::thread sniffer_;
};

}  // namespace

int main(int argc, char** argv) {
  try {
    const Options o = parse(argc, argv);
    Flood flood(o);
    flood.start_sniffer();
    if (!o.record_file.empty()) {
      flood.record();
      return 0;
    }
    flood.prepare();
    flood.send_all();
    flood.stop();
    flood.report();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-flood: %s\n", e.what());
    return 3;
  }
}
