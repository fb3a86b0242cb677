#include "net/wire.hpp"

#include "net/envelope.hpp"

#include <sodium.h>

#include <time.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace haptic::net {

namespace {

template <class T>
void put(std::uint8_t* p, std::size_t off, T v) {
  std::memcpy(p + off, &v, sizeof(T));
}
template <class T>
T get(const std::uint8_t* p, std::size_t off) {
  T v;
  std::memcpy(&v, p + off, sizeof(T));
  return v;
}

void init_sodium() {
  if (sodium_init() < 0) throw std::runtime_error("net: libsodium failed to initialize");
}

void mac(const std::uint8_t* data, std::size_t len, const SessionKey& key, std::uint8_t* tag) {
  crypto_generichash(tag, kMacBytes, data, len, key.bytes.data(), key.bytes.size());
}

}  // namespace

const char* to_string(DropReason r) {
  switch (r) {
    case DropReason::truncated: return "truncated";
    case DropReason::oversized: return "oversized";
    case DropReason::garbled: return "garbled";
    case DropReason::wrong_version: return "wrong_version";
    case DropReason::wrong_session: return "wrong_session";
    case DropReason::unknown_sender: return "unknown_sender";
    case DropReason::wrong_destination: return "wrong_destination";
    case DropReason::bad_mac: return "bad_mac";
    case DropReason::replayed: return "replayed";
    case DropReason::stale: return "stale";
    case DropReason::too_large: return "too_large";
    case DropReason::reassembly_evicted: return "reassembly_evicted";
    case DropReason::old_incarnation: return "old_incarnation";
    case DropReason::future_sequence: return "future_sequence";
    case DropReason::wrong_source: return "wrong_source";
    case DropReason::non_finite: return "non_finite";
    case DropReason::out_of_envelope: return "out_of_envelope";
    case DropReason::rate_limited: return "rate_limited";
    case DropReason::zero_length: return "zero_length";
    case DropReason::keys_not_agreed: return "keys_not_agreed";
    case DropReason::incarnation_while_live: return "incarnation_while_live";
    case DropReason::key_compromise: return "key_compromise";
    case DropReason::replayed_fingerprint: return "replayed_fingerprint";
    case DropReason::replayed_hello: return "replayed_hello";
    case DropReason::count_: break;
  }
  return "?";
}

std::uint64_t DropCounters::total() const {
  std::uint64_t t = 0;
  for (auto c : by_reason) t += c;
  return t;
}

SessionKey SessionKey::from_hex(std::string_view hex, std::string_view config_key) {
  SessionKey k;
  auto nib = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  bool ok = hex.size() == 2 * kKeyBytes;
  for (std::size_t i = 0; ok && i < kKeyBytes; ++i) {
    const int hi = nib(hex[2 * i]), lo = nib(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) ok = false;
    else k.bytes[i] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  if (!ok)
    throw std::invalid_argument(std::string(config_key) + " must be 64 hexadecimal digits (a 32-byte key)");
  return k;
}

void WireConfig::validate() const {
  if (max_datagram_bytes < kMinDatagramBytes + 8 || max_datagram_bytes > kMaxDatagramBytes)
    throw std::invalid_argument("net.max_datagram_bytes must be in [" + std::to_string(kMinDatagramBytes + 8) +
                                ", " + std::to_string(kMaxDatagramBytes) + "]");
  if (station_id == kNoStation) throw std::invalid_argument("station id must be in [0, 65534]");
}

std::uint64_t new_incarnation() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000u + static_cast<std::uint64_t>(ts.tv_nsec);
}

std::uint64_t fingerprint_hash(const void* data, std::size_t bytes) {
  init_sodium();
  std::uint8_t h[16];
  crypto_generichash(h, sizeof h, static_cast<const std::uint8_t*>(data), bytes, nullptr, 0);
  return get<std::uint64_t>(h, 0);
}

std::string fingerprint_difference(const Fingerprint& mine, const Fingerprint& theirs) {
  std::string out;
  auto field = [&](const char* name, auto a, auto b, bool show_values) {
    if (a == b) return;
    if (!out.empty()) out += "; ";
    out += name;
    if (show_values) out += ": " + std::to_string(a) + " here, " + std::to_string(b) + " at the peer";
    else out += " differs";
  };
  field("protocol version", mine.protocol_version, theirs.protocol_version, true);
  field("scene nodes", mine.scene_nodes, theirs.scene_nodes, true);
  // scene_hash: geometry in the high 32 bits, material in the low 32 (firmware/station/plan.cpp).
  const bool geometry = (mine.scene_hash >> 32) != (theirs.scene_hash >> 32);
  const bool material = (mine.scene_hash & 0xFFFFFFFFu) != (theirs.scene_hash & 0xFFFFFFFFu);
  if (geometry && !material) field("scene geometry (hash)", mine.scene_hash, theirs.scene_hash, false);
  else if (material && !geometry) field("scene material (hash)", mine.scene_hash, theirs.scene_hash, false);
  else field("scene data (hash)", mine.scene_hash, theirs.scene_hash, false);
  field("period_ns", mine.period_ns, theirs.period_ns, true);
  field("gains or shared station options (hash)", mine.gains_hash, theirs.gains_hash, false);
  auto named = [&](const char* name, const char* a, const char* b) {
    if (std::strcmp(a, b) == 0) return;
    if (!out.empty()) out += "; ";
    out += std::string(name) + ": " + a + " here, " + b + " at the peer";
  };
  auto law = [](std::uint8_t c) { return c == kConsensusLawEq18 ? "eq18" : c == kConsensusLawPspm ? "pspm" : c == 0 ? "not sent" : "unknown"; };
  named("consensus passivity (station.consensus_passivity)", law(mine.consensus_law), law(theirs.consensus_law));
  named("predictive deadband (station.tx_predict)", mine.tx_predict ? "on" : "off", theirs.tx_predict ? "on" : "off");
  field("transmission deadband (station.tx_deadband_mm, station.tx_max_interval_ticks; hash)", mine.tx_deadband_hash, theirs.tx_deadband_hash, false);
  return out;
}

