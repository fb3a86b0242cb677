// The station's record windows (firmware/station/records.hpp): memory set by a time window, not
// by the planned duration; the writer thread streams every row the tick wrote, in order.
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>

#include "firmware/station/plan.hpp"
#include "firmware/station/records.hpp"
#include "firmware/station/report.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;
using namespace haptic::firmware;

namespace {

StationPlan plan_for(double duration_s, const std::string& extra = "") {
  test::StationText s;
  s.peers = {2, 3, 4};
  s.out_dir = "/tmp";
  s.station_extra = "duration_s = " + std::to_string(duration_s) + "\n" + extra;
  const PlanResult pr = plan_station(parse_station_file(s.text()), RunOverrides{}, read_clocks());
  CHECK_TEXT(pr.status == PhaseStatus::kOk, pr.error.c_str());
  return *pr.plan;
}

// The writer side as the tick does it, except that this test waits for room (the tick never does).
void push_trace(TickRecords& rec, std::int64_t k) {
  std::size_t s;
  while ((s = rec.trace_window.writer_slot()) == RowWindow::kNone) std::this_thread::sleep_for(std::chrono::microseconds(200));
  TraceRec r{};
  r.k = k;
  r.node[0] = 0.25 * static_cast<double>(k);
  rec.trace[s] = r;
  rec.trace_window.writer_commit();
}

void push_state(TickRecords& rec, std::int64_t k) {
  std::size_t s;
  while ((s = rec.state_window.writer_slot()) == RowWindow::kNone) std::this_thread::sleep_for(std::chrono::microseconds(200));
  rec.state_k[s] = k;
  for (int d = 0; d < rec.dofs; ++d) rec.state_x[s * static_cast<std::size_t>(rec.dofs) + static_cast<std::size_t>(d)] = static_cast<double>(k + d);
  rec.state_window.writer_commit();
}

std::string file_text(const std::string& path) {
  std::ifstream f(path);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

}  // namespace

TEST_GROUP(StationRecords){};

// An hour's plan locks as much record memory as a minute's: the windows hold station.trace_every /
// state_every rows of kRecordWindowS, whatever station.duration_s (and reserve() holds what the
// plan says).
TEST(StationRecords, ThePlannedRecordBytesOfAMinuteAndOfAnHourAreEqual) {
  const StationPlan minute = plan_for(60), hour = plan_for(3600);
  CHECK(minute.times.run_ticks * 50 <= hour.times.run_ticks);
  CHECK(minute.record_window_bytes() > 0);
  LONGS_EQUAL(minute.record_window_bytes(), hour.record_window_bytes());
  LONGS_EQUAL(minute.trace_capacity, hour.trace_capacity);
  LONGS_EQUAL(minute.state_capacity, hour.state_capacity);
  // the window covers kRecordWindowS of rows (default trace_every 1, state_every 5 at 2 ms)
  CHECK(static_cast<double>(hour.trace_capacity) * hour.built->spec.period_s >= kRecordWindowS);
  CHECK(static_cast<double>(hour.state_capacity) * 5 * hour.built->spec.period_s >= kRecordWindowS);
  TickRecords rec;
  rec.reserve(hour.trace_capacity, hour.state_capacity, hour.built->scene.dofs);
  LONGS_EQUAL(hour.record_window_bytes(),
              rec.trace.size() * sizeof(TraceRec) + rec.state_k.size() * sizeof(std::int64_t) + rec.state_x.size() * sizeof(double));
}

// Many times the window's rows go through it while the writer thread drains it: the files hold
// every row once, in order, with main's text (header and row format).
TEST(StationRecords, TheWriterStreamsEveryRowOnceInOrderThroughASmallWindow) {
  const std::string dir = test::fresh_dir("records");
  const int dofs = 3;
  TickRecords rec;
  rec.reserve(64, 16, dofs);
  LONGS_EQUAL(64, rec.trace_window.slots());
  RecordFiles files(dir + "/s", 0.002, rec);
  for (int k = 0; k < 2000; ++k) {
    push_trace(rec, k);
    if (k % 5 == 0) push_state(rec, k);
  }
  STRCMP_EQUAL("", files.finish().c_str());
  std::string want_trace =
      "k,t_s,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,device_x_m,device_y_m,device_z_m,"
      "port_energy_J,controller_energy_J,vo_energy_J,contact,flags,max_speed_m_per_s,wake_latency_ns,step_s\n";
  std::string want_state = "k,x0,x1,x2\n";
  char line[512];
  for (int k = 0; k < 2000; ++k) {
    std::snprintf(line, sizeof line, "%d,%.4f,%.9g,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n", k, (k + 1) * 0.002, 0.25 * k);
    want_trace += line;
    if (k % 5 == 0) {
      std::snprintf(line, sizeof line, "%d,%d,%d,%d\n", k, k, k + 1, k + 2);
      want_state += line;
    }
  }
  CHECK(want_trace == file_text(dir + "/s-trace.csv"));
  CHECK(want_state == file_text(dir + "/s-state.csv"));
}

// A file that cannot be created is an error naming it, before any thread starts.
TEST(StationRecords, AnUnwritableOutputIsAnErrorNamingTheFile) {
  TickRecords rec;
  rec.reserve(4, 4, 3);
  try {
    RecordFiles files("/proc/no-such-dir/station-1", 0.002, rec);
    FAIL("no error");
  } catch (const std::runtime_error& e) {
    STRCMP_CONTAINS("cannot write /proc/no-such-dir/station-1-trace.csv", e.what());
  }
}

// Rows the tick dropped because the writer fell behind are in station-<id>.json, never silent.
TEST(StationRecords, RowsLostToAFullWindowAreInTheStationSummary) {
  const StationPlan plan = plan_for(60);
  TickRecords rec;
  rec.reserve(plan.trace_capacity, plan.state_capacity, plan.built->scene.dofs);
  rec.trace_rows = 1000;
  rec.trace_lost = 3;
  rec.state_rows = 200;
  rec.state_lost = 1;
  StationOutcome o;
  o.plan = &plan;
  o.records = &rec;
  o.records_streamed = true;
  const nlohmann::json j = station_summary(o, run_conditions(o));
  LONGS_EQUAL(1000, j["records"]["trace_rows"].get<long>());
  LONGS_EQUAL(3, j["records"]["trace_rows_lost"].get<long>());
  LONGS_EQUAL(200, j["records"]["state_rows"].get<long>());
  LONGS_EQUAL(1, j["records"]["state_rows_lost"].get<long>());
  LONGS_EQUAL(plan.record_window_bytes(), j["records"]["window_bytes"].get<long>());
}
