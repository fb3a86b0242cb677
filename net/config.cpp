#include "net/config.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sched.h>

#include "net/keys.hpp"
#include "net/wire.hpp"
#include "net/options.hpp"
#include "platform/toml_config.hpp"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace haptic::net {

namespace {

using platform::config::bad;
using platform::config::boolean;
using platform::config::real;
using platform::config::text;
using platform::config::View;

template <class T>
T integer(View n, const std::string& key, T def, long long lo, long long hi) {
  return static_cast<T>(platform::config::integer(n, key, static_cast<long long>(def), lo, hi));
}

// Option `key` of [net] section `section` ("net", "net.impairment") read by its one declaration
// (net/options.cpp); P: the section as written ("net." or "network.").
platform::config::OptionValue option(View table, const char* section, const char* key, const std::string& P) {
  const std::string sub = std::string(section).substr(3);  // "" or ".impairment"
  return platform::config::read_option(table[key], net_option(section, key), P.substr(0, P.size() - 1) + sub + "." + key);
}
double real_of(View t, const char* key, const std::string& P) { return option(t, "net", key, P).real; }
template <class T>
T integer_of(View t, const char* key, const std::string& P) {
  return static_cast<T>(option(t, "net", key, P).integer);
}
bool boolean_of(View t, const char* key, const std::string& P) { return option(t, "net", key, P).boolean; }
std::string text_of(View t, const char* key, const std::string& P) { return option(t, "net", key, P).text; }

}  // namespace

namespace {
// net.revoked_keys: public keys (64 hex each) separated by spaces or commas.
std::vector<PublicKey> parse_revoked_keys(View net, const std::string& P) {
  std::vector<PublicKey> keys;
  const std::string list = text_of(net, "revoked_keys", P);
  std::size_t i = 0, n = 0;
  while (i < list.size()) {
    if (list[i] == ' ' || list[i] == ',' || list[i] == '\t' || list[i] == '\n') {
      ++i;
      continue;
    }
    const std::size_t end = list.find_first_of(" ,\t\n", i);
    const std::string one = list.substr(i, end == std::string::npos ? std::string::npos : end - i);
    keys.push_back(public_key_from_hex(one, P + "revoked_keys (key " + std::to_string(++n) + ")"));
    i = end == std::string::npos ? list.size() : end;
  }
  return keys;
}
bool revoked(const std::vector<PublicKey>& list, const PublicKey& k) {
  for (const auto& r : list)
    if (r == k) return true;
  return false;
}

// net.key_file (pairwise keys) or net.shared_session_key (one key for the whole session).
void parse_keys(const toml::node_view<const toml::node>& net, const std::string& P, const std::string& config_file,
                EndpointConfig& e, const std::vector<PublicKey>& revoked_keys) {
  const bool demo = boolean(net["demo_keys"], P + "demo_keys", false);
  if (net["session_key"])
    bad(P + "session_key", "gone: set " + P + "key_file (this station's key pair, `haptic-keygen FILE`; each of " + P +
                               "peers lists its public_key) or, where every station shares one secret, " + P +
                               "shared_session_key (then any key holder can forge any station's packets)");
  e.pairwise_keys = static_cast<bool>(net["key_file"]);
  if (e.pairwise_keys && net["shared_session_key"])
    bad(P + "shared_session_key", "absent when " + P + "key_file is set (pairwise keys replace the shared key)");
  if (e.pairwise_keys) {
    std::string path = text(net["key_file"], P + "key_file", "");
    if (path.empty()) bad(P + "key_file", "a file name");
    e.own_keys = read_key_file(platform::config::path_beside(path, config_file), P + "key_file", demo);
    if (revoked(revoked_keys, e.own_keys.public_key))
      bad(P + "key_file = \"" + path + "\"",
          "a key that is not revoked: its public key " + to_hex(e.own_keys.public_key.data(), e.own_keys.public_key.size()) + " is in " + P +
              "revoked_keys (make this station a new key pair: haptic-keygen, or haptic-lab rotate-keys)");
    return;
  }
  if (!net["shared_session_key"])
    bad(P + "key_file", "set: this station's key pair (`haptic-keygen FILE`, mode 0600), with every " + P +
                            "peers entry's public_key; or " + P + "shared_session_key for one key shared by the session");
  const std::string K = P + "shared_session_key";
  e.wire.key = SessionKey::from_hex(text(net["shared_session_key"], K, ""), K);
  // A key that is no secret (all bytes alike, a byte sequence, the old lab files' 00..00ff) only
  // for an explicit demonstration.
  if (!demo && is_example_key(e.wire.key.bytes.data(), e.wire.key.bytes.size()))
    bad(K, "a secret, not an example key (all bytes alike or a byte sequence): generate one with "
           "`openssl rand -hex 32`, or set " + P + "demo_keys = true for a demonstration");
}
}  // namespace