// ---------------------------------------------------------------- encoder

Encoder::Encoder(const WireConfig& cfg) : cfg_(cfg) {
  cfg_.validate();
  init_sodium();
  value_bytes_ = cfg_.encoding == ValueEncoding::float32 ? 4 : 8;
  // Stride: whole values per fragment, so no value straddles two datagrams.
  const std::size_t room = std::min<std::size_t>(cfg_.max_datagram_bytes - kHeaderBytes - kMacBytes, 0xFFFF);
  stride_ = room / value_bytes_ * value_bytes_;
}

std::size_t Encoder::fragment_count(std::uint32_t value_count) const {
  const std::size_t bytes = payload_bytes(value_count);
  const std::size_t n = bytes == 0 ? 1 : (bytes + stride_ - 1) / stride_;
  return n > kMaxFragments ? 0 : n;
}

namespace {
// Values [first, first + count) of a state packet's payload x_hat ++ v_hat ++ proxy, in the wire
// encoding T, to out. In safe state the state is not sent (it may be non-finite): zeros and the
// flag instead; no proxy: zeros and no flag. One tight loop per source array (the codec's
// per-value branches cost more than the copy). RT-safe.
template <class T>
void put_payload(const OutgoingState& s, std::size_t first, std::size_t count, std::uint8_t* out) {
  const std::size_t n = s.value_count;
  const double* src[3] = {s.x_hat, s.v_hat, s.proxy};
  const std::size_t begin[3] = {0, n, 2 * n}, end[3] = {n, 2 * n, 2 * n + kProxyValues};
  for (std::size_t a = 0; a < 3 && count > 0; ++a) {
    if (first >= end[a]) continue;
    const std::size_t m = std::min(count, end[a] - first);
    const double* from = src[a] + (first - begin[a]);
    if (s.safe_state || src[a] == nullptr) {
      std::memset(out, 0, m * sizeof(T));
    } else {
      for (std::size_t i = 0; i < m; ++i) {
        const T v = static_cast<T>(from[i]);
        std::memcpy(out + i * sizeof(T), &v, sizeof(T));
      }
    }
    out += m * sizeof(T);
    first += m;
    count -= m;
  }
}
}  // namespace

std::size_t Encoder::encode_fragment(const OutgoingState& s, std::size_t index, std::uint8_t* out,
                                     std::size_t cap, const SessionKey* key) const {
  const std::size_t nfrag = fragment_count(s.value_count);
  if (nfrag == 0 || index >= nfrag) return 0;
  const std::size_t total = payload_bytes(s.value_count);
  const std::size_t offset = index * stride_;
  const std::size_t len = std::min(stride_, total - offset);
  const std::size_t size = kHeaderBytes + len + kMacBytes;
  if (cap < size) return 0;

  std::uint8_t flags = 0;
  if (cfg_.encoding == ValueEncoding::float32) flags |= kFlagFloat32;
  if (s.has_echo) flags |= kFlagHasEcho;
  if (s.safe_state) flags |= kFlagSafeState;
  if (s.proxy != nullptr && !s.safe_state) flags |= kFlagProxy;
  namespace o = wire_offset;
  put_common(out, PayloadKind::state, flags, s.dest, s.seq, s.send_time_ns);
  put<std::uint64_t>(out, o::echo_seq, s.has_echo ? s.echo_seq : 0);
  put<std::int64_t>(out, o::echo_hold, s.has_echo ? s.echo_hold_ns : 0);
  put<std::uint32_t>(out, o::value_count, s.value_count);
  put<std::uint16_t>(out, o::frag_index, static_cast<std::uint16_t>(index));
  put<std::uint16_t>(out, o::frag_count, static_cast<std::uint16_t>(nfrag));
  put<std::uint32_t>(out, o::frag_offset, static_cast<std::uint32_t>(offset));
  put<std::uint16_t>(out, o::frag_len, static_cast<std::uint16_t>(len));
  put<std::uint16_t>(out, o::frag_stride, static_cast<std::uint16_t>(stride_));

  // Payload slice: values [offset/vb, (offset+len)/vb) of the concatenation x_hat ++ v_hat ++ proxy.
  if (value_bytes_ == 8)
    put_payload<double>(s, offset / value_bytes_, len / value_bytes_, out + kHeaderBytes);
  else
    put_payload<float>(s, offset / value_bytes_, len / value_bytes_, out + kHeaderBytes);
  mac(out, kHeaderBytes + len, key ? *key : cfg_.key, out + kHeaderBytes + len);
  return size;
}

