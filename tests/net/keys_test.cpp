// Station keys (net/keys.hpp, issue 11 item 1): key files only their owner may read, created 0600
// and never overwritten, example keys refused outside demo mode (also in shipped configurations),
// and the pair-key derivation the pairwise protocol will use (both ends agree, nonces separate runs).
#include <CppUTest/TestHarness.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <functional>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "net/config.hpp"
#include "net/keys.hpp"

using namespace haptic::net;
namespace fs = std::filesystem;

namespace {

std::string temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("haptic-keys-" + name + "-" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d.string();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_GROUP(Keys){};

TEST(Keys, AKeyFileOthersCanReadIsRefusedNamingTheChmod) {
  const std::string dir = temp_dir("perm");
  const std::string pub = write_new_key_file(dir + "/s.key");
  struct stat st {};
  ::stat((dir + "/s.key").c_str(), &st);
  CHECK_EQUAL(0600u, st.st_mode & 0777u);  // created private whatever the umask
  const StationKeyPair kp = read_key_file(dir + "/s.key", "net.key_file", false);
  STRCMP_EQUAL(pub.c_str(), to_hex(kp.public_key.data(), kp.public_key.size()).c_str());
  ::chmod((dir + "/s.key").c_str(), 0640);
  const std::string e = error_of([&] { read_key_file(dir + "/s.key", "net.key_file", false); });
  STRCMP_CONTAINS("net.key_file", e.c_str());
  STRCMP_CONTAINS("chmod 600", e.c_str());
  CHECK(!error_of([&] { write_new_key_file(dir + "/s.key"); }).empty());  // never overwrites
  fs::remove_all(dir);
}

TEST(Keys, ExampleKeysAreRefusedOutsideDemoMode) {
  const std::string head = "[station]\nid = 1\n[net]\nbind = \"127.0.0.1:47001\"\n";
  const std::string peer = "[[net.peers]]\nid = 2\naddress = \"127.0.0.1:47002\"\n";
  for (const char* k : {"0000000000000000000000000000000000000000000000000000000000000000",
                        "00000000000000000000000000000000000000000000000000000000000000ff",
                        "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f"}) {
    const std::string doc = head + "session_key = \"" + k + "\"\n" + peer;
    const std::string e = error_of([&] { parse_net_config(doc, 99); });
    STRCMP_CONTAINS("net.session_key", e.c_str());
    STRCMP_CONTAINS("demo_keys", e.c_str());
    CHECK(error_of([&] { parse_net_config(head + "demo_keys = true\nsession_key = \"" + k + "\"\n" + peer, 99); }).empty());
  }
  // A random key is fine.
  CHECK(error_of([&] { parse_net_config(head + "session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n" + peer, 99); })
            .empty());
}

TEST(Keys, BothEndsOfAPairDeriveTheSameDirectedKeysAndEachRunItsOwn) {
  const StationKeyPair a = generate_key_pair(), b = generate_key_pair(), c = generate_key_pair();
  const PairKeys ab = pair_keys(a, 1, b.public_key, 2), ba = pair_keys(b, 2, a.public_key, 1), cb = pair_keys(c, 3, b.public_key, 2);
  CHECK(ab.tx.bytes == ba.rx.bytes);
  CHECK(ab.rx.bytes == ba.tx.bytes);
  CHECK(ab.tx.bytes != ab.rx.bytes);  // each direction its own key
  CHECK(cb.tx.bytes != ab.tx.bytes);  // a third station derives something else
  const RunNonce n1 = new_run_nonce(), n2 = new_run_nonce(), n3 = new_run_nonce();
  CHECK(traffic_key(ab.tx, n1, n2).bytes == traffic_key(ba.rx, n1, n2).bytes);
  CHECK(traffic_key(ab.tx, n1, n2).bytes != traffic_key(ab.tx, n3, n2).bytes);  // a new run, a new key
  CHECK_FALSE(is_example_key(ab.tx.bytes.data(), ab.tx.bytes.size()));
}
