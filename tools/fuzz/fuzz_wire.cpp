// libFuzzer target: the wire decoder and reassembly (net/wire.hpp) with arbitrary datagrams.
// The input is split into datagrams by a 2-byte length prefix, so the fuzzer can build
// multi-fragment sequences; half of the datagrams are re-signed with the real key so the
// fuzzer gets past the MAC and exercises the authenticated-field checks and reassembly.
// Properties checked: no crash/UB (ASan+UBSan), and every completed packet is well-formed.
#include <sodium.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "net/wire.hpp"

using namespace haptic::net;

namespace {
WireConfig config(std::uint16_t station) {
  WireConfig c;
  c.session_id = 0x5EED;
  c.station_id = station;
  for (std::size_t i = 0; i < c.key.bytes.size(); ++i) c.key.bytes[i] = static_cast<std::uint8_t>(i);
  return c;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::uint16_t peers[] = {1, 2, 3};
  static const WireConfig cfg = config(0);
  Decoder dec(cfg, peers, 3 * 200, 2);
  std::vector<std::uint8_t> buf;
  std::vector<double> x(3 * 200), v(3 * 200);
  std::size_t pos = 0;
  while (pos + 3 <= size) {
    const std::size_t len = (std::size_t{data[pos]} | (std::size_t{data[pos + 1]} << 8)) % 1600;
    const bool resign = data[pos + 2] & 1;
    pos += 3;
    const std::size_t n = len < size - pos ? len : size - pos;
    buf.assign(data + pos, data + pos + n);
    pos += n;
    if (resign && buf.size() >= kHeaderBytes + kMacBytes) {
      // Make the datagram authentic where the decoder will look for the tag.
      std::uint16_t frag_len;
      std::memcpy(&frag_len, buf.data() + wire_offset::frag_len, 2);
      if (kHeaderBytes + std::size_t{frag_len} + kMacBytes == buf.size())
        crypto_generichash(buf.data() + kHeaderBytes + frag_len, kMacBytes, buf.data(), kHeaderBytes + frag_len,
                           cfg.key.bytes.data(), cfg.key.bytes.size());
    }
    DecodedState st;
    if (dec.decode(buf.data(), buf.size(), st) == DecodeStatus::complete) {
      if (st.value_count == 0 || st.value_count > 3 * 200 || st.payload == nullptr) std::abort();
      st.copy_out(x.data(), v.data());
    }
  }
  return 0;
}
