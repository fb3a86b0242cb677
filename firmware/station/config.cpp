#include "firmware/station/config.hpp"

#include "net/options.hpp"
#include "platform/toml_config.hpp"
#include "rt/set_position_modulation.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace haptic::firmware {

namespace {

using platform::config::bad;
using platform::config::integer;
using platform::config::only_keys;
using platform::config::text;
using platform::config::View;

// What one option's range cannot say: the [station] table itself and keys that depend on others.
void check_station_section(View root, const StationFile& f) {
  const View st = root["station"];
  const StationSection& s = f.station;
  if (st["tx_max_interval_ticks"] && s.tx_deadband_mm == 0)  // like sim's --tx-max-interval: nothing to hold without a band
    bad("station.tx_max_interval_ticks", "left out unless station.tx_deadband_mm > 0 (without a band every state is sent)");
  if (s.tx_predict && s.consensus_passivity != "pspm")
    bad("station.tx_predict", "false unless station.consensus_passivity = \"pspm\" (eq. 18 does not cover extrapolated neighbour data)");
  if (s.out_dir.empty()) bad("station.out_dir", "a non-empty directory path");
  in_addr bind_addr{};
  if (inet_pton(AF_INET, f.view.bind.c_str(), &bind_addr) != 1)
    bad("station.view_bind", "an IPv4 address of this machine, e.g. \"127.0.0.1\" (the default) or \"0.0.0.0\"");
}

void check_scene_and_device(View root, StationFile& f) {
  const View sc = root["scene"];
  if (sc && f.scene.file.empty()) bad("scene.file", "a mesh file (.msh, .node, .ele, .vtk, .obj, .stl, .off) when [scene] is present");
  if (!f.scene.file.empty() && root["station"]["nodes"]) bad("station.nodes", "absent when scene.file is set (the mesh file gives the nodes)");
  if (f.device.kind == "falcon" && f.device.falcon_firmware_path.empty())
    bad("device.falcon_firmware_path", "the Novint firmware file (loaded at every start; not shipped) when device.kind = \"falcon\"");
  platform::validate(f.rt);
  platform::validate(f.loop);
}

// The [net] / [network] keys net/ declares (net/options.hpp), and what the station needs of them
// before net/ parses the section's values.
void parse_net_keys(const toml::table& cd, View root, StationFile& f) {
  const std::string P = cd.contains("network") ? "network" : "net";
  const View nt = root[P];
  f.net_section = P;
  if (!nt) bad("[net]", "present (transport, addresses, key_file, peers: see net/config.hpp)");
  const auto& decls = net::net_options();
  platform::config::only_keys(nt, P, platform::config::section_keys(decls, "net", {"impairment", "peers"}));
  platform::config::only_keys(nt["impairment"], P + ".impairment", platform::config::section_keys(decls, "net.impairment"));
  f.net_station_id_set = static_cast<bool>(nt["station_id"]);
  f.impairment_seed_set = static_cast<bool>(nt["impairment"]["seed"]);
  f.impairment_preset = text(nt["impairment"]["preset"], P + ".impairment.preset", "none");
  if (nt["peers"] && nt["peers"].is_array()) {
    std::size_t i = 0;
    for (const auto& node : *nt["peers"].as_array()) {
      const std::string k = P + ".peers[" + std::to_string(i++) + "]";
      if (!node.is_table()) bad(k, "a table");
      const View p{node};
      platform::config::only_keys(p, k, platform::config::section_keys(decls, "net.peers[]"));
      const View idv = p["id"] ? p["id"] : p["station"];
      f.peer_id_keys.push_back(p["id"] || !p["station"] ? "id" : "station");
      const int id = static_cast<int>(integer(idv, k + ".id", -1, 0, 65534));
      f.peer_mean_delay_set.emplace_back(id, static_cast<bool>(p["mean_delay_ms"]));
    }
  }
  if (f.net_station_id_set && integer(nt["station_id"], P + ".station_id", 0, 0, 65534) != f.station.id)
    bad(P + ".station_id", "absent or equal to station.id (" + std::to_string(f.station.id) + "): wire ids are the user numbers");
}

}  // namespace

StationFile parse_station_file(std::string_view toml_text, const std::vector<StationOption>& options, bool solo) {
  toml::table doc = platform::config::parse_document(toml_text);
  if (solo) {  // one user: station.id is 1 unless the file names its own (a lab file, whose [net] must agree with it)
    if (!doc.contains("station")) doc.insert("station", toml::table{});
    if (toml::table* st = doc["station"].as_table(); st && !st->contains("id")) st->insert("id", 1);
  }
  const toml::table& cd = doc;
  const View root{cd};
  only_keys(root, "", {"station", "scene", "device", "rt", "loop", "gpio", "telemetry", "trace", "net", "network"});
  if (cd.contains("net") && cd.contains("network")) bad("[network]", "absent when [net] is present (one network section)");
  if (!root["station"] && !solo) bad("[station]", "present (with at least id = 1..users)");

  StationFile f;
  f.text = std::string(toml_text);
  read_station_options(doc, f, options);
  check_station_section(root, f);
  check_scene_and_device(root, f);
  only_keys(root["trace"], "trace", {});
  // [net] / [network]: only key names here; values are net/'s (net/config.hpp).
  if (!solo || root["net"] || root["network"]) parse_net_keys(cd, root, f);  // solo: a lab file's [net] is checked, never used
  return f;
}

std::string StationFile::peer_key(std::size_t index, const std::string& field) const {
  const std::string f = field == "id" && index < peer_id_keys.size() ? peer_id_keys[index] : field;
  return net_section + ".peers[" + std::to_string(index) + "]." + f;
}

std::string StationFile::relative_to_file(const std::string& value) const {
  return platform::config::path_beside(value, path);
}

StationFile load_station_file(const std::string& path, const std::vector<std::pair<std::string, std::string>>& overrides, bool solo) {
  StationFile f = parse_station_file(with_overrides(path.empty() ? std::string() : platform::config::read_file(path), overrides), station_options(), solo);
  f.path = path;
  return f;
}

}  // namespace haptic::firmware
