#pragma once
// Station keys (net/README.md "Keys"): each station has a long-term X25519 key pair
// (libsodium crypto_kx) in a file only its owner may read; the lab file lists every station's
// public key. Each directed pair i -> j derives its own traffic key from the pair's crypto_kx
// session keys and a fresh per-run nonce of each station, agreed while probing (hello
// messages, wire kind 3), so a packet of one run never verifies in another and no station can
// forge another's packets. Everything here is start-up (not RT-safe) except where noted.
//
// Key file (TOML, mode 0600 or 0400; refused when group or others may read it):
//   public_key = "<64 hex>"
//   secret_key = "<64 hex>"
// Generate one with write_new_key_file(path) (haptic-keygen PATH prints the public key).
#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "net/wire.hpp"

namespace haptic::net {

inline constexpr std::size_t kPublicKeyBytes = 32;
inline constexpr std::size_t kNonceBytes = kRunNonceBytes;  // RunNonce: net/wire.hpp
using PublicKey = std::array<std::uint8_t, kPublicKeyBytes>;

struct StationKeyPair {
  PublicKey public_key{};
  std::array<std::uint8_t, 32> secret_key{};
};

// A fresh key pair from libsodium's CSPRNG.
StationKeyPair generate_key_pair();
// Creates `path` (O_EXCL, mode 0600: never overwrites) with a fresh key pair; returns the public
// key as 64 hex digits. Throws std::runtime_error naming the path on failure.
std::string write_new_key_file(const std::string& path);
// Reads a key file. Throws std::invalid_argument naming `config_key` (e.g. "net.key_file") when
// the file is readable by group or others (says the chmod to run), unreadable, malformed, when
// the public key does not belong to the secret key, or when the key is a known example key
// and demo mode is off.
StationKeyPair read_key_file(const std::string& path, std::string_view config_key, bool demo_keys);
// 64 hex digits -> key; throws std::invalid_argument naming config_key.
PublicKey public_key_from_hex(std::string_view hex, std::string_view config_key);
std::string to_hex(const std::uint8_t* data, std::size_t n);

// A key that is no secret: all bytes equal, at most 4 distinct byte values (e.g. the old lab
// files' 00..00ff), or an arithmetic sequence of bytes (000102..1f and the like).
bool is_example_key(const std::uint8_t* key, std::size_t n);

// A fresh random per-run nonce (never all zero).
RunNonce new_run_nonce();

// The static key of the directed pair (me -> peer) and (peer -> me) from crypto_kx (the lower
// station id plays the client): {tx, rx}. Throws std::invalid_argument if the peer's public
// key is invalid (a low-order point).
struct PairKeys {
  SessionKey tx, rx;
};
PairKeys pair_keys(const StationKeyPair& mine, std::uint16_t my_id, const PublicKey& theirs, std::uint16_t their_id);
// The traffic key of direction sender -> receiver for one run: keyed BLAKE2b (key = that
// direction's pair key) of "HAPN traffic v3" || sender's nonce || receiver's nonce. RT-safe.
SessionKey traffic_key(const SessionKey& directed_pair_key, const RunNonce& sender_nonce, const RunNonce& receiver_nonce);

}  // namespace haptic::net
