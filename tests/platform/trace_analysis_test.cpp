// Records a short real LTTng trace of two haptic-jitter processes at once (two "stations", each
// running platform::PeriodicLoop with deliberate overruns) through tools/trace/record.sh, analyses
// it with tools/trace/analyze.py, and checks each station against the loop's own counters
// (haptic-jitter --json): ticks, overruns, missed cycles, period, per-stage breakdown.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <regex>
#include <string>
#include <vector>

#include "platform/trace.hpp"
#include "tests/support/file_text.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

namespace {
using haptic::test::file_text;
// First integer value of "key": N in a JSON text (flat enough for these two documents).
long long json_int(const std::string& text, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("\"" + key + "\": (-?[0-9]+)"))) return -1;
  return std::stoll(m[1]);
}

// Per-station blocks of the analysis JSON ("vpid" starts each one).
std::vector<std::string> station_blocks(const std::string& analysis) {
  std::vector<std::string> blocks;
  std::size_t pos = analysis.find("\"vpid\":");
  while (pos != std::string::npos) {
    const std::size_t next = analysis.find("\"vpid\":", pos + 1);
    blocks.push_back(analysis.substr(pos, next == std::string::npos ? std::string::npos : next - pos));
    pos = next;
  }
  return blocks;
}
}  // namespace

TEST_GROUP(TraceAnalysis){};

TEST(TraceAnalysis, analysis_of_a_real_trace_matches_the_loops_own_counters) {
  if (!haptic::platform::trace::kCompiledIn) {
    FAIL("tracing impossible: built with HAPTIC_WITH_LTTNG=OFF (install liblttng-ust-dev and reconfigure)");
  }
  if (access("/usr/bin/lttng", X_OK) != 0) FAIL("tracing impossible: /usr/bin/lttng missing (apt install lttng-tools)");
  char tmpl[] = "/tmp/haptic-trace-test-XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  const std::string src = HAPTIC_SOURCE_DIR;
  const std::string jitter = HAPTIC_JITTER_BIN;
  // Two "stations" in one trace: 1500 ticks of 1 ms with every 250th tick overrunning on purpose
  // (1.5 periods of busy work), and 800 ticks of 2 ms with every 200th overrunning.
  const std::string stations = "'" + jitter + " -q -i 1000 -w 50 -l 1500 --overrun-every 250 --no-mlock --json " + dir +
                               "/loop-a.json & " + jitter + " -q -i 2000 -w 50 -l 800 --overrun-every 200 --no-mlock --json " +
                               dir + "/loop-b.json & wait'";
  const std::string cmd = src + "/tools/trace/record.sh -o " + dir + "/trace -- sh -c " + stations + " > " + dir + "/record.log 2>&1";
  const int rc = std::system(cmd.c_str());
  const std::string log = file_text(dir + "/record.log");
  if (WEXITSTATUS(rc) == 3) FAIL(("tracing impossible here, record.sh says:\n" + log).c_str());
  LONGS_EQUAL_TEXT(0, WEXITSTATUS(rc), log.c_str());
  const std::string analyze = "/usr/bin/python3 " + src + "/tools/trace/analyze.py " + dir + "/trace --procname haptic-jitter --json " +
                              dir + "/analysis.json --plots " + dir + "/plots > " + dir + "/analyze.log 2>&1";
  const int rc2 = std::system(analyze.c_str());
  LONGS_EQUAL_TEXT(0, WEXITSTATUS(rc2), file_text(dir + "/analyze.log").c_str());

  const std::string analysis = file_text(dir + "/analysis.json");
  LONGS_EQUAL_TEXT(0, json_int(analysis, "discarded_events"), "the tracer discarded events; the comparison would be meaningless");
  const auto blocks = station_blocks(analysis);
  LONGS_EQUAL(2, blocks.size());
  for (const char* name : {"loop-a.json", "loop-b.json"}) {
    const std::string loop = file_text(dir + "/" + name);
    const long long ticks = json_int(loop, "ticks");
    const long long overruns = json_int(loop, "overruns");
    CHECK(ticks == 1500 || ticks == 800);
    CHECK(overruns >= 4);  // at least the deliberate ones
    int matched = 0;
    for (const auto& b : blocks) {
      if (json_int(b, "ticks") != ticks) continue;
      ++matched;
      LONGS_EQUAL(ticks, json_int(b, "tick_ends"));
      LONGS_EQUAL(overruns, json_int(b, "overruns"));
      LONGS_EQUAL(json_int(loop, "missed_cycles"), json_int(b, "missed_cycles"));
      LONGS_EQUAL(ticks == 1500 ? 1000 : 2000, json_int(b, "period_us"));
      STRCMP_CONTAINS("\"workload\": {", b.c_str());  // per-stage breakdown present
    }
    LONGS_EQUAL_TEXT(1, matched, name);
  }
  CHECK(access((dir + "/plots").c_str(), F_OK) == 0);
  std::system(("rm -rf " + dir).c_str());
}