void Encoder::put_common(std::uint8_t* out, PayloadKind kind, std::uint8_t flags, std::uint16_t dest, std::uint64_t seq,
                         std::int64_t send_time_ns) const {
  namespace o = wire_offset;
  put<std::uint32_t>(out, o::magic, kWireMagic);
  put<std::uint8_t>(out, o::version, kWireVersion);
  put<std::uint8_t>(out, o::kind, static_cast<std::uint8_t>(kind));
  put<std::uint8_t>(out, o::flags, flags);
  put<std::uint8_t>(out, o::header_len, static_cast<std::uint8_t>(kHeaderBytes));
  put<std::uint32_t>(out, o::session, cfg_.session_id);
  put<std::uint16_t>(out, o::sender, cfg_.station_id);
  put<std::uint16_t>(out, o::dest, dest);
  put<std::uint64_t>(out, o::seq, seq);
  put<std::int64_t>(out, o::send_time, send_time_ns);
  put<std::uint64_t>(out, o::incarnation, cfg_.incarnation);
}

// The header fields of a message that is one fragment of `len` bytes and no state (fingerprint,
// hello): no echo, value_count 0. RT-safe.
void Encoder::put_single_fragment(std::uint8_t* out, std::size_t len) {
  namespace o = wire_offset;
  put<std::uint64_t>(out, o::echo_seq, 0);
  put<std::int64_t>(out, o::echo_hold, 0);
  put<std::uint32_t>(out, o::value_count, 0);
  put<std::uint16_t>(out, o::frag_index, 0);
  put<std::uint16_t>(out, o::frag_count, 1);
  put<std::uint32_t>(out, o::frag_offset, 0);
  put<std::uint16_t>(out, o::frag_len, static_cast<std::uint16_t>(len));
  put<std::uint16_t>(out, o::frag_stride, static_cast<std::uint16_t>(len));
}

std::size_t Encoder::encode_fingerprint(std::uint16_t dest, std::uint64_t seq, std::int64_t send_time_ns,
                                        const Fingerprint& f, std::uint8_t* out, std::size_t cap,
                                        std::uint64_t round_trip_bound_ns, const SessionKey* key,
                                        std::int32_t loss_allowance_ticks, std::uint64_t step_max_ns) const {
  const std::size_t size = kHeaderBytes + kFingerprintBytes + kMacBytes;
  if (cap < size) return 0;
  put_common(out, PayloadKind::fingerprint, 0, dest, seq, send_time_ns);
  put_single_fragment(out, kFingerprintBytes);
  std::uint8_t* p = out + kHeaderBytes;
  put<std::uint32_t>(p, 0, f.protocol_version);
  put<std::uint32_t>(p, 4, f.scene_nodes);
  put<std::uint64_t>(p, 8, f.scene_hash);
  put<std::uint64_t>(p, 16, f.period_ns);
  put<std::uint64_t>(p, 24, f.gains_hash);
  put<std::uint64_t>(p, 32, round_trip_bound_ns);
  put<std::uint32_t>(p, 40, loss_allowance_ticks < 0 ? 0u : static_cast<std::uint32_t>(loss_allowance_ticks) + 1u);
  put<std::uint8_t>(p, 44, f.consensus_law);
  put<std::uint8_t>(p, 45, f.tx_predict);
  put<std::uint16_t>(p, 46, f.tx_deadband_hash);
  put<std::uint64_t>(p, 48, step_max_ns);
  mac(out, kHeaderBytes + kFingerprintBytes, key ? *key : cfg_.key, out + kHeaderBytes + kFingerprintBytes);
  return size;
}

std::size_t Encoder::encode_hello(std::uint16_t dest, std::uint64_t seq, std::int64_t send_time_ns, const RunNonce& mine,
                                  const RunNonce& echo, bool agreed, const SessionKey& key, std::uint8_t* out,
                                  std::size_t cap) const {
  const std::size_t size = kHeaderBytes + kHelloBytes + kMacBytes;
  if (cap < size) return 0;
  put_common(out, PayloadKind::hello, agreed ? kFlagHelloAgreed : 0, dest, seq, send_time_ns);
  put_single_fragment(out, kHelloBytes);
  std::memcpy(out + kHeaderBytes, mine.data(), kRunNonceBytes);
  std::memcpy(out + kHeaderBytes + kRunNonceBytes, echo.data(), kRunNonceBytes);
  mac(out, kHeaderBytes + kHelloBytes, key, out + kHeaderBytes + kHelloBytes);
  return size;
}

// ---------------------------------------------------------------- decoded state

void DecodedState::copy_out(double* x_hat, double* v_hat) const {
  const std::size_t n = value_count;
  if (encoding == ValueEncoding::float64) {
    std::memcpy(x_hat, payload, 8 * n);
    std::memcpy(v_hat, payload + 8 * n, 8 * n);
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      float f;
      std::memcpy(&f, payload + 4 * i, 4);
      x_hat[i] = f;
      std::memcpy(&f, payload + 4 * (n + i), 4);
      v_hat[i] = f;
    }
  }
}

