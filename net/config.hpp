#pragma once
// The [net] section of a station's TOML configuration -> EndpointConfig + transport.
// Start-up only (not RT-safe). Every bad value throws std::invalid_argument naming the key
// and the allowed range. Each key's type, range, default and meaning is declared once in
// net/options.cpp (listed in firmware/station/OPTIONS.md): sections [net] (alias [network], with
// `listen` for `bind`), [net.impairment] (emulate the link in our send path) and [[net.peers]]
// (id or station, address (udp) or mac (raw), mean_delay_ms, public_key with net.key_file).
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "net/endpoint.hpp"
#include "net/keys.hpp"
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
  // net.revoked_keys: public keys no station of the session may use (this station's own key or a
  // neighbour's public_key in it is refused at start-up, naming the key as written).
  std::vector<PublicKey> revoked_keys;
  // Opens the socket (throws std::system_error, e.g. without CAP_NET_RAW for "raw").
  std::unique_ptr<Transport> make_transport() const;
};

// Parses the whole TOML document text; value_count is the scene's 3n; config_file: the file the
// text came from (a relative net.key_file is read beside it, platform::config::path_beside; "" =
// from the working directory).
NetConfig parse_net_config(std::string_view toml_text, std::uint32_t value_count, const std::string& config_file = "");
NetConfig load_net_config(const std::string& path, std::uint32_t value_count);

}  // namespace haptic::net
