// Key agreement of one pair (net/key_agreement.hpp), alone: two PairAgreements exchanging hellos
// agree the same traffic keys; a nonce is adopted only from a hello echoing ours; a restart
// forgets the agreement.
#include <CppUTest/TestHarness.h>

#include "net/key_agreement.hpp"

using namespace haptic::net;

namespace {
struct Ends {
  StationKeyPair ka = generate_key_pair(), kb = generate_key_pair();
  PairAgreement a{ka, 1, kb.public_key, 2, new_run_nonce()};
  PairAgreement b{kb, 2, ka.public_key, 1, new_run_nonce()};
};
// x sends a hello to y; y's on_hello result.
bool hello(PairAgreement& x, PairAgreement& y) {
  const PairAgreement::Hello h = x.take_hello();
  x.count_hello_sent();
  return y.on_hello(x.my_nonce(), *h.echo, h.agreed);
}
}  // namespace

TEST_GROUP(PairAgreement){};

TEST(PairAgreement, TwoHellosEachWayAgreeTheSameTrafficKeys) {
  Ends e;
  CHECK(e.a.hello_wanted());
  CHECK_FALSE(hello(e.a, e.b));  // b learns a's nonce, cannot adopt (a did not echo b's)
  CHECK(hello(e.b, e.a));        // echoes a's nonce: a adopts b's
  CHECK(e.a.agreed());
  CHECK(hello(e.a, e.b));        // echoes b's nonce: b adopts a's
  CHECK(e.b.agreed());
  MEMCMP_EQUAL(e.a.tx_traffic().bytes.data(), e.b.rx_traffic().bytes.data(), kKeyBytes);
  MEMCMP_EQUAL(e.b.tx_traffic().bytes.data(), e.a.rx_traffic().bytes.data(), kKeyBytes);
  CHECK(e.a.tx_traffic().bytes != e.a.rx_traffic().bytes);
  CHECK(e.a.take_fingerprint_due());  // a fingerprint goes out at once after an agreement
  CHECK_FALSE(e.a.take_fingerprint_due());
  hello(e.b, e.a);  // b tells a it agreed: a needs no more hellos
  CHECK_FALSE(e.a.hello_wanted());
}

TEST(PairAgreement, ANonceIsAdoptedOnlyFromAHelloEchoingOurs) {
  Ends e;
  const RunNonce other_run = new_run_nonce();
  // A hello recorded in another run echoes another nonce of ours: never adopted.
  CHECK_FALSE(e.a.on_hello(new_run_nonce(), other_run, true));
  CHECK_FALSE(e.a.agreed());
  CHECK(e.a.hello_wanted());
}

TEST(PairAgreement, ForgetDropsTheAgreement) {
  Ends e;
  hello(e.a, e.b);
  hello(e.b, e.a);
  CHECK(e.a.agreed());
  e.a.forget();
  CHECK_FALSE(e.a.agreed());
  CHECK(e.a.hello_wanted());
  PeerStats s;
  e.a.fill(s);
  CHECK_FALSE(s.keys_agreed);
  CHECK_EQUAL(1u, s.key_agreements);
  CHECK_EQUAL(1u, s.hellos_sent);
  CHECK_EQUAL(1u, s.hellos_received);
}