double DecodedState::value(std::size_t i) const {
  if (encoding == ValueEncoding::float64) return get<double>(payload, 8 * i);
  return static_cast<double>(get<float>(payload, 4 * i));
}

namespace {
// Every payload value finite (float32 or float64 bit patterns: exponent not all ones). RT-safe.
// No early exit: the loop vectorizes (a payload is almost always all finite).
bool payload_finite(const std::uint8_t* p, std::size_t values, std::size_t vb) {
  unsigned bad = 0;
  if (vb == 8) {
    for (std::size_t i = 0; i < values; ++i)
      bad |= (get<std::uint64_t>(p, 8 * i) & 0x7FF0000000000000ull) == 0x7FF0000000000000ull;
  } else {
    for (std::size_t i = 0; i < values; ++i) bad |= (get<std::uint32_t>(p, 4 * i) & 0x7F800000u) == 0x7F800000u;
  }
  return bad == 0;
}

// The first 8 bytes of an (authenticated) datagram's MAC: what tells two authentic datagrams apart.
std::uint64_t mac_digest(const std::uint8_t* d, const HeaderView& h) {
  return get<std::uint64_t>(d, kHeaderBytes + h.frag_len);
}

// A control message (hello, fingerprint): no values, one fragment of exactly `bytes` payload bytes.
bool single_control_fragment(const HeaderView& h, std::size_t bytes) {
  return h.value_count == 0 && h.frag_index == 0 && h.frag_count == 1 && h.frag_offset == 0 && h.frag_len == bytes &&
         h.frag_stride == bytes;
}
}  // namespace

bool peek_header(const std::uint8_t* d, std::size_t len, HeaderView& h) {
  if (len < kHeaderBytes) return false;
  namespace o = wire_offset;
  h.magic = get<std::uint32_t>(d, o::magic);
  h.version = get<std::uint8_t>(d, o::version);
  h.kind = get<std::uint8_t>(d, o::kind);
  h.flags = get<std::uint8_t>(d, o::flags);
  h.header_len = get<std::uint8_t>(d, o::header_len);
  h.session = get<std::uint32_t>(d, o::session);
  h.sender = get<std::uint16_t>(d, o::sender);
  h.dest = get<std::uint16_t>(d, o::dest);
  h.seq = get<std::uint64_t>(d, o::seq);
  h.send_time_ns = get<std::int64_t>(d, o::send_time);
  h.echo_seq = get<std::uint64_t>(d, o::echo_seq);
  h.echo_hold_ns = get<std::int64_t>(d, o::echo_hold);
  h.incarnation = get<std::uint64_t>(d, o::incarnation);
  h.value_count = get<std::uint32_t>(d, o::value_count);
  h.frag_index = get<std::uint16_t>(d, o::frag_index);
  h.frag_count = get<std::uint16_t>(d, o::frag_count);
  h.frag_offset = get<std::uint32_t>(d, o::frag_offset);
  h.frag_len = get<std::uint16_t>(d, o::frag_len);
  h.frag_stride = get<std::uint16_t>(d, o::frag_stride);
  return true;
}

// ---------------------------------------------------------------- decoder

Decoder::Decoder(const WireConfig& cfg, std::span<const std::uint16_t> peers, std::uint32_t max_value_count,
                 std::size_t slots_per_peer)
    : cfg_(cfg), max_value_count_(max_value_count), slots_per_peer_(slots_per_peer) {
  cfg_.validate();
  init_sodium();
  if (slots_per_peer_ < 1 || slots_per_peer_ > 64)
    throw std::invalid_argument("net.reassembly_slots must be in [1, 64]");
  if (max_value_count == 0) throw std::invalid_argument("decoder: scene value count must be > 0");
  max_payload_bytes_ = (2ull * max_value_count + kProxyValues) * 8;  // room for float64 (float32 fits too)
  for (auto id : peers) {
    if (id == kNoStation || id == cfg_.station_id)
      throw std::invalid_argument("net.peers: station id " + std::to_string(id) +
                                  " is invalid or this station's own id");
    for (auto& p : peers_)
      if (p.id == id) throw std::invalid_argument("net.peers: station id " + std::to_string(id) + " listed twice");
    Peer p;
    p.id = id;
    p.first_slot = peers_.size() * slots_per_peer_;
    peers_.push_back(p);
  }
  for (std::size_t i = 0; i < peers_.size(); ++i) peers_[i].first_digest = i * kReplayWindow;
  digests_.resize(peers_.size() * kReplayWindow);
  slots_.resize(peers_.size() * slots_per_peer_);
  storage_.resize(slots_.size() * max_payload_bytes_);
  for (std::size_t i = 0; i < slots_.size(); ++i) slots_[i].buffer = storage_.data() + i * max_payload_bytes_;
}

void Decoder::set_peer_keys(std::uint16_t sender, const SessionKey& hello_key, const SessionKey* traffic_key) {
  const int pi = peer_index(sender);
  if (pi < 0) throw std::invalid_argument("decoder: station " + std::to_string(sender) + " is not a neighbour");
  Peer& p = peers_[static_cast<std::size_t>(pi)];
  p.pairwise = true;
  p.hello_key = hello_key;
  p.has_traffic_key = traffic_key != nullptr;
  p.traffic_key = traffic_key ? *traffic_key : SessionKey{};
}