namespace {
// net.transport and net.session_id.
void parse_transport(const toml::node_view<const toml::node>& net, const std::string& P, NetConfig& c) {
  EndpointConfig& e = c.endpoint;
  c.transport = text_of(net, "transport", P);
  e.wire.session_id = integer_of<std::uint32_t>(net, "session_id", P);
}

// Encoding, datagram size, the I/O thread, round-trip margins and receive limits.
void parse_io_options(const toml::node_view<const toml::node>& net, const std::string& P, NetConfig& c) {
  EndpointConfig& e = c.endpoint;
  e.wire.encoding = text_of(net, "encoding", P) == "float64" ? ValueEncoding::float64 : ValueEncoding::float32;
  e.wire.max_datagram_bytes = integer_of<std::size_t>(net, "max_datagram_bytes", P);
  e.io_busy_poll = boolean_of(net, "io_busy_poll", P);
  e.tx_spin = boolean_of(net, "tx_spin", P);
  e.tx_direct = boolean_of(net, "tx_direct", P);
  e.io_cpu = integer_of<int>(net, "io_cpu", P);
  e.tx_spin_lead_s = real_of(net, "tx_spin_lead_us", P) * 1e-6;
  e.tx_spin_tail_s = real_of(net, "tx_spin_tail_us", P) * 1e-6;
  e.peer_silence_s = real_of(net, "peer_silence_s", P);
  e.delay_queue_datagrams = integer_of<std::size_t>(net, "delay_queue_datagrams", P);
  e.rtt.margin_fraction = real_of(net, "rtt_margin_fraction", P);
  e.rtt.margin_s = real_of(net, "rtt_margin_s", P);
  e.rtt.min_probe_samples = integer_of<std::uint64_t>(net, "rtt_min_probe_samples", P);
  c.listen_any = boolean_of(net, "listen_any", P);
  e.max_sequence_ahead_ticks = integer_of<std::uint64_t>(net, "max_sequence_ahead_ticks", P);
  e.rx_rate_limit_per_s = real_of(net, "rx_rate_limit_per_s", P);
  c.envelope_radii = real_of(net, "envelope_radii", P);
}

// This station's own address, parsed once: the udp bind (len 0 for raw) and the largest datagram
// the transport sends (udp: what the address family sends unfragmented; raw: the interface's MTU,
// known when it opens, at most kMaxDatagramBytes).
struct LocalAddress {
  sockaddr_storage bind{};
  socklen_t bind_len = 0;
  std::size_t most_datagram_bytes = kMaxDatagramBytes;
};

// Where this station listens: bind (udp; never the wildcard without listen_any) or interface (raw).
LocalAddress parse_local_address(const toml::node_view<const toml::node>& net, const std::string& P, NetConfig& c) {
  LocalAddress own;
  if (c.transport == "raw") {
    c.interface = text(net["interface"], P + "interface", "");
    if (c.interface.empty()) bad(P + "interface", "set for transport = \"raw\"");
    return own;
  }
  const std::string bind_key = P + (net["bind"] || !net["listen"] ? "bind" : "listen");
  c.bind = net["bind"] ? text(net["bind"], P + "bind", "") : text(net["listen"], P + "listen", "");
  if (c.bind.empty()) bad(P + "bind", "set for transport = \"udp\" (\"a.b.c.d:port\" or \"[v6]:port\")");
  own.bind = parse_udp_address(c.bind, bind_key, own.bind_len);
  own.most_datagram_bytes = UdpTransport::max_datagram_bytes_for(own.bind.ss_family);
  const sockaddr_storage& a = own.bind;
  const bool any = a.ss_family == AF_INET ? reinterpret_cast<const sockaddr_in*>(&a)->sin_addr.s_addr == htonl(INADDR_ANY)
                                          : IN6_IS_ADDR_UNSPECIFIED(&reinterpret_cast<const sockaddr_in6*>(&a)->sin6_addr);
  if (any && !c.listen_any)
    bad(bind_key, "this station's own address, not the wildcard \"" + c.bind + "\" (listening on every interface needs " + P +
                      "listen_any = true; neighbours are still accepted only from their configured addresses)");
  return own;
}

// net.max_datagram_bytes, said when the file is read (--check-config), not first at start-up: at
// most what the transport sends (udp: no datagram IP would fragment), and large enough that one
// state packet of this scene (x_hat, v_hat, the proxy) fits kMaxFragments datagrams (the smallest
// size that fits is named).
void check_datagram_size(const NetConfig& c, const std::string& P, const LocalAddress& own) {
  const EndpointConfig& e = c.endpoint;
  const bool udp = c.transport == "udp";
  const std::size_t most = own.most_datagram_bytes;
  const std::string key = P + "max_datagram_bytes = " + std::to_string(e.wire.max_datagram_bytes);
  if (udp && e.wire.max_datagram_bytes > most)
    bad(key, "at most " + std::to_string(most) + " for transport = \"udp\" over " + (own.bind.ss_family == AF_INET6 ? "IPv6" : "IPv4") +
                 " (no datagram is sent that IP would fragment)");
  const Encoder enc(e.wire);
  if (enc.fragment_count(e.value_count) != 0) return;
  const std::size_t payload = enc.payload_bytes(e.value_count), vb = enc.value_bytes();
  const std::size_t stride = (payload + kMaxFragments - 1) / kMaxFragments;
  const std::size_t need = (stride + vb - 1) / vb * vb + kHeaderBytes + kMacBytes;
  const std::string what = "this scene's state packet (" + std::to_string(e.value_count / 3) + " nodes, " +
                           (vb == 4 ? "float32" : "float64") + ": " + std::to_string(payload) + " bytes) in at most " +
                           std::to_string(kMaxFragments) + " datagrams";
  const std::string f32 = vb == 8 ? "; " + P + "encoding = \"float32\" halves the packet" : std::string();
  if (need <= most) bad(key, "at least " + std::to_string(need) + " for " + what + (udp ? "" : " (and at most the interface's MTU)") + f32);
  bad(key, "large enough for " + what + ": no datagram of transport = \"" + c.transport + "\" is (at most " + std::to_string(most) +
               " bytes): the scene has too many nodes for the network" + f32);
}

// [net.impairment]: one model for every link this station sends on.
struct ImpairmentSection {
  std::string preset = "none";
  std::uint64_t seed = 1;
  std::shared_ptr<const std::vector<double>> trace;
  double blackout_start_s = 0.0, blackout_length_s = 0.0;
  bool any() const { return preset != "none" || trace || blackout_length_s > 0.0; }
};

ImpairmentSection parse_impairment(const toml::node_view<const toml::node>& net, const std::string& P, NetConfig& c) {
  ImpairmentSection s;
  const auto imp = net["impairment"];
  if (!imp) return s;
  if (!imp.is_table()) bad("[" + P + "impairment]", "a table");
  s.preset = text(imp["preset"], P + "impairment.preset", "none");
  LinkImpairment::preset(s.preset, 0.0, P + "impairment.preset");  // validates the name
  s.seed = static_cast<std::uint64_t>(option(imp, "net.impairment", "seed", P).integer);
  c.impairment_seed = s.seed;
  c.impairment_seed_given = static_cast<bool>(imp["seed"]);
  const std::string tf = text(imp["trace_file"], P + "impairment.trace_file", "");
  if (!tf.empty()) {
    try {
      s.trace = load_delay_trace(tf);
    } catch (const std::invalid_argument& e) {
      bad(P + "impairment.trace_file = \"" + tf + "\"", std::string("a readable delay trace (ms per line): ") + e.what());
    }
  }
  s.blackout_start_s = option(imp, "net.impairment", "blackout_start_s", P).real;
  s.blackout_length_s = option(imp, "net.impairment", "blackout_length_s", P).real;
  return s;
}

// A peer's UDP address (key k): parsed, a port other than 0 and not this station's own bind.
void check_peer_address(const NetConfig& c, const std::string& k, const std::string& P, const LocalAddress& own) {
  const std::string& text_address = c.udp_peers.back().address;
  socklen_t len = 0;
  const sockaddr_storage a = parse_udp_address(text_address, k, len);
  const auto port = [](const sockaddr_storage& s) {
    return ntohs(s.ss_family == AF_INET ? reinterpret_cast<const sockaddr_in*>(&s)->sin_port : reinterpret_cast<const sockaddr_in6*>(&s)->sin6_port);
  };
  if (port(a) == 0) bad(k + " = \"" + text_address + "\"", "a neighbour's address with its port (1..65535), not port 0");
  if (len == own.bind_len && std::memcmp(&a, &own.bind, len) == 0)
    bad(k + " = \"" + text_address + "\"", "another station's address, not this station's own " + P + "bind");
}

// One entry of net.peers (key k, e.g. "net.peers[2]"): id, impairment of our link to it, its
// public key, and its address on the configured transport.
void parse_peer(const toml::node_view<const toml::node>& p, const std::string& k, const std::string& P,
                const ImpairmentSection& imp, const LocalAddress& own, NetConfig& c) {
  EndpointConfig& e = c.endpoint;
  const std::uint16_t self = e.wire.station_id;
  PeerLink l;
  const char* id_key = p["id"] ? "id" : "station";
  if (!p[id_key]) bad(k + ".id", "present");
  l.station_id = integer<std::uint16_t>(p[id_key], k + "." + id_key, 0, 0, 65534);
  if (l.station_id == self) bad(k + ".id", "different from this station's id " + std::to_string(self));
  const double mean_ms = real(p["mean_delay_ms"], k + ".mean_delay_ms", 0.0, 0.0, 1e5);
  if (imp.any()) {
    l.impaired = true;
    l.impairment = LinkImpairment::preset(imp.preset, mean_ms * 1e-3, P + "impairment.preset");
    l.impairment.delay_trace = imp.trace;
    l.impairment.blackout_start_s = imp.blackout_start_s;
    l.impairment.blackout_length_s = imp.blackout_length_s;
    // The simulator's seed rule (net::link_seed; wire ids are user numbers, index + 1).
    l.seed = link_seed(imp.seed, static_cast<int>(l.station_id) - 1, static_cast<int>(self) - 1);
    ImpairedLink check(l.impairment, l.seed);  // validates the model now, naming the key
    (void)check;
  }
  if (e.pairwise_keys) {
    if (!p["public_key"]) bad(k + ".public_key", "set when " + P + "key_file is (the neighbour's public key, 64 hex digits)");
    const std::string written = text(p["public_key"], k + ".public_key", "");
    l.public_key = public_key_from_hex(written, k + ".public_key");
    if (revoked(c.revoked_keys, l.public_key))
      bad(k + ".public_key = \"" + written + "\"", "a key that is not revoked: it is in " + P + "revoked_keys (station " +
                                                      std::to_string(l.station_id) + "'s key was revoked: give it a new key pair and "
                                                      "this file its public key, e.g. haptic-lab rotate-keys)");
    if (l.public_key == e.own_keys.public_key) bad(k + ".public_key", "the neighbour's key, not this station's own");
    try {  // the agreement run does while probing: a key with no shared secret (all zero, a low-order point) fails here
      (void)pair_keys(e.own_keys, self, l.public_key, l.station_id);
    } catch (const std::invalid_argument&) {
      bad(k + ".public_key", "a valid public key (`haptic-keygen` prints it): this one, e.g. all zero, agrees no key");
    }
  } else if (p["public_key"]) {
    bad(k + ".public_key", "absent with " + P + "shared_session_key (public keys go with " + P + "key_file)");
  }
  e.peers.push_back(l);
  if (c.transport == "udp") {
    if (!p["address"]) bad(k + ".address", "set for transport = \"udp\"");
    c.udp_peers.push_back({l.station_id, text(p["address"], k + ".address", "")});
    check_peer_address(c, k + ".address", P, own);
  } else {
    if (!p["mac"]) bad(k + ".mac", "set for transport = \"raw\"");
    c.raw_peers.push_back({l.station_id, parse_mac(text(p["mac"], k + ".mac", ""), k + ".mac")});
  }
}
}  // namespace

