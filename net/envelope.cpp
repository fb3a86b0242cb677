#include "net/envelope.hpp"

namespace haptic::net {

namespace {
template <class Get>
bool inside(const PayloadEnvelope& e, std::size_t n, Get value) {
  const double r2 = e.max_offset_m * e.max_offset_m, s2 = e.max_speed_m_per_s * e.max_speed_m_per_s;
  const bool positions = !e.rest_x.empty(), speeds = e.max_speed_m_per_s > 0.0;
  for (std::size_t p = 0; p + 2 < n; p += 3) {
    double d2 = 0.0, v2 = 0.0;
    for (std::size_t a = 0; a < 3; ++a) {
      if (positions) {
        const double d = value(p + a) - e.rest_x[p + a];
        d2 += d * d;
      }
      const double v = value(n + p + a);
      v2 += v * v;
    }
    // Written so that a NaN fails too.
    if (positions && !(d2 <= r2)) return false;
    if (speeds && !(v2 <= s2)) return false;
  }
  return true;
}
}  // namespace

bool PayloadEnvelope::contains(const DecodedState& st) const {
  if (!active()) return true;
  if (!rest_x.empty() && rest_x.size() != st.value_count) return false;
  return inside(*this, st.value_count, [&](std::size_t i) { return st.value(i); });
}

bool PayloadEnvelope::contains(const double* x, const double* v, std::size_t values) const {
  if (!active()) return true;
  if (!rest_x.empty() && rest_x.size() != values) return false;
  return inside(*this, values, [&](std::size_t i) { return i < values ? x[i] : v[i - values]; });
}

bool PayloadEnvelope::contains(const std::uint8_t* payload, std::size_t values, ValueEncoding encoding) const {
  DecodedState st;
  st.value_count = static_cast<std::uint32_t>(values);
  st.encoding = encoding;
  st.payload = payload;
  return contains(st);
}

}  // namespace haptic::net