int Decoder::peer_index(std::uint16_t id) const {
  for (std::size_t i = 0; i < peers_.size(); ++i)
    if (peers_[i].id == id) return static_cast<int>(i);
  return -1;
}

bool Decoder::seen(const ReplayWindow& p, std::uint64_t seq, DropReason& why) {
  if (!p.any || seq > p.newest) return false;
  const std::uint64_t back = p.newest - seq;
  if (back >= kReplayWindow) {
    why = DropReason::stale;
    return true;
  }
  if ((p.window[back / 64] >> (back % 64)) & 1u) {
    why = DropReason::replayed;
    return true;
  }
  return false;
}

void Decoder::mark(ReplayWindow& p, std::uint64_t seq) {
  if (!p.any) {
    p.any = true;
    p.newest = seq;
    p.window = {};
    p.window[0] = 1;
    return;
  }
  if (seq > p.newest) {
    const std::uint64_t shift = seq - p.newest;
    if (shift >= kReplayWindow) {
      p.window = {};
    } else {
      // Shift the bitmap "up" by `shift` bits (bit b means newest - b).
      const std::size_t words = shift / 64, bits = shift % 64;
      constexpr std::size_t W = kReplayWindow / 64;
      for (std::size_t i = W; i-- > 0;) {
        std::uint64_t v = 0;
        if (i >= words) {
          v = p.window[i - words] << bits;
          if (bits != 0 && i >= words + 1) v |= p.window[i - words - 1] >> (64 - bits);
        }
        p.window[i] = v;
      }
    }
    p.newest = seq;
    p.window[0] |= 1;
  } else {
    const std::uint64_t back = p.newest - seq;
    p.window[back / 64] |= (std::uint64_t{1} << (back % 64));
  }
}

bool Decoder::control_replayed(Peer& p, std::uint64_t seq) {
  DropReason why{};
  if (seen(p.control, seq, why)) return true;  // replayed or stale alike: idempotent, nothing lost
  mark(p.control, seq);
  return false;
}

DecodeStatus Decoder::drop(DropReason r) {
  ++drops_.by_reason[static_cast<std::size_t>(r)];
  return DecodeStatus::dropped;
}

bool Decoder::check_incarnation(Peer& p, std::uint64_t incarnation, const DecodeLimits& lim, bool& raised,
                                DropReason& why) {
  raised = false;
  why = DropReason::old_incarnation;
  if (!p.has_incarnation) {
    p.has_incarnation = true;
    p.incarnation = incarnation;
    p.heard = false;  // the first datagram may be a replay of an earlier run (a hello): no sign of life yet
    return true;
  }
  if (incarnation < p.incarnation) return false;  // alone never a compromise: cross-run replays would be a DoS
  if (incarnation == p.incarnation) return true;
  if (lim.incarnation_quiet_ns > 0 && p.heard && lim.now_ns - p.heard_ns <= lim.incarnation_quiet_ns) {
    // The current one spoke within the quiet time: a restart is accepted only after it has gone
    // silent. Refused and remembered: if the current one speaks again while this one does, both live.
    p.challenger = std::max(p.challenger, incarnation);
    p.challenger_ns = lim.now_ns;
    ++p.challenger_datagrams;
    why = DropReason::incarnation_while_live;
    return false;
  }
  // A restarted sender: its sequence numbers start afresh, so forget its replay window and
  // its partial packets (all of the old incarnation).
  p.incarnation = incarnation;
  p.heard = false;  // its hellos come first; its states (or fingerprints) will say it is live
  p.challenger = 0;
  p.states = {};
  p.control = {};
  for (std::size_t i = 0; i < slots_per_peer_; ++i) slots_[p.first_slot + i].used = false;
  ++incarnation_changes_;
  p.raise_pending = true;
  raised = true;
  return true;
}

bool Decoder::note_current(Peer& p, const DecodeLimits& lim, bool fresh) {
  if (fresh && p.challenger != 0 && lim.incarnation_quiet_ns > 0 && lim.now_ns - p.challenger_ns <= lim.incarnation_quiet_ns) {
    // Two live incarnations of one station: only a second holder of its key can make that.
    p.compromised = true;
    p.compromised_ns = lim.now_ns;
    return false;
  }
  p.heard = true;
  p.heard_ns = lim.now_ns;
  return true;
}

IncarnationWatch Decoder::incarnations(std::uint16_t sender) const {
  const int pi = peer_index(sender);
  if (pi < 0) throw std::invalid_argument("decoder: station " + std::to_string(sender) + " is not a neighbour");
  const Peer& p = peers_[static_cast<std::size_t>(pi)];
  return {p.has_incarnation ? p.incarnation : 0, p.challenger, p.challenger_datagrams, p.compromised, p.compromised_ns,
          p.conflicting_datagrams, p.conflict_seq};
}

void Decoder::report(DecodedState& out, const HeaderView& h, Peer& peer, bool raised, PayloadKind kind) {
  out.sender = h.sender;
  out.incarnation = h.incarnation;
  out.new_incarnation = raised || peer.raise_pending;  // a raise seen on an earlier fragment
  peer.raise_pending = false;
  out.kind = kind;
  out.seq = h.seq;
  out.send_time_ns = h.send_time_ns;
}