NetConfig parse_net_config(std::string_view toml_text, std::uint32_t value_count, const std::string& config_file) {
  const toml::table doc = platform::config::parse_document(toml_text);
  // The section is [net]; [network] (firmware/deploy's lab configs) is accepted as an alias,
  // with `listen` for `bind` and peers' `station` for `id`.
  const bool alias = !std::as_const(doc)["net"] && std::as_const(doc)["network"];
  const std::string P = alias ? "network." : "net.";
  const toml::node_view<const toml::node> net = std::as_const(doc)[alias ? "network" : "net"];
  if (!net.is_table()) bad("[net]", "a table");
  NetConfig c;
  EndpointConfig& e = c.endpoint;
  e.value_count = value_count;
  if (net["station_id"]) e.wire.station_id = integer<std::uint16_t>(net["station_id"], P + "station_id", 0, 0, 65534);
  else e.wire.station_id = integer<std::uint16_t>(std::as_const(doc)["station"]["id"], "station.id", 0, 0, 65534);

  parse_transport(net, P, c);
  c.revoked_keys = parse_revoked_keys(net, P);
  parse_keys(net, P, config_file, e, c.revoked_keys);
  parse_io_options(net, P, c);
  const LocalAddress own = parse_local_address(net, P, c);
  const ImpairmentSection imp = parse_impairment(net, P, c);

  const auto peers = net["peers"];
  if (!peers.is_array() || peers.as_array()->empty()) bad(P + "peers", "an array of one or more tables");
  std::size_t idx = 0;
  for (const auto& node : *peers.as_array()) {
    if (!node.is_table()) bad(P + "peers", "an array of tables");
    parse_peer(toml::node_view<const toml::node>{node}, P + "peers[" + std::to_string(idx++) + "]", P, imp, own, c);
  }
  e.wire.validate();
  check_datagram_size(c, P, own);
  e.rtt.validate();
  return c;
}

NetConfig load_net_config(const std::string& path, std::uint32_t value_count) {
  return parse_net_config(platform::config::read_file(path), value_count, path);
}

std::unique_ptr<Transport> NetConfig::make_transport() const {
  if (transport == "raw") return std::make_unique<RawEthernetTransport>(interface, raw_peers);
  return std::make_unique<UdpTransport>(bind, udp_peers, listen_any);
}

}  // namespace haptic::net
