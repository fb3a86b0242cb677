// [net] configuration: a full UDP config parses into the endpoint config with the simulator's
// seed scheme; every bad value is rejected naming its key.
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <string>

#include "net/config.hpp"
#include "net/wire.hpp"

using namespace haptic::net;

namespace {
const std::string kKey = "5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d";

std::string udp_doc(const std::string& extra_net = "", const std::string& peer_extra = "") {
  return "[station]\nid = 2\n[net]\ntransport = \"udp\"\nbind = \"127.0.0.1:7002\"\nsession_id = 9\n"
         "shared_session_key = \"" + kKey + "\"\n" + extra_net +
         "[net.impairment]\npreset = \"paper\"\nseed = 5\n"
         "[[net.peers]]\nid = 0\naddress = \"127.0.0.1:7000\"\nmean_delay_ms = 4\n" + peer_extra +
         "[[net.peers]]\nid = 3\naddress = \"127.0.0.1:7003\"\nmean_delay_ms = 200\n";
}

std::string error_of(const std::string& doc, std::uint32_t values = 99) {
  try {
    parse_net_config(doc, values);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(NetConfig){};

TEST(NetConfig, UdpConfigParsesWithPaperImpairmentAndSimulatorSeeds) {
  const NetConfig c = parse_net_config(udp_doc(), 99);
  CHECK_EQUAL(2, c.endpoint.wire.station_id);
  CHECK_EQUAL(9u, c.endpoint.wire.session_id);
  CHECK_EQUAL(0x1d, c.endpoint.wire.key.bytes[31]);
  CHECK_EQUAL(2u, c.endpoint.peers.size());
  CHECK(c.endpoint.peers[1].impaired);
  DOUBLES_EQUAL(0.200, c.endpoint.peers[1].impairment.mean_delay_s, 1e-12);
  DOUBLES_EQUAL(0.05, c.endpoint.peers[1].impairment.loss_probability, 1e-12);
  // Link 2 -> 3 is the simulator's (receiver 3, sender 2).
  CHECK_EQUAL(5ull * 1000003ull + 2 * 64 + 1, c.endpoint.peers[1].seed);  // net::link_seed(5, receiver 3 -> index 2, sender 2 -> index 1)
  CHECK_EQUAL(std::string("127.0.0.1:7003"), c.udp_peers[1].address);
  auto t = c.make_transport();
  CHECK_EQUAL(std::string("udp4"), t->name());
}

TEST(NetConfig, RawConfigNeedsInterfaceAndMacs) {
  const std::string doc = "[net]\nstation_id = 0\ntransport = \"raw\"\ninterface = \"hpn0\"\nshared_session_key = \"" + kKey +
                          "\"\n[[net.peers]]\nid = 1\nmac = \"02:48:50:00:00:02\"\n";
  const NetConfig c = parse_net_config(doc, 99);
  CHECK_EQUAL(std::string("hpn0"), c.interface);
  CHECK_EQUAL(0x02, c.raw_peers[0].mac[5]);
  CHECK_FALSE(c.endpoint.peers[0].impaired);
  CHECK(error_of("[net]\ntransport = \"raw\"\nshared_session_key = \"" + kKey + "\"\n[[net.peers]]\nid = 1\n")
            .find("net.interface") != std::string::npos);
}

TEST(NetConfig, BadValuesNameTheirKey) {
  CHECK(error_of(udp_doc("encoding = \"float16\"\n")).find("net.encoding") != std::string::npos);
  CHECK(error_of(udp_doc("max_datagram_bytes = 20\n")).find("net.max_datagram_bytes") != std::string::npos);
  CHECK(error_of(udp_doc("rtt_margin_fraction = -1\n")).find("net.rtt_margin_fraction") != std::string::npos);
  CHECK(error_of(udp_doc("io_cpu = -2\n")).find("net.io_cpu") != std::string::npos);
  CHECK(error_of(udp_doc("tx_spin = 1\n")).find("net.tx_spin") != std::string::npos);
  CHECK(error_of(udp_doc("tx_spin_tail_us = 0\n")).find("net.tx_spin_tail_us") != std::string::npos);
  std::string bad_transport = udp_doc();
  bad_transport.replace(bad_transport.find("\"udp\""), 5, "\"tcp\"");
  CHECK(error_of(bad_transport).find("net.transport") != std::string::npos);
  std::string bad_delay = udp_doc();
  bad_delay.replace(bad_delay.find("mean_delay_ms = 4"), 17, "mean_delay_ms = -3");
  CHECK(error_of(bad_delay).find("net.peers[0].mean_delay_ms") != std::string::npos);
  std::string bad_addr = udp_doc();
  bad_addr.replace(bad_addr.find("127.0.0.1:7003"), 14, "localhost:7003");
  CHECK(error_of(bad_addr).find("net.peers[1].address") != std::string::npos);
  std::string bad_key = udp_doc();
  bad_key.replace(bad_key.find(kKey), 4, "zzzz");
  CHECK(error_of(bad_key).find("net.shared_session_key") != std::string::npos);
  std::string bad_preset = udp_doc();
  bad_preset.replace(bad_preset.find("\"paper\""), 7, "\"awful\"");
  CHECK(error_of(bad_preset).find("net.impairment.preset") != std::string::npos);
  CHECK(error_of("[net\n").find("TOML parse error") != std::string::npos);
  CHECK(error_of("[station]\nid = 1\n").find("[net]") != std::string::npos);
}

// A scene whose state packet needs more than kMaxFragments datagrams is refused when the file is
// read (--check-config), naming the key with the smallest size that fits; that size is accepted and
// the endpoint then needs kMaxFragments datagrams or fewer. Float64 also names the encoding.
TEST(NetConfig, AStatePacketTooLargeForTheFragmentsNamesTheSmallestDatagramThatFits) {
  const std::uint32_t dofs = 3 * 29000;  // 29,000 nodes: 696 kB in float32, 1448-byte datagrams
  std::string e;
  try {
    parse_net_config(udp_doc(), dofs);
  } catch (const std::invalid_argument& x) {
    e = x.what();
  }
  STRCMP_CONTAINS("net.max_datagram_bytes = 1400 must be at least ", e.c_str());
  STRCMP_CONTAINS("29000 nodes, float32", e.c_str());
  const int need = std::stoi(e.substr(e.find("at least ") + 9));
  const NetConfig ok = parse_net_config(udp_doc("max_datagram_bytes = " + std::to_string(need) + "\n"), dofs);
  const Encoder enc(ok.endpoint.wire);
  CHECK(enc.fragment_count(dofs) >= 1 && enc.fragment_count(dofs) <= kMaxFragments);
  CHECK(error_of(udp_doc("max_datagram_bytes = " + std::to_string(need - 4) + "\n"), dofs).find("net.max_datagram_bytes") != std::string::npos);
  STRCMP_CONTAINS("net.encoding = \"float32\"", error_of(udp_doc("encoding = \"float64\"\n"), dofs).c_str());
  CHECK(error_of(udp_doc(), 99).empty());  // a small scene: one datagram
  // above what UDP sends unfragmented: said here too, not first when the transport opens
  STRCMP_CONTAINS("net.max_datagram_bytes = 1473 must be at most 1472 for transport = \"udp\" over IPv4",
                  error_of(udp_doc("max_datagram_bytes = 1473\n")).c_str());
  CHECK(error_of(udp_doc("max_datagram_bytes = 1472\n")).empty());
  CHECK(error_of(udp_doc(), 3 * 16703).empty());  // the 16,703-node ball: 306 datagrams of 1400 bytes
  // 40,000 nodes need 1964-byte datagrams: more than UDP sends unfragmented, at any setting
  STRCMP_CONTAINS("too many nodes for the network", error_of(udp_doc("max_datagram_bytes = 1472\n"), 3 * 40000).c_str());
}

TEST(NetConfig, Float32IsTheDefaultAndTickSynchronousTxIsOptIn) {
  const NetConfig c = parse_net_config(udp_doc(), 99);
  CHECK(c.endpoint.wire.encoding == ValueEncoding::float32);
  CHECK_FALSE(c.endpoint.tx_spin);
  CHECK_EQUAL(-1, c.endpoint.io_cpu);
  const NetConfig s = parse_net_config(udp_doc("tx_spin = true\nio_cpu = 0\ntx_spin_lead_us = 50\n"), 99);
  CHECK(s.endpoint.tx_spin);
  CHECK_EQUAL(0, s.endpoint.io_cpu);
  DOUBLES_EQUAL(50e-6, s.endpoint.tx_spin_lead_s, 1e-12);
}

TEST(NetConfig, DirectTxIsOptInAndNamedWhenMistyped) {
  CHECK_FALSE(parse_net_config(udp_doc(), 99).endpoint.tx_direct);
  CHECK(parse_net_config(udp_doc("tx_direct = true\n"), 99).endpoint.tx_direct);
  CHECK(error_of(udp_doc("tx_direct = 1\n")).find("net.tx_direct") != std::string::npos);
}

TEST(NetConfig, DeployStyleNetworkSectionIsAccepted) {
  const std::string doc = "[station]\nid = 1\n[network]\ntransport = \"udp\"\nlisten = \"192.168.10.11:47000\"\nshared_session_key = \"" +
                          kKey + "\"\npeers = [{ station = 2, address = \"192.168.10.12:47000\" }]\n";
  const NetConfig c = parse_net_config(doc, 99);
  CHECK_EQUAL(1, c.endpoint.wire.station_id);
  CHECK_EQUAL(std::string("192.168.10.11:47000"), c.bind);
  CHECK_EQUAL(2, c.endpoint.peers[0].station_id);
  CHECK(error_of("[network]\ntransport = \"udp\"\nlisten = \"127.0.0.1:1\"\nshared_session_key = \"" + kKey +
                 "\"\npeers = [{ station = 2, address = \"nowhere\" }]\n")
            .find("network.peers[0].address") != std::string::npos);
}

TEST(NetConfig, ListeningOnAllInterfacesNeedsAnExplicitSetting) {
  const std::string head = "[station]\nid = 1\n[network]\ntransport = \"udp\"\nshared_session_key = \"" + kKey + "\"\n";
  const std::string peers = "peers = [{ station = 2, address = \"127.0.0.1:47002\" }]\n";
  const std::string e4 = error_of(head + "listen = \"0.0.0.0:47000\"\n" + peers);
  CHECK_TEXT(e4.find("network.listen") != std::string::npos && e4.find("listen_any") != std::string::npos, e4.c_str());
  const std::string e6 = error_of("[station]\nid = 1\n[net]\ntransport = \"udp\"\nshared_session_key = \"" + kKey +
                                  "\"\nbind = \"[::]:47000\"\n[[net.peers]]\nid = 2\naddress = \"[::1]:47002\"\n");
  CHECK_TEXT(e6.find("net.bind") != std::string::npos, e6.c_str());
  const NetConfig ok = parse_net_config(head + "listen = \"0.0.0.0:47000\"\nlisten_any = true\n" + peers, 99);
  CHECK_TRUE(ok.listen_any);
}