Decoder::Peer* Decoder::authenticate(const std::uint8_t* d, std::size_t len, HeaderView& h, const DecodeLimits& lim,
                                     DropReason& why) {
  why = DropReason::truncated;
  if (d == nullptr || len < kHeaderBytes + kMacBytes) return nullptr;
  why = DropReason::oversized;
  if (len > cfg_.max_datagram_bytes) return nullptr;
  peek_header(d, len, h);
  why = DropReason::garbled;
  if (h.magic != kWireMagic) return nullptr;
  why = DropReason::wrong_version;
  if (h.version != kWireVersion) return nullptr;
  why = DropReason::garbled;
  if (h.header_len != kHeaderBytes) return nullptr;
  // The MAC position follows from frag_len: check it lies inside the datagram first.
  if (kHeaderBytes + std::size_t{h.frag_len} + kMacBytes != len) {
    why = kHeaderBytes + std::size_t{h.frag_len} + kMacBytes > len ? DropReason::truncated : DropReason::garbled;
    return nullptr;
  }
  why = DropReason::wrong_session;
  if (h.session != cfg_.session_id) return nullptr;
  const int pi = peer_index(h.sender);
  why = DropReason::unknown_sender;
  if (pi < 0) return nullptr;
  why = DropReason::wrong_source;
  if (lim.source_station == kSourceUnknown || (lim.source_station >= 0 && lim.source_station != h.sender)) return nullptr;
  why = DropReason::wrong_destination;
  if (h.dest != cfg_.station_id) return nullptr;
  Peer& peer = peers_[static_cast<std::size_t>(pi)];
  why = DropReason::key_compromise;  // two live incarnations seen: nothing of this sender is used again
  if (peer.compromised) return nullptr;
  // Pairwise keys: a hello verifies with the pair's static key, everything else with this run's
  // traffic key; before the run's keys are agreed nothing but hellos can be of this run.
  const bool is_hello = h.kind == static_cast<std::uint8_t>(PayloadKind::hello);
  why = DropReason::keys_not_agreed;
  if (peer.pairwise && !is_hello && !peer.has_traffic_key) return nullptr;
  const SessionKey& key = !peer.pairwise ? cfg_.key : is_hello ? peer.hello_key : peer.traffic_key;
  std::uint8_t tag[kMacBytes];
  mac(d, kHeaderBytes + h.frag_len, key, tag);
  why = DropReason::bad_mac;
  if (sodium_memcmp(tag, d + kHeaderBytes + h.frag_len, kMacBytes) != 0) return nullptr;
  return &peer;
}

DecodeStatus Decoder::decode_hello(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out,
                                   const DecodeLimits& lim) {
  if (!peer.pairwise || (h.flags & ~kFlagHelloAgreed) != 0 || !single_control_fragment(h, kHelloBytes))
    return drop(DropReason::garbled);
  // Hellos obey the incarnation rule (a hello of an earlier process, e.g. replayed from an
  // earlier run, is dropped once a newer one was seen) and the control replay window (a hello of
  // this incarnation replayed within it). Signed with the pair's static key, an earlier run's replay
  // them: no sign of life (note_current); the nonce they echo decides whether they count.
  bool raised = false;
  DropReason why{};
  if (!check_incarnation(peer, h.incarnation, lim, raised, why)) return drop(why);
  if (control_replayed(peer, h.seq)) return drop(DropReason::replayed_hello);
  out = DecodedState{};
  report(out, h, peer, raised, PayloadKind::hello);
  std::memcpy(out.hello_nonce.data(), d + kHeaderBytes, kRunNonceBytes);
  std::memcpy(out.hello_echo.data(), d + kHeaderBytes + kRunNonceBytes, kRunNonceBytes);
  out.hello_agreed = (h.flags & kFlagHelloAgreed) != 0;
  ++accepted_datagrams_;
  return DecodeStatus::hello;
}

DecodeStatus Decoder::decode_fingerprint(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out,
                                         const DecodeLimits& lim) {
  if (h.flags != 0 || !single_control_fragment(h, kFingerprintBytes)) return drop(DropReason::garbled);
  bool raised = false;
  DropReason why{};
  if (!check_incarnation(peer, h.incarnation, lim, raised, why)) return drop(why);
  // A replay within the incarnation: refused before it can count as a sign of life.
  if (control_replayed(peer, h.seq)) return drop(DropReason::replayed_fingerprint);
  // Under this run's pairwise traffic key: alive (no other run can replay it, nor, the control
  // window refusing it, this one). No proof next to a challenger yet (note_current's `fresh`: states
  // only, as the rule was written). The shared key: neither.
  if (peer.pairwise) note_current(peer, lim, false);
  const std::uint8_t* p = d + kHeaderBytes;
  out = DecodedState{};
  report(out, h, peer, raised, PayloadKind::fingerprint);
  out.fingerprint.protocol_version = get<std::uint32_t>(p, 0);
  out.fingerprint.scene_nodes = get<std::uint32_t>(p, 4);
  out.fingerprint.scene_hash = get<std::uint64_t>(p, 8);
  out.fingerprint.period_ns = get<std::uint64_t>(p, 16);
  out.fingerprint.gains_hash = get<std::uint64_t>(p, 24);
  out.fingerprint.consensus_law = get<std::uint8_t>(p, 44);
  out.fingerprint.tx_predict = get<std::uint8_t>(p, 45);
  out.fingerprint.tx_deadband_hash = get<std::uint16_t>(p, 46);
  out.round_trip_bound_ns = get<std::uint64_t>(p, 32);
  const std::uint32_t allowance = get<std::uint32_t>(p, 40);
  out.loss_allowance_ticks = allowance == 0 || allowance > (1u << 30) ? -1 : static_cast<std::int32_t>(allowance - 1);
  out.step_max_ns = get<std::uint64_t>(p, 48);
  ++accepted_datagrams_;
  return DecodeStatus::fingerprint;
}

