#pragma once
// Station files for in-process tests of `haptic-station run` over UDP on 127.0.0.1 (no root:
// rt set-up falls back with warnings, no memory locking, the I/O thread stays SCHED_OTHER).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace haptic::test {

// A private UDP port range per test process (50000-50999 is the station helper's range).
inline int station_port_base() { return 50100 + static_cast<int>(getpid() % 80) * 10; }

// A fresh empty directory under the system's temporary directory.
inline std::string fresh_dir(const std::string& name) {
  const auto d = std::filesystem::temp_directory_path() / ("haptic-station-test-" + std::to_string(getpid()) + "-" + name);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d.string();
}

struct StationText {
  int id = 1;
  std::vector<int> peers;          // neighbour ids (net.peers in this order)
  int port_base = 50100;
  int session = 1;
  std::string out_dir = ".";
  std::string station_extra;       // more [station] lines
  std::string net_extra;           // more [net] lines
  std::string device = "kind = \"simulated\"\nsim_max_force_N = 50.0\nmax_power_W = 0\n";  // the [device] lines
  std::string text() const {
    std::string t = "[station]\nid = " + std::to_string(id) + "\nout_dir = \"" + out_dir + "\"\nio_priority = 0\n" + station_extra;
    t += "[device]\n" + device;
    t += "[rt]\nlock_memory = false\n";
    t += "[net]\ntransport = \"udp\"\nsession_id = " + std::to_string(session) + "\n";
    t += "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n";
    t += "bind = \"127.0.0.1:" + std::to_string(port_base + id) + "\"\n" + net_extra;
    for (int p : peers) t += "[[net.peers]]\nid = " + std::to_string(p) + "\naddress = \"127.0.0.1:" + std::to_string(port_base + p) + "\"\n";
    return t;
  }
};

}  // namespace haptic::test
