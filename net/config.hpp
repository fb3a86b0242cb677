#pragma once
// The [net] section of a station's TOML configuration -> EndpointConfig + transport.
// Start-up only (not RT-safe). Every bad value throws std::invalid_argument naming the key
// and the allowed range. Keys (defaults in parentheses):
//
//   [net]
//   station_id = 0                 # this station, 0-based (else [station].id); 0..65534
//   transport = "udp"              # "udp" | "raw"
//   bind = "127.0.0.1:7000"        # udp: numeric address:port, IPv6 as "[::1]:7000"
//   interface = "hpn0"             # raw: interface name
//   session_id = 1                 # 0..2^32-1; use a new one per run
//   key_file = "station-1.key"     # this station's key pair (net/keys.hpp: mode 0600, `haptic-keygen FILE`);
//                                  # relative names are relative to the config file's folder. Pairwise keys:
//                                  # every [[net.peers]] lists its public_key; each directed pair gets its own
//                                  # traffic key per run, agreed by hellos while probing (net/README.md "Keys")
//   shared_session_key = "<64 hex>" # instead of key_file: ONE 32-byte MAC key for every station of the session
//                                  # (any key holder can forge any station; for tests and old set-ups). Example
//                                  # keys (all bytes alike, byte sequences such as 0001..1f) are refused unless
//                                  # demo_keys = true. (The old name session_key is refused, naming both.)
//   demo_keys = false              # true: accept example keys (demonstrations only)
//   encoding = "float32"           # "float32" | "float64" (float32: one datagram for 33 nodes; tools/bench/results/net_float32_consensus.json)
//   max_datagram_bytes = 1400      # 96..65507 and <= the transport's MTU
//   io_busy_poll = false
//   io_cpu = -1                    # pin the I/O thread to this CPU (-1: unpinned)
//   tx_spin = false                # tick-synchronous TX (net/endpoint.hpp): the I/O thread spins
//   tx_spin_lead_us = 100          #   from lead before the next push is due (0..1e6)
//   tx_spin_tail_us = 300          #   to tail after it (1..1e6; lead + tail < the tick period)
//   peer_silence_s = 0.25          # a neighbour silent this long is marked down (0.01..60)
//   delay_queue_datagrams = 8192   # 16..1048576
//   rtt_margin_fraction = 0.25     # 0..10
//   rtt_margin_s = 0.004           # 0..10
//   rtt_min_probe_samples = 20     # >= 1
//   listen_any = false             # true: allow bind = "0.0.0.0:p" / "[::]:p" (all interfaces)
//   max_sequence_ahead_ticks = 50  # drop authentic datagrams whose sequence is beyond our tick + this, [1, 2^40]
//   rx_rate_limit_per_s = 0        # per-source datagram rate limit (token bucket, before the MAC); 0 = 20x expected
//   envelope_radii = 3.0           # payload envelope: a node farther than this many object radii from its rest
//                                  # position drops the packet (out_of_envelope); 0 = off. [0, 1e6]
//   [net.impairment]               # optional: emulate the link in our send path
//   preset = "none"                # "none" | "paper" | "bursty"
//   seed = 1                       # run seed: link seeds by net::link_seed (the simulator's rule)
//   trace_file = ""                # optional recorded delays (ms per line), replaces the uniform draw
//   blackout_start_s = 0.0         # with blackout_length_s > 0: total loss in that window
//   blackout_length_s = 0.0
//   [[net.peers]]
//   id = 1                         # neighbor station id
//   address = "127.0.0.1:7001"     # udp
//   mac = "02:48:50:00:00:02"      # raw
//   mean_delay_ms = 4.0            # impairment mean for the directed link self -> id (>= 0)
//   public_key = "<64 hex>"        # the neighbour's public key (required with net.key_file)
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "net/endpoint.hpp"
#include "net/transport_raw.hpp"
#include "net/transport_udp.hpp"

namespace haptic::net {

struct NetConfig {
  EndpointConfig endpoint;
  std::string transport = "udp";
  std::string bind;
  std::string interface;
  std::vector<UdpPeer> udp_peers;
  std::vector<RawPeer> raw_peers;
  std::uint64_t impairment_seed = 1;   // [net.impairment] seed (run seed of net::link_seed)
  bool impairment_seed_given = false;  // the key was in the file
  bool listen_any = false;             // net.listen_any: binding the wildcard address is allowed
  double envelope_radii = 3.0;         // net.envelope_radii (the station turns it into metres)
  // Opens the socket (throws std::system_error, e.g. without CAP_NET_RAW for "raw").
  std::unique_ptr<Transport> make_transport() const;
};

// Parses the whole TOML document text; value_count is the scene's 3n; config_file: the file the
// text came from (a relative net.key_file is read beside it, platform::config::path_beside; "" =
// from the working directory).
NetConfig parse_net_config(std::string_view toml_text, std::uint32_t value_count, const std::string& config_file = "");
NetConfig load_net_config(const std::string& path, std::uint32_t value_count);

}  // namespace haptic::net
