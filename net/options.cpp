#include "net/options.hpp"

#include <cstring>
#include <stdexcept>
#include <string>

#include "net/wire.hpp"

namespace haptic::net {

namespace {

using platform::config::OptionDecl;

OptionDecl real(const char* s, const char* k, double def, double lo, double hi, const char* help) {
  return platform::config::real_option(s, k, def, lo, hi, help);
}
OptionDecl integer(const char* s, const char* k, double def, double lo, double hi, const char* help) {
  return platform::config::integer_option(s, k, def, lo, hi, help);
}
OptionDecl flag(const char* s, const char* k, bool def, const char* help) { return platform::config::boolean_option(s, k, def, help); }
OptionDecl text(const char* s, const char* k, const char* def, const char* help, const char* choices = "") {
  return platform::config::text_option(s, k, def, help, choices);
}

std::vector<OptionDecl> make_net_options() {
  return {
      integer("net", "station_id", 0, 0, 65534, "this station's wire id (absent: station.id; must equal it)"),
      text("net", "transport", "udp", "udp or raw Ethernet (AF_PACKET)", "udp|raw"),
      text("net", "bind", "", "udp: this station's numeric address:port, IPv6 as \"[::1]:7000\" (required for udp)"),
      text("net", "listen", "", "alias of bind (firmware/deploy's lab files)"),
      text("net", "interface", "", "raw: the interface name (required for raw)"),
      integer("net", "session_id", 1, 0, 4294967295.0, "session id; use a new one per run"),
      text("net", "key_file", "", "this station's key pair (mode 0600, `haptic-keygen FILE`), relative to the station file's folder; "
                                  "every peer then lists its public_key: pairwise keys agreed per run (net/README.md \"Keys\")"),
      text("net", "shared_session_key", "", "instead of key_file: one 32-byte MAC key (64 hex) for every station of the session "
                                            "(any key holder can forge any station); example keys are refused unless demo_keys"),
      text("net", "session_key", "", "refused: the old name of shared_session_key (the error names both)"),
      flag("net", "demo_keys", false, "accept example keys (demonstrations only)"),
      text("net", "revoked_keys", "", "public keys (64 hex each, separated by spaces or commas) no station may use: this station's own "
                                      "key or a peer's public_key in it is refused at start-up, naming the key (a stolen key: "
                                      "net/README.md \"Incarnations and restarts\"; haptic-lab rotate-keys)"),
      text("net", "encoding", "float32", "state values on the wire (float32: one datagram for 33 nodes)", "float32|float64"),
      integer("net", "max_datagram_bytes", double(kDefaultDatagramBytes), double(kMinDatagramBytes + 8), double(kMaxDatagramBytes),
              "largest datagram sent (and <= the transport's MTU)"),
      flag("net", "io_busy_poll", false, "the I/O thread polls its socket instead of sleeping in it"),
      integer("net", "io_cpu", -1, -1, 1023, "pin the I/O thread to this CPU (-1: unpinned)"),
      flag("net", "tx_spin", false, "tick-synchronous TX (net/endpoint.hpp): the I/O thread spins around each push"),
      flag("net", "tx_direct", false, "direct TX (net/tx_direct.hpp): the tick sends its push itself, no thread wake-up; not with tx_spin"),
      real("net", "tx_spin_lead_us", 100, 0, 1e6, "with tx_spin: spin from this long before the next push is due (lead + tail < the tick period)"),
      real("net", "tx_spin_tail_us", 300, 1, 1e6, "with tx_spin: spin until this long after it"),
      real("net", "peer_silence_s", 0.25, 0.01, 60, "a neighbour with no authentic datagram for this long is marked down; a newer incarnation of it (a restart) "
                                                   "is accepted only after this long without a sign of life of the current one (net/README.md)"),
      integer("net", "delay_queue_datagrams", 8192, 16, 1 << 20, "capacity of the impairment emulator's delay queue"),
      real("net", "rtt_margin_fraction", 0.25, 0, 10, "round-trip bound = measured x (1 + this) + rtt_margin_s"),
      real("net", "rtt_margin_s", 0.004, 0, 10, "added to the measured round trip's bound"),
      integer("net", "rtt_min_probe_samples", 20, 1, 1000000, "round trips a link needs while probing"),
      flag("net", "listen_any", false, "allow bind = \"0.0.0.0:p\" / \"[::]:p\" (all interfaces)"),
      integer("net", "max_sequence_ahead_ticks", 50, 1, double(1ll << 40), "drop authentic datagrams whose sequence is beyond our tick + this"),
      real("net", "rx_rate_limit_per_s", 0, 0, 1e9, "per-source datagram rate limit (token bucket, before the MAC); 0 = 20x the expected rate"),
      real("net", "envelope_radii", 3, 0, 1e6, "payload envelope: a node farther than this many object radii from its rest position drops "
                                                "the packet (out_of_envelope); 0 = off"),
      text("net.impairment", "preset", "none", "emulate the link in our send path", "none|paper|bursty"),
      integer("net.impairment", "seed", 1, 0, double(1ll << 62), "run seed: link seeds by net::link_seed (the simulator's rule)"),
      text("net.impairment", "trace_file", "", "recorded delays (ms per line) replacing the uniform draw"),
      real("net.impairment", "blackout_start_s", 0, 0, 1e6, "with blackout_length_s > 0: total loss from this time"),
      real("net.impairment", "blackout_length_s", 0, 0, 1e6, "length of the blackout"),
      integer("net.peers[]", "id", 0, 0, 65534, "the neighbour's station id (required; `station` is its alias)"),
      integer("net.peers[]", "station", 0, 0, 65534, "alias of id"),
      text("net.peers[]", "address", "", "udp: its address:port (required for udp; never port 0 nor this station's own bind)"),
      text("net.peers[]", "mac", "", "raw: its MAC address (required for raw)"),
      real("net.peers[]", "mean_delay_ms", 0, 0, 1e5, "impairment mean for the directed link self -> id"),
      text("net.peers[]", "public_key", "", "its public key, 64 hex (required with key_file; never all zero)"),
  };
}

}  // namespace

const std::vector<OptionDecl>& net_options() {
  static const std::vector<OptionDecl> options = make_net_options();
  return options;
}

const OptionDecl& net_option(const char* section, const char* key) {
  for (const OptionDecl& d : net_options())
    if (std::strcmp(d.section, section) == 0 && std::strcmp(d.key, key) == 0) return d;
  throw std::logic_error(std::string("net option not declared: ") + section + "." + key);
}

}  // namespace haptic::net