bool Decoder::state_layout_ok(const HeaderView& h, DropReason& why) const {
  why = DropReason::garbled;
  if ((h.flags & ~(kFlagFloat32 | kFlagHasEcho | kFlagSafeState | kFlagProxy)) != 0) return false;
  const std::size_t vb = (h.flags & kFlagFloat32) ? 4 : 8;
  if (h.value_count == 0) return false;
  why = DropReason::too_large;
  if (h.value_count > max_value_count_) return false;
  why = DropReason::garbled;
  const std::size_t total = (2ull * h.value_count + kProxyValues) * vb;
  if (h.frag_count == 0 || h.frag_count > kMaxFragments || h.frag_index >= h.frag_count) return false;
  if (h.frag_stride == 0 || h.frag_stride % vb != 0) return false;
  if (std::size_t{h.frag_count} != (total + h.frag_stride - 1) / h.frag_stride) return false;
  const std::size_t expect_off = std::size_t{h.frag_index} * h.frag_stride;
  const std::size_t expect_len = std::min<std::size_t>(h.frag_stride, total - expect_off);
  return h.frag_offset == expect_off && h.frag_len == expect_len;
}

bool Decoder::junk(const std::uint8_t* payload, std::size_t values, const HeaderView& h, const DecodeLimits& lim,
                   DropReason& reason) {
  const std::size_t vb = (h.flags & kFlagFloat32) ? 4 : 8;
  reason = DropReason::non_finite;
  if (!payload_finite(payload, values, vb)) return true;
  reason = DropReason::out_of_envelope;
  // Another scene size is the endpoint's to name (wrong_scene_size), not an envelope violation.
  const bool same_scene = lim.envelope != nullptr && (lim.envelope->rest_x.empty() || lim.envelope->rest_x.size() == h.value_count);
  return same_scene && (h.flags & kFlagSafeState) == 0 &&
         !lim.envelope->contains(payload, h.value_count, vb == 4 ? ValueEncoding::float32 : ValueEncoding::float64);
}

void Decoder::report_state(DecodedState& out, const HeaderView& h, Peer& peer, bool raised, const std::uint8_t* payload) {
  report(out, h, peer, raised, PayloadKind::state);
  out.has_echo = (h.flags & kFlagHasEcho) != 0;
  out.echo_seq = h.echo_seq;
  out.echo_hold_ns = h.echo_hold_ns;
  out.value_count = h.value_count;
  out.encoding = (h.flags & kFlagFloat32) ? ValueEncoding::float32 : ValueEncoding::float64;
  out.safe_state = (h.flags & kFlagSafeState) != 0;
  out.has_proxy = (h.flags & kFlagProxy) != 0;
  out.payload = payload;
}

Decoder::Slot* Decoder::reassembly_slot(const HeaderView& h, Peer& peer, std::uint64_t mac, DropReason& why) {
  // This sequence's slot, else a free one, else evict the oldest partial.
  Slot* slots = slots_.data() + peer.first_slot;
  Slot* slot = nullptr;
  for (std::size_t i = 0; i < slots_per_peer_; ++i)
    if (slots[i].used && slots[i].seq == h.seq) slot = &slots[i];
  if (slot != nullptr) {
    why = DropReason::garbled;
    if (slot->frag_count != h.frag_count || slot->value_count != h.value_count || slot->stride != h.frag_stride ||
        slot->flags != h.flags)
      return nullptr;
    why = DropReason::replayed;
    if ((slot->bitmap[h.frag_index / 64] >> (h.frag_index % 64)) & 1u) {
      if (slot->mac[h.frag_index] != mac) why = DropReason::key_compromise;  // authentic, other content
      return nullptr;
    }
    return slot;
  }
  for (std::size_t i = 0; i < slots_per_peer_ && slot == nullptr; ++i)
    if (!slots[i].used) slot = &slots[i];
  if (slot == nullptr) {
    slot = &slots[0];
    for (std::size_t i = 1; i < slots_per_peer_; ++i)
      if (slots[i].age < slot->age) slot = &slots[i];
    ++drops_.by_reason[static_cast<std::size_t>(DropReason::reassembly_evicted)];
  }
  slot->used = true;
  slot->seq = h.seq;
  slot->age = ++age_clock_;
  slot->frag_count = h.frag_count;
  slot->received = 0;
  slot->stride = h.frag_stride;
  slot->flags = h.flags;
  slot->value_count = h.value_count;
  slot->bitmap = {};
  slot->send_time_ns = h.send_time_ns;
  slot->echo_seq = h.echo_seq;
  slot->echo_hold_ns = h.echo_hold_ns;
  return slot;
}

