// Telemetry: the ring drains to the file without loss under a bounded rate; a fault dumps the
// last seconds of records; a full ring counts drops instead of blocking.
#include <time.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "platform/telemetry.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

using haptic::platform::FaultKind;
using haptic::platform::Telemetry;
using haptic::platform::TelemetryConfig;
using haptic::platform::TelemetryRecord;

namespace {
std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(f, line)) lines.push_back(line);
  return lines;
}
std::string temp_dir() {
  char tmpl[] = "/tmp/haptic-telemetry-XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d ? d : "/tmp";
}
void sleep_us(long us) {
  timespec ts{0, us * 1000};
  nanosleep(&ts, nullptr);
}
}  // namespace

TEST_GROUP(Telemetry) {
  std::string dir;
  void setup() override { dir = temp_dir(); }
  void teardown() override { std::system(("rm -rf " + dir).c_str()); }
};

TEST(Telemetry, ring_drains_to_the_file_without_loss_at_a_bounded_rate) {
  TelemetryConfig c;
  c.path = dir + "/telemetry.csv";
  c.postmortem_dir = dir;
  c.value_names = {"energy_J", "force_N"};
  c.drain_period_ns = 2'000'000;
  auto t = std::make_unique<Telemetry>(c);
  constexpr std::uint64_t kRecords = 6000;  // 12 s of a 500 Hz station, pushed at ~40 kHz in bursts of 20
  for (std::uint64_t i = 0; i < kRecords; ++i) {
    TelemetryRecord r;
    r.tick = i;
    r.values[0] = 0.5 * static_cast<double>(i);
    r.values[1] = -1.0;
    CHECK(t->record(r));
    if (i % 20 == 19) sleep_us(500);
  }
  t->flush();
  LONGS_EQUAL(0, t->dropped());
  LONGS_EQUAL(kRecords, t->written());
  t.reset();
  const auto lines = read_lines(c.path);
  LONGS_EQUAL(kRecords + 1, lines.size());
  STRCMP_EQUAL("tick,scheduled_ns,wake_latency_ns,exec_ns,overruns,status,energy_J,force_N", lines[0].c_str());
  for (std::uint64_t i = 0; i < kRecords; ++i) {
    const std::string expected_prefix = std::to_string(i) + ",";
    CHECK_TEXT(lines[i + 1].rfind(expected_prefix, 0) == 0, lines[i + 1].c_str());
  }
  STRCMP_EQUAL("5999,0,0,0,0,0,2999.5,-1", lines.back().c_str());
}

TEST(Telemetry, fault_dumps_the_last_seconds_of_history) {
  TelemetryConfig c;
  c.postmortem_dir = dir;
  c.period_s = 0.002;
  c.postmortem_s = 1.0;  // 500 records
  auto t = std::make_unique<Telemetry>(c);
  LONGS_EQUAL(500, t->history_capacity());
  for (std::uint64_t i = 0; i < 1200; ++i) {
    TelemetryRecord r;
    r.tick = i;
    t->record(r);
    if (i % 100 == 99) sleep_us(1000);
  }
  t->report_fault(FaultKind::overrun_storm, 1199);
  t->report_fault(FaultKind::divergence, 1199);  // while the first is pending: counted only
  t->flush();
  LONGS_EQUAL(1, t->dumps());
  LONGS_EQUAL(2, t->faults());
  const std::string path = t->last_dump_path();
  STRCMP_CONTAINS("postmortem-overrun_storm-tick1199.csv", path.c_str());
  const auto lines = read_lines(path);
  LONGS_EQUAL(2 + 500, lines.size());  // comment, header, 500 records
  STRCMP_CONTAINS("fault overrun_storm reported at tick 1199", lines[0].c_str());
  CHECK(lines[2].rfind("700,", 0) == 0);
  CHECK(lines.back().rfind("1199,", 0) == 0);
}

TEST(Telemetry, full_ring_counts_drops_instead_of_blocking) {
  TelemetryConfig c;
  c.postmortem_dir = dir;
  c.drain_period_ns = 1'000'000'000;  // the logger sleeps 1 s between drains
  auto t = std::make_unique<Telemetry>(c);
  sleep_us(20'000);  // let the logger's first (empty) drain pass
  constexpr std::uint64_t kRecords = Telemetry::kRingCapacity + 1000;
  std::uint64_t accepted = 0;
  for (std::uint64_t i = 0; i < kRecords; ++i) {
    TelemetryRecord r;
    r.tick = i;
    if (t->record(r)) ++accepted;
  }
  t->flush();
  CHECK(t->dropped() > 0);
  LONGS_EQUAL(kRecords, accepted + t->dropped());
  LONGS_EQUAL(accepted, t->written());
}

TEST(Telemetry, bad_configuration_names_the_key) {
  TelemetryConfig c;
  c.postmortem_s = 0.0;
  try {
    Telemetry t(c);
    FAIL("postmortem_s = 0 accepted");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("telemetry.postmortem_s", e.what());
  }
  c = TelemetryConfig{};
  c.path = "/nonexistent-dir/x.csv";
  try {
    Telemetry t(c);
    FAIL("unwritable path accepted");
  } catch (const std::runtime_error& e) {
    STRCMP_CONTAINS("telemetry.path", e.what());
  }
}
