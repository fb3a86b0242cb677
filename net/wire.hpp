#pragma once
// Wire format v3 of the station-to-station packets (spec: net/README.md).
//
// v3 appends the sender's virtual proxy position (3 values, flag kFlagProxy) to every state
// packet's payload, so a station's live view can draw its neighbours' proxies (display only: the
// core never reads it).
//
// v2 adds the sender's incarnation (new per process start) to every header, a fingerprint
// message (kind 2: scene, period, gains, protocol version, exchanged while probing) and
// carries the echo's holding time instead of an echoed stamp (round trips come from the
// receiver's own send records). One state packet (x_hat_i(k), v_hat_i(k), proxy) is sent as 1..kMaxFragments datagrams. Every
// datagram is self-contained and authenticated: a 64-byte little-endian header, a slice of
// the payload, and a 16-byte keyed BLAKE2b MAC (libsodium crypto_generichash with the session
// key) over header + slice. The decoder validates everything before it changes any state and
// counts every dropped datagram by reason; reassembly uses slots preallocated at construction.
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace haptic::net {

static_assert(std::endian::native == std::endian::little, "wire codec assumes a little-endian host");

inline constexpr std::uint32_t kWireMagic = 0x4E504148u;  // bytes "HAPN" on the wire
inline constexpr std::uint8_t kWireVersion = 3;
inline constexpr std::size_t kHeaderBytes = 72;
inline constexpr std::size_t kMacBytes = 16;
inline constexpr std::size_t kKeyBytes = 32;
inline constexpr std::size_t kMinDatagramBytes = kHeaderBytes + kMacBytes + 8;
inline constexpr std::size_t kMaxDatagramBytes = 65507;  // largest UDP/IPv4 payload
inline constexpr std::size_t kDefaultDatagramBytes = 1400;  // fits UDP/IPv4, UDP/IPv6 and raw Ethernet
inline constexpr std::size_t kMaxFragments = 512;  // 16,703 nodes in float32 are 306 datagrams of 1400 bytes
inline constexpr std::uint16_t kNoStation = 0xFFFF;

enum class PayloadKind : std::uint8_t { state = 1, fingerprint = 2, hello = 3 };
// Hello (kind 3, pairwise keys, net/keys.hpp): the sender's per-run nonce, then the newest nonce
// it received from the destination (zeros: none yet); MAC'd with the pair's static key.
// Flag bit 0 of a hello (kFlagHelloAgreed): the sender has adopted the nonce it echoes, i.e. holds
// this run's traffic keys with the destination.
inline constexpr std::size_t kRunNonceBytes = 16;
inline constexpr std::size_t kHelloBytes = 2 * kRunNonceBytes;
using RunNonce = std::array<std::uint8_t, kRunNonceBytes>;
inline constexpr std::uint8_t kFlagHelloAgreed = 0x01;
enum class ValueEncoding : std::uint8_t { float64 = 0, float32 = 1 };

// Header flag bits.
inline constexpr std::uint8_t kFlagFloat32 = 0x01;
inline constexpr std::uint8_t kFlagHasEcho = 0x02;
// The sender is in its safe state (diverged or faulted): the payload is zeros, not a state to
// couple to. Receivers count it and do not hand it to the tick (the edge then acts passively).
inline constexpr std::uint8_t kFlagSafeState = 0x04;
// The payload's last 3 values are the sender's virtual proxy position (m); without it they are 0
// and mean nothing (a push with no proxy: probing, rejoining).
inline constexpr std::uint8_t kFlagProxy = 0x08;
// Values of a state packet's payload after x_hat and v_hat: the proxy position.
inline constexpr std::size_t kProxyValues = 3;

// Byte offsets of the header fields (little-endian).
namespace wire_offset {
inline constexpr std::size_t magic = 0;          // u32
inline constexpr std::size_t version = 4;        // u8
inline constexpr std::size_t kind = 5;           // u8
inline constexpr std::size_t flags = 6;          // u8
inline constexpr std::size_t header_len = 7;     // u8 (= 64)
inline constexpr std::size_t session = 8;        // u32
inline constexpr std::size_t sender = 12;        // u16
inline constexpr std::size_t dest = 14;          // u16
inline constexpr std::size_t seq = 16;           // u64
inline constexpr std::size_t send_time = 24;     // i64 ns, sender's CLOCK_MONOTONIC
inline constexpr std::size_t echo_seq = 32;      // u64
inline constexpr std::size_t echo_hold = 40;     // i64 ns, how long the sender held echo_seq by send_time
inline constexpr std::size_t value_count = 48;   // u32, values per vector (3n)
inline constexpr std::size_t frag_index = 52;    // u16
inline constexpr std::size_t frag_count = 54;    // u16
inline constexpr std::size_t frag_offset = 56;   // u32, byte offset of this slice in the payload
inline constexpr std::size_t frag_len = 60;      // u16, bytes of payload in this datagram
inline constexpr std::size_t frag_stride = 62;   // u16, payload bytes of every non-last fragment
inline constexpr std::size_t incarnation = 64;   // u64, sender's incarnation (new per process start)
}  // namespace wire_offset

enum class DropReason : std::uint8_t {
  truncated,          // shorter than header + MAC
  oversized,          // longer than the configured maximum
  garbled,            // bad magic, header_len, kind, or inconsistent lengths/fragment fields
  wrong_version,
  wrong_session,
  unknown_sender,
  wrong_destination,
  bad_mac,            // forged or corrupted
  replayed,           // sequence (or fragment) already delivered: replay or duplicate
  stale,              // sequence older than the anti-replay window
  too_large,          // value_count above this station's scene size
  reassembly_evicted, // partial packet evicted (counted per evicted packet, not per datagram)
  old_incarnation,    // authentic, but from an incarnation older than the newest seen from that sender
  future_sequence,    // authentic, but its sequence is beyond our own tick + net.max_sequence_ahead_ticks
  wrong_source,       // came from an address (UDP address:port, source MAC) not configured for its sender
  non_finite,         // authentic, but a payload value is NaN or infinite
  out_of_envelope,    // authentic, but a state outside the physically possible envelope (endpoint)
  rate_limited,       // over the per-source datagram rate (net.rx_rate_limit_per_s), dropped unread
  zero_length,        // an empty datagram
  keys_not_agreed,    // pairwise keys: a state/fingerprint datagram from a neighbour before this run's keys are agreed
  incarnation_while_live,  // authentic, a newer incarnation while the current one spoke within the quiet time (refused, remembered)
  key_compromise,     // from a neighbour with two live incarnations (key compromise suspected): every datagram, for the rest of the run
  replayed_fingerprint,  // authentic fingerprint whose control sequence was already seen (or is older than the window): a replay
  replayed_hello,        // the same for a hello
  count_
};
inline constexpr std::size_t kDropReasonCount = static_cast<std::size_t>(DropReason::count_);
const char* to_string(DropReason r);

struct DropCounters {
  std::array<std::uint64_t, kDropReasonCount> by_reason{};
  std::uint64_t operator[](DropReason r) const { return by_reason[static_cast<std::size_t>(r)]; }
  std::uint64_t total() const;
};

struct SessionKey {
  std::array<std::uint8_t, kKeyBytes> bytes{};
  // 64 hex digits; throws std::invalid_argument naming `config_key` otherwise.
  static SessionKey from_hex(std::string_view hex, std::string_view config_key = "net.session_key");
};

// A fresh incarnation number: CLOCK_REALTIME in ns at the call (grows across restarts as long
// as the wall clock does not step back by more than a restart takes). Not RT-safe (call once).
std::uint64_t new_incarnation();

// What two stations must agree on before they couple (exchanged while probing, kind 2).
struct Fingerprint {
  std::uint32_t protocol_version = kWireVersion;
  std::uint32_t scene_nodes = 0;
  std::uint64_t scene_hash = 0;   // scene data: high 32 bits geometry (rest positions, tetrahedra), low 32 material (M, B, K)
  std::uint64_t period_ns = 0;    // the tick period T
  std::uint64_t gains_hash = 0;   // fingerprint_hash of the coupling gains (P_ij, D_ij, ...)
  // The coupling law, which both ends of a link must run alike (eq. 18's proof, the predictive
  // deadband's extrapolation): kConsensusLaw* (the station's station.consensus_passivity; 0: not
  // sent), the predictive deadband (station.tx_predict: 1 on), and 16 bits of fingerprint_hash of
  // the transmission deadband (band in m, max interval in ticks; 0: off).
  std::uint8_t consensus_law = 0;
  std::uint8_t tx_predict = 0;
  std::uint16_t tx_deadband_hash = 0;
};
inline constexpr std::uint8_t kConsensusLawEq18 = 1;  // B_i from eq. (18) (the paper)
inline constexpr std::uint8_t kConsensusLawPspm = 2;  // passive set-position modulation
// The fingerprint message's payload: the Fingerprint (32 bytes), then what is not part of the
// fingerprint but travels with it so both ends of a link agree on the larger of each (net/README.md):
// a u64, the sender's round-trip bound to the destination as its probing fixed it, in ns (0: not
// yet); a u32, the sender's loss allowance for the link in ticks + 1 (0: not yet; the station's
// station.loss_allowance_ticks, firmware/station/probe.hpp); then the fingerprint's coupling law
// (u8 consensus_law, u8 tx_predict, u16 tx_deadband_hash: the word that was reserved, 0, before);
// then a u64, the sender's step bound T^max in ns as its probing fixed it (0: not yet; eq. 18 at the
// receiver needs it, firmware/station/probe.hpp).
inline constexpr std::size_t kFingerprintBytes = 56;
// 64-bit keyless BLAKE2b of bytes (for Fingerprint's hashes). Not RT-safe (start-up).
std::uint64_t fingerprint_hash(const void* data, std::size_t bytes);
// "" when equal, else which fields differ, e.g. "scene nodes: 33 here, 27 at the peer". Not RT-safe.
std::string fingerprint_difference(const Fingerprint& mine, const Fingerprint& theirs);

struct WireConfig {
  std::uint32_t session_id = 1;
  std::uint16_t station_id = 0;              // this station
  std::uint64_t incarnation = 0;             // this process's incarnation (new_incarnation())
  std::size_t max_datagram_bytes = kDefaultDatagramBytes;
  ValueEncoding encoding = ValueEncoding::float64;
  SessionKey key{};
  // Throws std::invalid_argument naming the key (net.max_datagram_bytes, ...) and the range.
  void validate() const;
};

// One state packet to encode (x_hat and v_hat, value_count values each; the proxy, 3 values).
struct OutgoingState {
  std::uint16_t dest = 0;
  std::uint64_t seq = 0;
  std::int64_t send_time_ns = 0;
  bool has_echo = false;
  std::uint64_t echo_seq = 0;
  std::int64_t echo_hold_ns = 0;  // how long we held echo_seq by send_time_ns (our clock, >= 0)
  std::uint32_t value_count = 0;
  const double* x_hat = nullptr;
  const double* v_hat = nullptr;
  bool safe_state = false;  // sets kFlagSafeState; x_hat/v_hat are not read, zeros are sent
  const double* proxy = nullptr;  // the sender's proxy position (sets kFlagProxy); nullptr: zeros, no flag
};

class Encoder {
 public:
  explicit Encoder(const WireConfig& cfg);  // validates cfg (throws)
  std::size_t value_bytes() const { return value_bytes_; }
  std::size_t payload_bytes(std::uint32_t value_count) const { return (2u * value_count + kProxyValues) * value_bytes_; }
  // Payload bytes per full fragment (the stride).
  std::size_t stride() const { return stride_; }
  // Number of datagrams one state packet of value_count values needs (0 if above kMaxFragments).
  std::size_t fragment_count(std::uint32_t value_count) const;
  // Writes datagram `index` of the packet into out[0..cap). Returns its size, or 0 when
  // cap is too small or index is out of range. RT-safe (no allocation, no syscall).
  // key: the pair's traffic key (pairwise keys); nullptr = the configured shared session key.
  std::size_t encode_fragment(const OutgoingState& s, std::size_t index, std::uint8_t* out,
                              std::size_t cap, const SessionKey* key = nullptr) const;
  // Writes one fingerprint datagram (kind 2) to `dest` into out[0..cap); its size or 0 when
  // cap is too small. RT-safe.
  // round_trip_bound_ns: our probing's round-trip bound to `dest` (0: none yet);
  // loss_allowance_ticks: our loss allowance for the link (< 0: none yet);
  // step_max_ns: our step bound T^max (0: none yet).
  std::size_t encode_fingerprint(std::uint16_t dest, std::uint64_t seq, std::int64_t send_time_ns,
                                 const Fingerprint& f, std::uint8_t* out, std::size_t cap,
                                 std::uint64_t round_trip_bound_ns = 0, const SessionKey* key = nullptr,
                                 std::int32_t loss_allowance_ticks = -1, std::uint64_t step_max_ns = 0) const;
  // One hello datagram (kind 3) to `dest`: our run nonce, the newest nonce we received from
  // dest (echo), whether we hold this run's traffic keys with it (agreed); MAC'd with `key`, the
  // pair's static key of direction us -> dest. Its size or 0 when cap is too small. RT-safe.
  std::size_t encode_hello(std::uint16_t dest, std::uint64_t seq, std::int64_t send_time_ns, const RunNonce& mine,
                           const RunNonce& echo, bool agreed, const SessionKey& key, std::uint8_t* out,
                           std::size_t cap) const;
  const WireConfig& config() const { return cfg_; }

 private:
  // Magic, version, kind, flags, header_len, session, sender, dest, seq, send_time, incarnation.
  void put_common(std::uint8_t* out, PayloadKind kind, std::uint8_t flags, std::uint16_t dest, std::uint64_t seq,
                  std::int64_t send_time_ns) const;
  static void put_single_fragment(std::uint8_t* out, std::size_t len);
  WireConfig cfg_;
  std::size_t value_bytes_;
  std::size_t stride_;
};

// A fully received and validated state packet. `payload` holds x_hat, v_hat, then the proxy in
// the wire encoding; it points into the decoder (valid until the next decode call).
struct DecodedState {
  std::uint16_t sender = 0;
  std::uint64_t incarnation = 0;  // sender's incarnation
  bool new_incarnation = false;   // this datagram raised the sender's incarnation (its replay state was reset)
  PayloadKind kind = PayloadKind::state;
  Fingerprint fingerprint{};      // kind == fingerprint (DecodeStatus::fingerprint)
  std::uint64_t round_trip_bound_ns = 0;  // kind == fingerprint: the sender's probing bound to us (0: none yet)
  std::int32_t loss_allowance_ticks = -1; // kind == fingerprint: the sender's loss allowance for the link (-1: none yet)
  std::uint64_t step_max_ns = 0;          // kind == fingerprint: the sender's step bound T^max (0: none yet)
  RunNonce hello_nonce{}, hello_echo{};   // kind == hello: the sender's run nonce, the newest of ours it received
  bool hello_agreed = false;              // kind == hello: kFlagHelloAgreed
  std::uint64_t seq = 0;
  std::int64_t send_time_ns = 0;
  bool has_echo = false;
  std::uint64_t echo_seq = 0;
  std::int64_t echo_hold_ns = 0;
  std::uint32_t value_count = 0;
  ValueEncoding encoding = ValueEncoding::float64;
  bool safe_state = false;        // kFlagSafeState: the sender is in its safe state (payload zeros)
  bool has_proxy = false;         // kFlagProxy: proxy() is the sender's proxy position
  const std::uint8_t* payload = nullptr;
  // Converts the payload to doubles (value_count each). RT-safe.
  void copy_out(double* x_hat, double* v_hat) const;
  // Payload value i (0 .. 2 value_count + 2: x_hat, v_hat, then the proxy) as a double. RT-safe.
  double value(std::size_t i) const;
  // The proxy position's coordinate a (0..2), meaningful when has_proxy. RT-safe.
  double proxy(std::size_t a) const { return value(2u * value_count + a); }
};

// Limits the caller (the endpoint) applies to one datagram, from what only it knows.
inline constexpr int kSourceUnchecked = -2;  // the transport cannot tell where it came from
inline constexpr int kSourceUnknown = -1;    // from an address no neighbour is configured at
struct PayloadEnvelope;  // net/envelope.hpp
struct DecodeLimits {
  // Highest acceptable sequence number (our own tick + slack); larger: future_sequence.
  std::uint64_t max_sequence = ~std::uint64_t{0};
  // The physically possible states (nullptr: unchecked). A complete state packet outside it (not a
  // safe-state one) is dropped as out_of_envelope BEFORE its sequence enters the replay window, like a
  // non-finite one: authentic junk never uses up the sequence number of the genuine packet.
  const PayloadEnvelope* envelope = nullptr;
  // The station id configured at the datagram's source address, kSourceUnknown, or
  // kSourceUnchecked; a sender field that disagrees with a known source is wrong_source.
  int source_station = kSourceUnchecked;
  // The incarnation rule (net/README.md "Incarnations and restarts"): the receive time (any clock,
  // ns) and the quiet time (net.peer_silence_s). A newer incarnation is accepted only when the current
  // one has been silent for more than the quiet time, else refused (incarnation_while_live) and
  // remembered; the current one speaking again (a state sequence never seen) while that challenger
  // spoke within the quiet time makes two live incarnations: key compromise suspected, and every
  // datagram of that sender is dropped from then on (key_compromise). 0: off (any newer incarnation
  // is accepted at once: tests and the fuzz target).
  std::int64_t now_ns = 0;
  std::int64_t incarnation_quiet_ns = 0;
};

// One sender's incarnations as the decoder judged them (Decoder::incarnations).
struct IncarnationWatch {
  std::uint64_t current = 0;       // accepted (0: none yet)
  std::uint64_t refused = 0;       // the newest newer one refused while the current spoke (0: none)
  std::uint64_t refused_datagrams = 0;
  bool compromised = false;        // key compromise suspected: every datagram of the sender is dropped
  std::int64_t compromised_ns = 0; // DecodeLimits::now_ns when it was found
  // What proved it: two live incarnations (false), or two different authentic state datagrams with
  // the same sequence and fragment in one incarnation (true; that sequence in conflict_seq).
  bool conflicting_datagrams = false;
  std::uint64_t conflict_seq = 0;
};

// fingerprint: an authentic fingerprint message (out.fingerprint); complete: a state packet.
struct HeaderView;  // below

// hello: an authentic hello (pairwise keys; out.hello_*).
enum class DecodeStatus : std::uint8_t { dropped, fragment_stored, complete, fingerprint, hello };

class Decoder {
 public:
  static constexpr std::size_t kReplayWindow = 1024;  // sequences tracked behind the newest
  // peers: the station ids we accept from; max_value_count: the scene's 3n. Allocates the
  // reassembly slots (slots_per_peer each, sized for max_value_count) here, never later.
  Decoder(const WireConfig& cfg, std::span<const std::uint16_t> peers, std::uint32_t max_value_count,
          std::size_t slots_per_peer = 4);
  // Validates one datagram. On `complete`, `out` describes the packet. Bad input is dropped
  // and counted, and leaves every state unchanged. Incarnations: the first authentic datagram
  // of a sender fixes its incarnation; a higher one resets that sender's replay window and
  // partial packets (a restarted process); a lower one is dropped (old_incarnation).
  // RT-safe (no allocation, no syscall).
  // limits: sequence ceiling and source check (DecodeLimits). Non-finite payloads are dropped
  // (non_finite) before their sequence enters the replay window.
  DecodeStatus decode(const std::uint8_t* data, std::size_t len, DecodedState& out, const DecodeLimits& limits = {});
  // Pairwise keys of one neighbour (net/keys.hpp): its hellos verify with hello_key (the pair's
  // static key, direction sender -> us), everything else with traffic_key (this run's key of that
  // direction); traffic_key == nullptr: none agreed (yet, or any more), so its state and fingerprint
  // datagrams are dropped unverified (keys_not_agreed). A neighbour never given keys uses the
  // configured shared session key. Throws std::invalid_argument for an unknown sender. RT-safe
  // (no allocation: copies two keys).
  void set_peer_keys(std::uint16_t sender, const SessionKey& hello_key, const SessionKey* traffic_key);
  // Counts a drop decided outside the decoder (rate limit, empty datagram, envelope). RT-safe.
  void count_drop(DropReason r) { ++drops_.by_reason[static_cast<std::size_t>(r)]; }
  const DropCounters& drops() const { return drops_; }
  std::uint64_t accepted_datagrams() const { return accepted_datagrams_; }
  std::uint64_t completed_packets() const { return completed_; }
  std::uint64_t incarnation_changes() const { return incarnation_changes_; }
  // The incarnation rule's view of one sender (IncarnationWatch); throws std::invalid_argument for an
  // unknown sender. Not for the RT thread (the I/O thread's own state: call it there, or when stopped).
  IncarnationWatch incarnations(std::uint16_t sender) const;

 private:
  struct Slot {
    bool used = false;
    std::uint64_t seq = 0;
    std::uint64_t age = 0;  // insertion stamp, for eviction of the oldest
    std::uint16_t frag_count = 0;
    std::uint16_t received = 0;
    std::uint16_t stride = 0;
    std::uint8_t flags = 0;
    std::uint32_t value_count = 0;
    std::array<std::uint64_t, kMaxFragments / 64> bitmap{};
    std::int64_t send_time_ns = 0;
    std::uint64_t echo_seq = 0;
    std::int64_t echo_hold_ns = 0;
    std::uint8_t* buffer = nullptr;  // into storage_
    std::array<std::uint64_t, kMaxFragments> mac{};  // first 8 bytes of each held fragment's MAC
  };
  // Sequences seen, 1024 wide behind the newest (bit b set = newest - b seen). One per sender for its
  // state packets, one for its control messages (fingerprints, hellos: their own sequence space).
  struct ReplayWindow {
    bool any = false;
    std::uint64_t newest = 0;
    std::array<std::uint64_t, kReplayWindow / 64> window{};
  };
  // The MACs (first 8 bytes) of a delivered state packet's first kDigestFragments datagrams, one
  // entry per sequence modulo the replay window: a datagram the window refuses as a replay is one
  // only if it is the same datagram; an authentic one with other content proves a second holder of
  // the sender's key (same_sequence_conflict). Partial packets keep every fragment's in their Slot.
  // Written whenever a sequence enters the window, so an entry the window points to is always of the
  // current incarnation (a raise empties the window).
  static constexpr std::size_t kDigestFragments = 4;
  struct SequenceDigests {
    std::uint64_t seq = 0;
    std::uint8_t held = 0;  // bit f: mac[f] is fragment f's
    std::array<std::uint64_t, kDigestFragments> mac{};
  };
  struct Peer {
    std::uint16_t id = kNoStation;
    bool has_incarnation = false;
    std::uint64_t incarnation = 0;
    bool raise_pending = false;  // raised; not yet reported with a delivered packet
    bool heard = false;          // the current incarnation gave a sign of life no other run can replay (note_current)
    std::int64_t heard_ns = 0;   // its newest (DecodeLimits::now_ns)
    std::uint64_t challenger = 0;          // a newer incarnation refused while the current one spoke (0: none)
    std::int64_t challenger_ns = 0;        // its newest datagram
    std::uint64_t challenger_datagrams = 0;
    bool compromised = false;
    std::int64_t compromised_ns = 0;
    bool conflicting_datagrams = false;  // IncarnationWatch
    std::uint64_t conflict_seq = 0;
    ReplayWindow states;   // delivered state sequences (of the current incarnation)
    ReplayWindow control;  // accepted fingerprint and hello sequences (of the current incarnation)
    std::size_t first_slot = 0;
    std::size_t first_digest = 0;  // its kReplayWindow entries in digests_
    bool pairwise = false, has_traffic_key = false;
    SessionKey hello_key{}, traffic_key{};
  };
  int peer_index(std::uint16_t id) const;
  static bool seen(const ReplayWindow& p, std::uint64_t seq, DropReason& why);
  static void mark(ReplayWindow& p, std::uint64_t seq);
  // A control message (fingerprint, hello) seen before in this incarnation (a replay, or older than
  // the window): counted as `replayed` of its kind. Else its sequence is marked seen.
  bool control_replayed(Peer& p, std::uint64_t seq);
  DecodeStatus drop(DropReason r);
  // The incarnation rule (DecodeLimits): false and why to drop; raised when it replaced the current one.
  bool check_incarnation(Peer& p, std::uint64_t incarnation, const DecodeLimits& lim, bool& raised, DropReason& why);
  // A sign of life of the current incarnation that no other run can replay: a fingerprint under this
  // run's pairwise traffic key (alive), or a state sequence not seen before (fresh: nor can a replay of
  // this run). Hellos are none (the pair's static key: an earlier run's replay them). false: the current
  // one spoke freshly while a refused newer one is live: two live incarnations, compromised.
  bool note_current(Peer& p, const DecodeLimits& lim, bool fresh);
  // Sender, incarnation (and whether it was raised), kind, seq and send time into `out`.
  static void report(DecodedState& out, const HeaderView& h, Peer& peer, bool raised, PayloadKind kind);
  // Framing, session, sender, source, destination and MAC (the steps of decode, in order): the
  // sending neighbour of an authentic datagram, or nullptr and why it is dropped. Reads `h`.
  Peer* authenticate(const std::uint8_t* d, std::size_t len, HeaderView& h, const DecodeLimits& lim, DropReason& why);
  DecodeStatus decode_hello(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out, const DecodeLimits& lim);
  DecodeStatus decode_fingerprint(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out,
                                  const DecodeLimits& lim);
  DecodeStatus decode_state(const std::uint8_t* d, const HeaderView& h, Peer& peer, DecodedState& out,
                            const DecodeLimits& lim);
  // A state fragment's flags, value count and fragment geometry agree with each other.
  bool state_layout_ok(const HeaderView& h, DropReason& why) const;
  // Non-finite, or outside the envelope: authentic junk, dropped before its sequence is marked.
  static bool junk(const std::uint8_t* payload, std::size_t values, const HeaderView& h, const DecodeLimits& lim,
                   DropReason& reason);
  static void report_state(DecodedState& out, const HeaderView& h, Peer& peer, bool raised, const std::uint8_t* payload);
  // The reassembly slot of this fragment's packet (found, free or evicted), or nullptr and why
  // (key_compromise: the slot holds another authentic datagram of this fragment, MAC digest `mac`).
  Slot* reassembly_slot(const HeaderView& h, Peer& peer, std::uint64_t mac, DropReason& why);
  // A delivered sequence's datagram of this fragment was authentic with another MAC digest.
  bool conflicts_with_delivered(const Peer& peer, const HeaderView& h, std::uint64_t mac) const;
  // Delivered: keep the MAC digests of its first fragments (from `macs`, indexed by fragment).
  void keep_digests(Peer& peer, std::uint64_t seq, const std::uint64_t* macs, std::size_t frags);
  // Two different authentic datagrams with one sequence and fragment: key compromise suspected.
  DecodeStatus same_sequence_conflict(Peer& peer, const HeaderView& h, const DecodeLimits& lim);

  WireConfig cfg_;
  std::uint32_t max_value_count_;
  std::size_t slots_per_peer_;
  std::size_t max_payload_bytes_;
  std::vector<Peer> peers_;
  std::vector<Slot> slots_;
  std::vector<std::uint8_t> storage_;
  std::vector<SequenceDigests> digests_;  // kReplayWindow per peer
  std::uint64_t age_clock_ = 0;
  DropCounters drops_{};
  std::uint64_t accepted_datagrams_ = 0;
  std::uint64_t completed_ = 0;
  std::uint64_t incarnation_changes_ = 0;
};

// Reads the header fields of a datagram without validation (tools, tests). Returns false if
// shorter than a header.
struct HeaderView {
  std::uint32_t magic, session;
  std::uint8_t version, kind, flags, header_len;
  std::uint16_t sender, dest, frag_index, frag_count, frag_len, frag_stride;
  std::uint64_t seq, echo_seq, incarnation;
  std::int64_t send_time_ns, echo_hold_ns;
  std::uint32_t value_count, frag_offset;
};
bool peek_header(const std::uint8_t* data, std::size_t len, HeaderView& out);

}  // namespace haptic::net
