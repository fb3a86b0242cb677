#pragma once
// Helpers for the exchange tests: two endpoints pumping state packets at each other until
// each has received `count` packets or a generous deadline passes (bounded loop).
#include <chrono>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "firmware/model/passivity_budget.hpp"
#include "net/endpoint.hpp"

namespace haptic::net::test {

inline WireConfig exchange_wire(std::uint16_t station) {
  WireConfig w;
  w.session_id = 0xABCD;
  w.station_id = station;
  for (std::size_t i = 0; i < w.key.bytes.size(); ++i) w.key.bytes[i] = static_cast<std::uint8_t>(3 * i + 11);
  return w;
}

inline EndpointConfig exchange_config(std::uint16_t self, std::uint16_t peer, std::uint32_t value_count) {
  EndpointConfig c;
  c.wire = exchange_wire(self);
  c.value_count = value_count;
  PeerLink l;
  l.station_id = peer;
  c.peers.push_back(l);
  c.rtt.min_probe_samples = 5;
  c.rtt.bound_policy = &haptic::model::round_trip_bound_s;  // the station's margin rule (net/ alone: the maximum)
  return c;
}

// The state station s sends at sequence k (so the receiver can check exact content).
inline void fill_state(std::uint16_t s, std::uint64_t k, std::vector<double>& x, std::vector<double>& v) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] = 1000.0 * s + static_cast<double>(k) + 1e-3 * static_cast<double>(i);
    v[i] = -x[i];
  }
}

struct ExchangeResult {
  std::uint64_t received[2] = {0, 0};
  std::uint64_t corrupt[2] = {0, 0};   // payload differs from fill_state(sender, seq)
  std::uint64_t out_of_order[2] = {0, 0};
};

// Both endpoints push packets (one per period_us) and drain; stops when both received
// `count` or after deadline_s. Probing runs over the first half.
inline ExchangeResult exchange(Endpoint& a, Endpoint& b, std::uint16_t id_a, std::uint16_t id_b, std::uint64_t count,
                               double deadline_s = 10.0, int period_us = 500) {
  ExchangeResult r;
  const std::size_t n = a.value_count();
  std::vector<double> x(n), v(n), ex(n), ev(n);
  std::uint64_t last_seq[2] = {0, 0};
  Endpoint* eps[2] = {&a, &b};
  const std::uint16_t ids[2] = {id_a, id_b};
  a.begin_probing();
  b.begin_probing();
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t k = 0;
  bool probed[2] = {false, false};
  while ((r.received[0] < count || r.received[1] < count) &&
         std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < deadline_s) {
    {  // keep sending until both sides have `count` (bounded by the deadline): a push the I/O
       // thread could not take on a loaded machine, or a datagram the kernel dropped, is
       // replaced by a later packet instead of stalling the exchange
      ++k;
      for (int e = 0; e < 2; ++e) {
        fill_state(ids[e], k, x, v);
        eps[e]->push_state(k, monotonic_s(), x.data(), v.data());
      }
    }
    // Probing ends from half-way on, as soon as each side has its samples (a loaded machine
    // may need a few more packets than half the run).
    if (k >= count / 2 && !probed[0]) probed[0] = a.finish_probing();
    if (k >= count / 2 && !probed[1]) probed[1] = b.finish_probing();
    for (int e = 0; e < 2; ++e) {
      eps[e]->drain([&](std::uint16_t sender, std::uint64_t seq, double, const double* xh, const double* vh,
                        std::uint32_t cnt) {
        ++r.received[e];
        if (seq <= last_seq[e]) ++r.out_of_order[e];
        last_seq[e] = seq;
        fill_state(sender, seq, ex, ev);
        bool same = cnt == n && sender == ids[1 - e];
        for (std::size_t i = 0; same && i < n; ++i) same = xh[i] == ex[i] && vh[i] == ev[i];
        if (!same) ++r.corrupt[e];
      });
    }
    std::this_thread::sleep_for(std::chrono::microseconds(period_us));
  }
  return r;
}

}  // namespace haptic::net::test
