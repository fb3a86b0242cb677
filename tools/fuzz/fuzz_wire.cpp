// libFuzzer target: a station's whole receive path with arbitrary datagrams:
//   decoder + reassembly (net/wire.hpp) with the endpoint's limits (a fuzzer-chosen source
//   address, the sequence ceiling of our own tick) -> the payload envelope (net/envelope.hpp)
//   -> the tick's echo-based age guard (net::RxPacket::age_bound_s) -> rt::RxLink::offer and
//   begin_tick, for three neighbours.
// The input is split into datagrams by a 3-byte prefix (2 bytes length, 1 byte control: bit 0
// re-sign with the real key so the fuzzer gets past the MAC, bits 1-3 the source address
// (unchecked / unknown / station 1..3 / another station), bits 4-7 how many ticks pass first).
// Properties checked (abort on violation), beyond no crash/UB (ASan+UBSan):
//  - every completed packet is well-formed and its values are finite;
//  - a completed packet's sequence is never above our tick + the ceiling slack, and its sender
//    matches a known source address;
//  - what a receive link holds is finite and inside the envelope, and its index delay is >= 0.
#include <sodium.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "net/endpoint.hpp"
#include "net/envelope.hpp"
#include "net/wire.hpp"
#include "rt/rx_link.hpp"

using namespace haptic::net;

namespace {
constexpr std::uint32_t kValues = 3 * 200;
constexpr std::uint64_t kAhead = 50;   // net.max_sequence_ahead_ticks
constexpr double kT = 0.002;           // tick period
constexpr double kMaxAge = 0.05;       // (R + slack) T of the age guard

WireConfig config(std::uint16_t station) {
  WireConfig c;
  c.session_id = 0x5EED;
  c.station_id = station;
  for (std::size_t i = 0; i < c.key.bytes.size(); ++i) c.key.bytes[i] = static_cast<std::uint8_t>(i);
  return c;
}

PayloadEnvelope envelope() {
  PayloadEnvelope e;
  e.rest_x.assign(kValues, 0.0);
  for (std::size_t i = 0; i < kValues; ++i) e.rest_x[i] = 0.001 * static_cast<double>(i % 7);
  e.max_offset_m = 0.15;
  e.max_speed_m_per_s = 50.0;
  return e;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::uint16_t peers[] = {1, 2, 3};
  static const WireConfig cfg = config(0);
  static const PayloadEnvelope env = envelope();
  Decoder dec(cfg, peers, kValues, 2);
  haptic::rt::RxLink links[3];
  for (auto& l : links) l.init(static_cast<int>(kValues), env.rest_x.data(), nullptr);
  std::vector<std::uint8_t> buf;
  std::vector<double> x(kValues), v(kValues);
  std::int64_t tick = 0;
  std::size_t pos = 0;
  while (pos + 3 <= size) {
    const std::size_t len = (std::size_t{data[pos]} | (std::size_t{data[pos + 1]} << 8)) % 1600;
    const std::uint8_t ctl = data[pos + 2];
    pos += 3;
    const std::size_t n = len < size - pos ? len : size - pos;
    buf.assign(data + pos, data + pos + n);
    pos += n;
    if ((ctl & 1) && buf.size() >= kHeaderBytes + kMacBytes) {
      // Make the datagram authentic where the decoder will look for the tag.
      std::uint16_t frag_len;
      std::memcpy(&frag_len, buf.data() + wire_offset::frag_len, 2);
      if (kHeaderBytes + std::size_t{frag_len} + kMacBytes == buf.size())
        crypto_generichash(buf.data() + kHeaderBytes + frag_len, kMacBytes, buf.data(), kHeaderBytes + frag_len,
                           cfg.key.bytes.data(), cfg.key.bytes.size());
    }
    tick += (ctl >> 4) & 0x0F;  // time passes between datagrams
    DecodeLimits lim;
    const int src = (ctl >> 1) & 0x07;
    lim.source_station = src == 0 ? kSourceUnchecked : src == 1 ? kSourceUnknown : src <= 4 ? src - 1 : 7;
    lim.max_sequence = static_cast<std::uint64_t>(tick) + kAhead;
    if (ctl & 0x80) lim.envelope = &env;  // the endpoint passes its envelope to the decoder
    DecodedState st;
    if (dec.decode(buf.data(), buf.size(), st, lim) != DecodeStatus::complete) continue;
    if (st.value_count == 0 || st.value_count > kValues || st.payload == nullptr) std::abort();
    if (st.seq > lim.max_sequence) std::abort();
    if (lim.source_station == kSourceUnknown || (lim.source_station >= 0 && lim.source_station != st.sender)) std::abort();
    st.copy_out(x.data(), v.data());
    for (std::uint32_t i = 0; i < st.value_count; ++i)
      if (!std::isfinite(x[i]) || !std::isfinite(v[i])) std::abort();
    // The decoder checked the envelope for a state of the envelope's scene size; another size is the
    // endpoint's to refuse (wrong_scene_size), so it is not an envelope finding here.
    if (lim.envelope != nullptr && !st.safe_state && st.value_count == env.rest_x.size() && !env.contains(st)) std::abort();
    if (st.value_count != kValues || st.safe_state || !env.contains(st)) continue;  // the endpoint's checks
    // The tick's age guard: our send of echo_seq was at echo_seq * T on our clock, now is tick * T.
    RxPacket p;
    p.has_echo = st.has_echo && st.echo_seq <= static_cast<std::uint64_t>(tick);
    p.echo_time_s = static_cast<double>(st.echo_seq) * kT;
    if (!p.has_echo || p.age_bound_s(static_cast<double>(tick) * kT) > kMaxAge) continue;
    haptic::rt::RxLink& l = links[st.sender - 1];
    l.offer(static_cast<std::int64_t>(st.seq), 0.0, x.data(), v.data(), static_cast<int>(kValues));
    const auto view = l.begin_tick(tick);
    if (view.index_delay < 0) std::abort();
    if (!env.contains(view.x_hat, view.v_hat, kValues)) std::abort();
  }
  return 0;
}