bool Decoder::conflicts_with_delivered(const Peer& peer, const HeaderView& h, std::uint64_t mac) const {
  const SequenceDigests& e = digests_[peer.first_digest + h.seq % kReplayWindow];
  if (e.seq != h.seq || h.frag_index >= kDigestFragments || ((e.held >> h.frag_index) & 1u) == 0) return false;
  return e.mac[h.frag_index] != mac;
}

void Decoder::keep_digests(Peer& peer, std::uint64_t seq, const std::uint64_t* macs, std::size_t frags) {
  SequenceDigests& e = digests_[peer.first_digest + seq % kReplayWindow];
  e.seq = seq;
  e.held = 0;
  for (std::size_t f = 0; f < std::min(frags, kDigestFragments); ++f) {
    e.mac[f] = macs[f];
    e.held = static_cast<std::uint8_t>(e.held | (1u << f));
  }
}

DecodeStatus Decoder::same_sequence_conflict(Peer& peer, const HeaderView& h, const DecodeLimits& lim) {
  // The genuine sender never signs two datagrams with one sequence and fragment in one incarnation:
  // another holder of its key signed one of them (e.g. to use up the genuine one's sequences).
  peer.compromised = true;
  peer.compromised_ns = lim.now_ns;
  peer.conflicting_datagrams = true;
  peer.conflict_seq = h.seq;
  return drop(DropReason::key_compromise);
}

DecodeStatus Decoder::decode_state(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out,
                                   const DecodeLimits& lim) {
  DropReason why{};
  if (!state_layout_ok(h, why)) return drop(why);
  // Beyond our own tick + slack: a forged or broken sender; before anything is touched (a far
  // future sequence would otherwise move the replay window and make every genuine packet stale).
  if (h.seq > lim.max_sequence) return drop(DropReason::future_sequence);
  bool raised = false;
  if (!check_incarnation(peer, h.incarnation, lim, raised, why)) return drop(why);
  const std::uint64_t mac = mac_digest(d, h);
  if (seen(peer.states, h.seq, why)) {  // never after a raise: the window is empty
    if (why == DropReason::replayed && conflicts_with_delivered(peer, h, mac)) return same_sequence_conflict(peer, h, lim);
    return drop(why);
  }
  // A sequence never seen: the current incarnation speaks (a replay cannot: the window refused it).
  if (!note_current(peer, lim, true)) return drop(DropReason::key_compromise);
  const std::size_t vb = (h.flags & kFlagFloat32) ? 4 : 8;

  // Authentic junk (non-finite, outside the envelope) is dropped before mark(): it never uses up a sequence.
  if (h.frag_count == 1) {
    if (junk(d + kHeaderBytes, h.frag_len / vb, h, lim, why)) return drop(why);
    mark(peer.states, h.seq);
    keep_digests(peer, h.seq, &mac, 1);
    ++accepted_datagrams_;
    ++completed_;
    report_state(out, h, peer, raised, d + kHeaderBytes);
    return DecodeStatus::complete;
  }

  Slot* slot = reassembly_slot(h, peer, mac, why);
  if (slot == nullptr) return why == DropReason::key_compromise ? same_sequence_conflict(peer, h, lim) : drop(why);
  std::memcpy(slot->buffer + h.frag_offset, d + kHeaderBytes, h.frag_len);
  slot->bitmap[h.frag_index / 64] |= std::uint64_t{1} << (h.frag_index % 64);
  slot->mac[h.frag_index] = mac;
  ++slot->received;
  ++accepted_datagrams_;
  if (slot->received < slot->frag_count) return DecodeStatus::fragment_stored;

  slot->used = false;
  if (junk(slot->buffer, 2ull * h.value_count + kProxyValues, h, lim, why)) return drop(why);
  mark(peer.states, h.seq);
  keep_digests(peer, h.seq, slot->mac.data(), slot->frag_count);
  // Report the header fields stored with the slot (from its first fragment) and its buffer.
  ++completed_;
  report_state(out, h, peer, raised, slot->buffer);
  out.send_time_ns = slot->send_time_ns;
  out.echo_seq = slot->echo_seq;
  out.echo_hold_ns = slot->echo_hold_ns;
  return DecodeStatus::complete;
}

DecodeStatus Decoder::decode(const std::uint8_t* d, std::size_t len, DecodedState& out, const DecodeLimits& lim) {
  HeaderView h{};
  DropReason why{};
  Peer* peer = authenticate(d, len, h, lim, why);
  if (peer == nullptr) return drop(why);
  // Authenticated from here on; still validate every field before touching state.
  if (h.kind == static_cast<std::uint8_t>(PayloadKind::hello)) return decode_hello(d, h, *peer, out, lim);
  if (h.kind == static_cast<std::uint8_t>(PayloadKind::fingerprint)) return decode_fingerprint(d, h, *peer, out, lim);
  if (h.kind != static_cast<std::uint8_t>(PayloadKind::state)) return drop(DropReason::garbled);
  return decode_state(d, h, *peer, out, lim);
}

}  // namespace haptic::net
