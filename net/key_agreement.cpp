#include "net/key_agreement.hpp"

namespace haptic::net {

PairAgreement::PairAgreement(const StationKeyPair& own, std::uint16_t own_id, const PublicKey& peer_public,
                             std::uint16_t peer_id, const RunNonce& my_nonce)
    : pair_(pair_keys(own, own_id, peer_public, peer_id)), my_nonce_(my_nonce) {}

bool PairAgreement::on_hello(const RunNonce& nonce, const RunNonce& echo, bool peer_agreed) {
  ++hellos_received_;
  if (nonce != seen_nonce_) {
    seen_nonce_ = nonce;  // a nonce we have not echoed yet: echo it with our next hello
    hello_due_ = true;
  }
  bool adopted = false;
  if (echo == my_nonce_ && !(agreed_ && agreed_nonce_ == nonce)) {
    agreed_nonce_ = nonce;
    tx_traffic_ = traffic_key(pair_.tx, my_nonce_, agreed_nonce_);
    rx_traffic_ = traffic_key(pair_.rx, agreed_nonce_, my_nonce_);
    agreed_ = true;
    ++key_agreements_;
    fingerprint_due_ = true;
    adopted = true;
  }
  // The neighbour lacks our nonce, or has not adopted it yet: it needs a hello from us.
  if (echo != my_nonce_ || !peer_agreed) hello_due_ = true;
  return adopted;
}

void PairAgreement::forget() {
  agreed_ = false;
  seen_nonce_ = RunNonce{};
  agreed_nonce_ = RunNonce{};
}

PairAgreement::Hello PairAgreement::take_hello() {
  hello_due_ = false;
  return Hello{&seen_nonce_, agreed_ && agreed_nonce_ == seen_nonce_};
}

void PairAgreement::fill(PeerStats& s) const {
  s.keys_agreed = agreed_;
  s.key_agreements = key_agreements_;
  s.hellos_sent = hellos_sent_;
  s.hellos_received = hellos_received_;
}

}  // namespace haptic::net
