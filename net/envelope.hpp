#pragma once
// The physically possible states of a neighbour's payload (net/README.md "Receive-path
// sanity"): every node within max_offset_m of its rest position and no faster than
// max_speed_m_per_s. Checked by the decoder (DecodeLimits::envelope, before the sequence is marked) on every authentic state packet and by
// the receive-path fuzz target. contains() is RT-safe (no allocation).
#include <vector>

#include "net/wire.hpp"

namespace haptic::net {

struct PayloadEnvelope {
  std::vector<double> rest_x;      // 3n rest positions; empty: positions unchecked
  double max_offset_m = 0.0;       // > 0 with rest_x
  double max_speed_m_per_s = 0.0;  // 0: speeds unchecked
  bool active() const { return !rest_x.empty() || max_speed_m_per_s > 0.0; }
  // x_hat, v_hat: `values` each (3n). true when every node is inside.
  bool contains(const DecodedState& st) const;
  bool contains(const double* x_hat, const double* v_hat, std::size_t values) const;
  // The wire payload (x_hat then v_hat, `values` each, in `encoding`): what the decoder checks.
  bool contains(const std::uint8_t* payload, std::size_t values, ValueEncoding encoding) const;
};

}  // namespace haptic::net
