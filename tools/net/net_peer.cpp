// haptic-net-peer: one station's network layer alone, from a station TOML file ([net]):
// probes round trips, then sends a synthetic 3n-value state every period and checks every
// received state bit for bit, for a bounded time (or until SIGINT/SIGTERM). Prints one JSON
// object with per-link delay, loss, round trip, bound and drop counters. For exercising the
// transports and the impairment across processes/namespaces before the real station runs.
//   haptic-net-peer --config FILE [--nodes 33] [--seconds 5] [--period-ms 2] [--probe-s 1]
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "net/config.hpp"

using namespace haptic::net;

namespace {
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

double value(std::uint16_t station, std::uint64_t k, std::size_t i) {
  return 1000.0 * station + static_cast<double>(k) * 1e-3 + 1e-7 * static_cast<double>(i);
}

struct PeerOptions {
  std::string config;
  int nodes = 33;
  double seconds = 5.0, period_ms = 2.0, probe_s = 1.0;
};

// Reads and checks the command line. Returns -1 to go on, else the exit code (2: usage).
int parse_options(int argc, char** argv, PeerOptions& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--config") o.config = next();
    else if (a == "--nodes") o.nodes = std::atoi(next());
    else if (a == "--seconds") o.seconds = std::atof(next());
    else if (a == "--period-ms") o.period_ms = std::atof(next());
    else if (a == "--probe-s") o.probe_s = std::atof(next());
    else {
      std::fprintf(stderr, "usage: %s --config FILE [--nodes N] [--seconds S] [--period-ms P] [--probe-s S]\n", argv[0]);
      return 2;
    }
  }
  if (o.config.empty() || o.nodes < 1 || o.nodes > 3000 || !(o.seconds > 0 && o.seconds <= 3600) ||
      !(o.period_ms >= 0.1 && o.period_ms <= 1000) || !(o.probe_s >= 0 && o.probe_s < o.seconds)) {
    std::fprintf(stderr, "haptic-net-peer: need --config; --nodes in [1,3000], --seconds in (0,3600], "
                         "--period-ms in [0.1,1000], --probe-s in [0, seconds)\n");
    return 2;
  }
  return -1;
}

// The station file's [net] for n values per state, pushed every --period-ms.
NetConfig load_config(const PeerOptions& o, std::uint32_t n) {
  NetConfig cfg = load_net_config(o.config, n);
  cfg.endpoint.tx_period_s = o.period_ms * 1e-3;  // net.tx_spin needs the push period
  if (cfg.endpoint.tx_spin && cfg.endpoint.tx_period_s <= cfg.endpoint.tx_spin_lead_s + cfg.endpoint.tx_spin_tail_s) {
    std::fprintf(stderr, "haptic-net-peer: --period-ms %g is shorter than net.tx_spin's window (lead + tail): sending through the eventfd\n",
                 o.period_ms);
    cfg.endpoint.tx_spin = false;
  }
  return cfg;
}

struct PeerCounts {
  std::uint64_t received = 0, corrupt = 0, k = 0;  // k: states sent
  bool probing = true;                              // round trips not measured yet
};

// Probes for --probe-s, then pushes a synthetic state every period and checks each one received,
// until --seconds are over or a signal came.
PeerCounts exchange(Endpoint& ep, const PeerOptions& o, std::uint32_t n, std::uint16_t self, bool f32) {
  PeerCounts r;
  std::vector<double> x(n), v(n);
  ep.start();
  ep.begin_probing();
  const double t0 = monotonic_s();
  double next = t0;
  while (!g_stop) {
    const double now = monotonic_s();
    if (now - t0 >= o.seconds) break;
    if (r.probing && now - t0 >= o.probe_s && ep.finish_probing()) r.probing = false;
    ++r.k;
    for (std::uint32_t i = 0; i < n; ++i) x[i] = value(self, r.k, i), v[i] = -x[i];
    ep.push_state(r.k, now, x.data(), v.data());
    ep.drain([&](std::uint16_t s, std::uint64_t seq, double, const double* xh, const double* vh, std::uint32_t c) {
      ++r.received;
      bool ok = c == n;
      // Exact in float64; in float32 the value must be the float32 rounding of what was sent.
      for (std::uint32_t i = 0; ok && i < n; ++i) {
        const double want = value(s, seq, i);
        ok = xh[i] == (f32 ? static_cast<double>(static_cast<float>(want)) : want) && vh[i] == -xh[i];
      }
      if (!ok) ++r.corrupt;
    });
    next += o.period_ms * 1e-3;
    const double sleep = next - monotonic_s();
    if (sleep > 0) std::this_thread::sleep_for(std::chrono::duration<double>(sleep));
  }
  ep.stop();
  return r;
}

// The JSON object on stdout: totals, drop counters and per link delay, loss and round trip.
void print_report(std::uint16_t self, const Endpoint& ep, const PeerCounts& r) {
  const EndpointStats st = ep.stats();
  std::printf("{\"station\": %u, \"transport\": \"%s\", \"sent\": %llu, \"received\": %llu, \"corrupt\": %llu, "
              "\"probing_done\": %s, \"drops\": %llu, \"tx_overruns\": %llu, \"rx_ring_full\": %llu, \"links\": [",
              self, ep.transport().name(), static_cast<unsigned long long>(r.k),
              static_cast<unsigned long long>(r.received), static_cast<unsigned long long>(r.corrupt),
              r.probing ? "false" : "true", static_cast<unsigned long long>(st.drops.total()),
              static_cast<unsigned long long>(st.tx_overruns), static_cast<unsigned long long>(st.rx_ring_full));
  for (std::size_t i = 0; i < st.peers.size(); ++i) {
    const PeerStats& p = st.peers[i];
    std::printf("%s{\"from\": %u, \"received\": %llu, \"loss\": %.4f, \"one_way_mean_ms\": %.3f, "
                "\"one_way_max_ms\": %.3f, \"rtt_samples\": %llu, \"rtt_mean_ms\": %.3f, \"rtt_max_ms\": %.3f, "
                "\"rtt_bound_ms\": %.3f, \"over_bound_events\": %llu, \"impair_lost_to\": %llu}",
                i ? ", " : "", p.station_id, static_cast<unsigned long long>(p.packets_received), p.loss_fraction,
                p.one_way_mean_s * 1e3, p.one_way_max_s * 1e3, static_cast<unsigned long long>(p.rtt_samples),
                p.rtt_mean_s * 1e3, p.rtt_max_s * 1e3, p.rtt_bound_s * 1e3,
                static_cast<unsigned long long>(p.rtt_over_bound_events),
                static_cast<unsigned long long>(p.impair_lost));
  }
  std::printf("]}\n");
}
}  // namespace

int main(int argc, char** argv) {
  PeerOptions o;
  if (const int rc = parse_options(argc, argv, o); rc >= 0) return rc;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    const std::uint32_t n = static_cast<std::uint32_t>(3 * o.nodes);
    const NetConfig cfg = load_config(o, n);
    const std::uint16_t self = cfg.endpoint.wire.station_id;
    Endpoint ep(cfg.endpoint, cfg.make_transport());
    const PeerCounts r = exchange(ep, o, n, self, cfg.endpoint.wire.encoding == ValueEncoding::float32);
    print_report(self, ep, r);
    return (r.corrupt == 0 && r.received > 0 && !r.probing) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-net-peer: %s\n", e.what());
    return 1;
  }
}
