#pragma once
// Key agreement with one neighbour (pairwise keys, net/keys.hpp): hellos (wire kind 3) carry
// each end's fresh per-run nonce and echo the other's; the neighbour's nonce is adopted only from
// a hello that echoes OUR nonce of this run (the neighbour made it after it saw ours, so it is of
// this run: a hello recorded in another run echoes another nonce). The pair's traffic keys of
// this run follow from the static pair keys and both nonces. Until they are agreed, no state or
// fingerprint goes to the neighbour or is accepted from it (the endpoint and decoder enforce it).
// I/O thread only; no allocation after construction.
#include <cstdint>

#include "net/keys.hpp"
#include "net/peer_stats.hpp"
#include "net/wire.hpp"

namespace haptic::net {

class PairAgreement {
 public:
  PairAgreement() = default;
  // The pair's static keys (crypto_kx of our key pair and the neighbour's public key) and this run's nonce.
  PairAgreement(const StationKeyPair& own, std::uint16_t own_id, const PublicKey& peer_public, std::uint16_t peer_id,
                const RunNonce& my_nonce);

  // An authentic hello of the neighbour: its nonce, the newest of ours it had received, and whether
  // it says it holds this run's keys. true when this hello agreed (new) traffic keys: the decoder
  // then takes rx_traffic(), and a fingerprint is due.
  bool on_hello(const RunNonce& nonce, const RunNonce& echo, bool peer_agreed);
  // A restarted neighbour (new incarnation): a new process brings a new nonce, so agree again.
  void forget();

  bool agreed() const { return agreed_; }
  // A hello is to be sent: keys not agreed yet, or the neighbour's hello asked for one.
  bool hello_wanted() const { return !agreed_ || hello_due_; }
  // The fields of the hello to send now (clears the request): the nonce to echo and whether both
  // ends hold the same agreement.
  struct Hello {
    const RunNonce* echo;
    bool agreed;
  };
  Hello take_hello();
  void count_hello_sent() { ++hellos_sent_; }
  // A fingerprint is due at once after an agreement (clears the request).
  bool take_fingerprint_due() {
    const bool due = fingerprint_due_;
    fingerprint_due_ = false;
    return due;
  }

  const RunNonce& my_nonce() const { return my_nonce_; }
  const SessionKey& hello_tx_key() const { return pair_.tx; }  // our hellos
  const SessionKey& hello_rx_key() const { return pair_.rx; }  // the neighbour's hellos
  const SessionKey& tx_traffic() const { return tx_traffic_; }
  const SessionKey& rx_traffic() const { return rx_traffic_; }
  // keys_agreed, key_agreements, hellos_sent, hellos_received of the neighbour's statistics.
  void fill(PeerStats& s) const;

 private:
  PairKeys pair_{};
  RunNonce my_nonce_{}, seen_nonce_{}, agreed_nonce_{};
  SessionKey tx_traffic_{}, rx_traffic_{};
  bool agreed_ = false, hello_due_ = false, fingerprint_due_ = false;
  std::uint64_t key_agreements_ = 0, hellos_sent_ = 0, hellos_received_ = 0;
};

}  // namespace haptic::net
