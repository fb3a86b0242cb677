#include "net/keys.hpp"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <set>
#include <stdexcept>

#include "platform/toml_config.hpp"

namespace haptic::net {

namespace {
void init() {
  if (sodium_init() < 0) throw std::runtime_error("net: libsodium failed to initialize");
}
template <std::size_t N>
std::array<std::uint8_t, N> from_hex(std::string_view hex, std::string_view key) {
  std::array<std::uint8_t, N> out{};
  std::size_t bin_len = 0;
  if (hex.size() != 2 * N ||
      sodium_hex2bin(out.data(), N, hex.data(), hex.size(), nullptr, &bin_len, nullptr) != 0 || bin_len != N)
    throw std::invalid_argument(std::string(key) + " must be " + std::to_string(2 * N) + " hexadecimal digits");
  return out;
}
}  // namespace

std::string to_hex(const std::uint8_t* data, std::size_t n) {
  std::string s(2 * n + 1, '\0');
  sodium_bin2hex(s.data(), s.size(), data, n);
  s.pop_back();
  return s;
}

PublicKey public_key_from_hex(std::string_view hex, std::string_view config_key) {
  init();
  return from_hex<kPublicKeyBytes>(hex, config_key);
}

bool is_example_key(const std::uint8_t* k, std::size_t n) {
  std::set<std::uint8_t> distinct(k, k + n);
  if (distinct.size() <= 4) return true;
  const std::uint8_t step = static_cast<std::uint8_t>(k[1] - k[0]);
  for (std::size_t i = 2; i < n; ++i)
    if (static_cast<std::uint8_t>(k[i] - k[i - 1]) != step) return false;
  return true;
}

StationKeyPair generate_key_pair() {
  init();
  StationKeyPair kp;
  crypto_kx_keypair(kp.public_key.data(), kp.secret_key.data());
  return kp;
}

std::string write_new_key_file(const std::string& path) {
  const StationKeyPair kp = generate_key_pair();
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error("cannot create key file " + path + ": " + std::strerror(errno));
  ::fchmod(fd, 0600);  // whatever the umask
  const std::string pub = to_hex(kp.public_key.data(), kp.public_key.size());
  std::string text = "# haptic station key pair (libsodium crypto_kx); keep this file secret (mode 0600)\n";
  text += "public_key = \"" + pub + "\"\n";
  text += "secret_key = \"" + to_hex(kp.secret_key.data(), kp.secret_key.size()) + "\"\n";
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  sodium_memzero(text.data(), text.size());
  ::close(fd);
  if (!ok) throw std::runtime_error("cannot write key file " + path);
  return pub;
}

StationKeyPair read_key_file(const std::string& path, std::string_view config_key, bool demo_keys) {
  init();
  const std::string k(config_key);
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw std::invalid_argument(k + " = \"" + path + "\": cannot read it (" + std::strerror(errno) + ")");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::invalid_argument(k + " = \"" + path + "\" is readable by group or others (mode " + mode +
                                "): a station's secret key must be private; run: chmod 600 " + path);
  }
  const toml::table doc = platform::config::parse_document(platform::config::read_file(path));
  const auto pub = doc["public_key"].value<std::string>();
  const auto sec = doc["secret_key"].value<std::string>();
  if (!pub || !sec) throw std::invalid_argument(k + " = \"" + path + "\" must hold public_key and secret_key (64 hex digits each)");
  StationKeyPair kp;
  kp.public_key = from_hex<32>(*pub, k + " (public_key)");
  kp.secret_key = from_hex<32>(*sec, k + " (secret_key)");
  PublicKey derived{};
  crypto_scalarmult_base(derived.data(), kp.secret_key.data());
  if (sodium_memcmp(derived.data(), kp.public_key.data(), derived.size()) != 0)
    throw std::invalid_argument(k + " = \"" + path + "\": public_key does not belong to secret_key");
  if (!demo_keys && is_example_key(kp.secret_key.data(), kp.secret_key.size()))
    throw std::invalid_argument(k + " = \"" + path + "\" holds an example key (no secret): generate one with haptic-keygen, "
                                "or set net.demo_keys = true for a demonstration");
  return kp;
}

RunNonce new_run_nonce() {
  init();
  RunNonce n{};
  do randombytes_buf(n.data(), n.size());
  while (std::all_of(n.begin(), n.end(), [](std::uint8_t b) { return b == 0; }));
  return n;
}

PairKeys pair_keys(const StationKeyPair& mine, std::uint16_t my_id, const PublicKey& theirs, std::uint16_t their_id) {
  init();
  PairKeys out;
  int rc = 0;
  if (my_id < their_id)
    rc = crypto_kx_client_session_keys(out.rx.bytes.data(), out.tx.bytes.data(), mine.public_key.data(), mine.secret_key.data(),
                                       theirs.data());
  else
    rc = crypto_kx_server_session_keys(out.rx.bytes.data(), out.tx.bytes.data(), mine.public_key.data(), mine.secret_key.data(),
                                       theirs.data());
  if (rc != 0) throw std::invalid_argument("net.peers: the public key of station " + std::to_string(their_id) + " is not a valid key");
  return out;
}

SessionKey traffic_key(const SessionKey& directed, const RunNonce& sender_nonce, const RunNonce& receiver_nonce) {
  static constexpr char kLabel[] = "HAPN traffic v3";
  std::uint8_t msg[sizeof kLabel + 2 * kNonceBytes];
  std::memcpy(msg, kLabel, sizeof kLabel);
  std::memcpy(msg + sizeof kLabel, sender_nonce.data(), kNonceBytes);
  std::memcpy(msg + sizeof kLabel + kNonceBytes, receiver_nonce.data(), kNonceBytes);
  SessionKey k;
  crypto_generichash(k.bytes.data(), k.bytes.size(), msg, sizeof msg, directed.bytes.data(), directed.bytes.size());
  return k;
}

}  // namespace haptic::net
