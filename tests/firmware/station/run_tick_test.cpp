// One iteration of the real station loop body (firmware::run_tick) with a real UDP endpoint, a
// neighbour process stand-in (a second endpoint in this process) sending states, the simulated
// device and the paper's 33-node core: it must not touch the heap, and it must use the packets.
#include <CppUTest/TestHarness.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "drivers/device_factory.hpp"
#include "firmware/scenario.hpp"
#include "tools/jitter/station_workload.hpp"
#include "firmware/session/h5.hpp"
#include "firmware/session/replay.hpp"
#include "firmware/station/run.hpp"
#include "net/config.hpp"
#include "tests/support/alloc_counter.hpp"
#include "tests/firmware/station/station_files.hpp"

using namespace haptic;

namespace {
std::string net_toml(int self, int port_base, const std::vector<int>& peers) {
  std::string t = "[station]\nid = " + std::to_string(self) + "\n[net]\ntransport = \"udp\"\nsession_id = 9\n";
  t += "shared_session_key = \"5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d\"\n";
  t += "bind = \"127.0.0.1:" + std::to_string(port_base + self) + "\"\n";
  for (int p : peers) t += "[[net.peers]]\nid = " + std::to_string(p) + "\naddress = \"127.0.0.1:" + std::to_string(port_base + p) + "\"\n";
  return t;
}

firmware::BuiltScenario rig_scenario(double period_min_s, double period_max_s) {
  firmware::ScenarioSpec s = firmware::make_scenario("paper-best");
  s.period_min_s = period_min_s;
  s.period_max_s = period_max_s;
  return firmware::build_scenario(s);
}

// Station 1 of the paper's scene with a real UDP endpoint, a neighbour stand-in (a second
// endpoint in this process) sending states, the simulated device and the 33-node core.
struct OneStationRig {
  firmware::BuiltScenario b = firmware::build_scenario(firmware::make_scenario("paper-best"));
  int dofs = b.scene.dofs;
  int port_base = 48000 + static_cast<int>(getpid() % 400) * 5;
  net::NetConfig c1, c2;
  std::unique_ptr<net::Endpoint> ep1, ep2;
  drivers::OpenedDevice dev;
  rt::StationCore core{b.station_config(0)};
  std::vector<int> sender_to_nbr = std::vector<int>(65536, -1);
  firmware::TickRecords rec;
  firmware::TickCounters cnt;
  firmware::TickInputs in;
  std::vector<double> x0, v0;
  platform::TickInfo info;

  explicit OneStationRig(int ticks, double period_min_s = 0, double period_max_s = 0) : b(rig_scenario(period_min_s, period_max_s)) {
    c1 = net::parse_net_config(net_toml(1, port_base, {2, 3, 4}), static_cast<std::uint32_t>(dofs));
    c2 = net::parse_net_config(net_toml(2, port_base, {1}), static_cast<std::uint32_t>(dofs));
    // As the station does: the endpoint is told the tick period (for net.tx_spin).
    c1.endpoint.tx_period_s = c2.endpoint.tx_period_s = b.spec.period_s;
    ep1 = std::make_unique<net::Endpoint>(c1.endpoint, c1.make_transport());
    ep2 = std::make_unique<net::Endpoint>(c2.endpoint, c2.make_transport());
    ep1->start();
    ep2->start();
    drivers::DeviceSelection sel;
    sel.kind = "simulated";
    sel.simulated.device = b.spec.device;
    sel.simulated.hand = b.spec.hand;
    sel.simulated.script = b.goal_script(0);
    for (int a = 0; a < 3; ++a) sel.simulated.start_position_m[a] = b.vp_start[0][a];
    dev = drivers::open_device(sel);
    for (std::size_t n = 0; n < b.neighbors[0].size(); ++n) sender_to_nbr[static_cast<std::size_t>(b.neighbors[0][n] + 1)] = static_cast<int>(n);
    rec.reserve(static_cast<std::size_t>(ticks), static_cast<std::size_t>(ticks), dofs);
    in.core = &core;
    in.ep = ep1.get();
    in.device = dev.device.get();
    in.simulated = dev.simulated;
    in.sender_to_nbr = sender_to_nbr.data();
    in.dofs = dofs;
    in.trace_node = b.trace_node;
    in.period_s = b.spec.period_s;
    x0.assign(b.scene.x_d.data(), b.scene.x_d.data() + dofs);
    v0.assign(static_cast<std::size_t>(dofs), 0.0);
  }
  ~OneStationRig() {
    ep1->stop();
    ep2->stop();
  }
  void step(std::int64_t k) {
    ep2->push_state(static_cast<std::uint64_t>(k), net::monotonic_s(), x0.data(), v0.data());
    std::this_thread::sleep_for(std::chrono::microseconds(1500));  // let the I/O threads deliver
    info.index = static_cast<std::uint64_t>(k);
    firmware::run_tick(in, rec, cnt, k, k, info);
  }
};
}  // namespace

// A session recorder writing `path`, fed by the rig's tick from now on.
std::unique_ptr<firmware::SessionRecorder> record_into(OneStationRig& r, const std::string& path) {
  firmware::RecorderConfig rc;
  rc.path = path;
  firmware::SessionInfo si;
  si.packets_float32 = r.c1.endpoint.wire.encoding == net::ValueEncoding::float32;
  auto rec = std::make_unique<firmware::SessionRecorder>(rc, si, r.core.config());
  r.in.recorder = rec.get();
  return rec;
}

TEST_GROUP(RunTick){};

TEST(RunTick, the_core_integrates_over_the_measured_wake_to_wake_period_clamped_to_the_bounds) {
  // station.period_min_s = 1.8 ms, period_max_s = 2.2 ms: prefactored steps every 0.05 ms. The
  // tick hands the core the interval between this wake and the previous one (T_k); an overrun's
  // 6 ms is clamped to 2.2 ms and counted.
  {
    OneStationRig r(8, 0.0018, 0.0022);
    const std::int64_t wake_us[] = {1000, 3100, 5000, 11000, 13000};
    const double want_s[] = {0.002, 0.0021, 0.0019, 0.0022, 0.002};
    for (int k = 0; k < 5; ++k) {
      r.info.wake_ns = wake_us[k] * 1000;
      r.step(k);
      DOUBLES_EQUAL(want_s[k], r.core.last_step_s(), 1e-12);
    }
    CHECK_EQUAL(1u, r.core.step_clamped_ticks());
  }
  // a fixed-step configuration integrates over the nominal period whatever the wake times (the
  // first rig is gone: the same ports)
  OneStationRig fixed(4);
  for (int k = 0; k < 3; ++k) {
    fixed.info.wake_ns = (k * 2500 + 7) * 1000;
    fixed.step(k);
    DOUBLES_EQUAL(0.002, fixed.core.last_step_s(), 1e-15);
  }
  CHECK_EQUAL(0u, fixed.core.step_clamped_ticks());
}

TEST(RunTick, OneLoopIterationAllocatesNothingAndUsesTheNeighboursPackets) {
  CHECK(test::allocation_counter_works());
  const int ticks = 300;
  OneStationRig r(ticks);
  CHECK(r.dev.simulated != nullptr);
  for (std::int64_t k = 0; k < 50; ++k) r.step(k);  // warm-up: first contact solve, first packets
  const std::uint64_t offered_before = r.cnt.rx_offered;
  std::uint64_t allocations = 0;
  {
    test::AllocationCounter counter;
    for (std::int64_t k = 50; k < ticks - 10; ++k) r.step(k);
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
  CHECK(r.cnt.rx_offered - offered_before > 100);  // the neighbour's packets went into rx(n).offer
  LONGS_EQUAL(ticks - 10, r.cnt.ticks_run);
  CHECK_FALSE(r.cnt.diverged);
  LONGS_EQUAL(0, r.cnt.device_fault_ticks);
}

// The tick's rows stream through the record windows while the writer thread drains them: the tick
// allocates nothing, and every row it wrote is in the files. With no room (a writer that fell
// behind) the tick does not wait: it drops the row and counts it.
TEST(RunTick, TheRecordWindowsCostTheTickNoAllocationAndAFullWindowDropsRowsAndCountsThem) {
  const std::string dir = test::fresh_dir("tick-records");
  std::uint64_t allocations = 0;
  {
    OneStationRig r(64);
    firmware::RecordFiles files(dir + "/s", r.b.spec.period_s, r.rec);
    for (std::int64_t k = 0; k < 20; ++k) r.step(k);  // warm-up
    {
      test::AllocationCounter counter;
      for (std::int64_t k = 20; k < 200; ++k) r.step(k);
      allocations = counter.allocations();
    }
    STRCMP_EQUAL("", files.finish().c_str());
    LONGS_EQUAL(200, r.rec.trace_rows + r.rec.trace_lost);
    LONGS_EQUAL(200, r.rec.state_rows + r.rec.state_lost);
    std::ifstream f(dir + "/s-trace.csv");
    std::size_t lines = 0;
    for (std::string line; std::getline(f, line);) ++lines;
    LONGS_EQUAL(r.rec.trace_rows + 1, lines);
  }
  LONGS_EQUAL(0, allocations);
  OneStationRig full(4);  // windows of 4 rows and no writer
  for (std::int64_t k = 0; k < 10; ++k) full.step(k);
  LONGS_EQUAL(4, full.rec.trace_rows);
  LONGS_EQUAL(6, full.rec.trace_lost);
  LONGS_EQUAL(4, full.rec.state_rows);
  LONGS_EQUAL(6, full.rec.state_lost);
  LONGS_EQUAL(10, full.cnt.ticks_run);
}

// The session log's caches stay at their fixed sizes however long the log grows: each dataset's
// chunk cache holds two chunks (HDF5's default, 1 MB for each of the log's 20 datasets, made a
// recording station's RSS grow 11 % in its first 10 minutes), the metadata cache 2 MB (the default
// grows adaptively to 32 MB).
TEST(RunTick, TheSessionLogsCachesStayFixedAsTheLogGrows) {
  const std::string path = test::fresh_dir("mdc") + "/log.h5";
  firmware::h5::Id file = firmware::h5::create_file(path);
  firmware::h5::Appendable a(file.get(), "x", firmware::h5::Type::kF64, 33, 4);
  std::vector<double> row(33, 1.0);
  for (int i = 0; i < 40000; ++i) a.append(firmware::h5::Type::kF64, row.data(), 1);
  H5AC_cache_config_t c;
  c.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  CHECK(H5Fget_mdc_config(file.get(), &c) >= 0);
  LONGS_EQUAL(firmware::h5::kMetadataCacheBytes, c.max_size);
  size_t max_size = 0, min_clean = 0, cur_size = 0;
  int entries = 0;
  CHECK(H5Fget_mdc_size(file.get(), &max_size, &min_clean, &cur_size, &entries) >= 0);
  LONGS_EQUAL(firmware::h5::kMetadataCacheBytes, max_size);
  CHECK(cur_size <= firmware::h5::kMetadataCacheBytes);
  firmware::h5::Id dapl(H5Dget_access_plist(a.id()), firmware::h5::Id::Kind::kPlist, "dapl");
  size_t slots = 0, bytes = 0;
  double w0 = 0;
  CHECK(H5Pget_chunk_cache(dapl.get(), &slots, &bytes, &w0) >= 0);
  LONGS_EQUAL(2 * 4 * 33 * sizeof(double), bytes);  // two chunks of 4 rows of 33 doubles
}

// The tick with the session recorder on still allocates nothing, and what it recorded (real UDP
// packets, the simulated device) replays bit-exactly.
TEST(RunTick, RecordingAllocatesNothingInTheTickAndTheLogReplaysBitExactly) {
  const int ticks = 300;
  OneStationRig r(ticks);
  const std::string path = "/tmp/haptic-run-tick-" + std::to_string(getpid()) + ".h5";
  const auto recorder = record_into(r, path);
  for (std::int64_t k = 0; k < 50; ++k) r.step(k);
  std::uint64_t allocations = 0;
  {
    test::AllocationCounter counter;
    for (std::int64_t k = 50; k < ticks; ++k) r.step(k);
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
  const firmware::RecorderStats st = recorder->finish();
  LONGS_EQUAL(ticks, st.ticks);
  LONGS_EQUAL(0, st.dropped_records);
  CHECK(st.packets > 100);
  const firmware::ReplayResult rr = firmware::replay_session(path, {});
  std::remove(path.c_str());
  LONGS_EQUAL(ticks, rr.ticks);
  CHECK_TRUE(rr.bit_exact());
}

// The live view's hand-off in the tick (station.view_port: a fixed-size frame filled in place in a
// latest-value mailbox every `every` ticks) allocates nothing, and the reader gets frames of this
// copy with the neighbour's link; a reader that does not keep up only misses frames (seq gaps).
TEST(RunTick, TheLiveViewHandOffAllocatesNothingInTheTickAndTheReaderGetsFrames) {
  const int ticks = 300;
  OneStationRig r(ticks);
  auto view = std::make_unique<firmware::ViewPublisher>(2);  // a frame every second tick: more often than a station's ~17
  r.in.view = view.get();
  for (std::int64_t k = 0; k < 50; ++k) r.step(k);
  auto frame = std::make_unique<firmware::ViewFrame>();
  std::uint64_t allocations = 0, frames = 0, first_seq = 0, last_seq = 0;
  {
    test::AllocationCounter counter;
    for (std::int64_t k = 50; k < ticks; ++k) {
      r.step(k);
      if (k % 10 == 0 && view->take(*frame)) {  // the reader takes one frame in five: it misses the rest
        ++frames;
        if (first_seq == 0) first_seq = frame->seq;
        last_seq = frame->seq;
      }
    }
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
  CHECK(frames >= 20);
  CHECK(last_seq - first_seq > 2 * (frames - 1));  // frames the reader did not take were replaced, not queued
  LONGS_EQUAL(r.core.neighbor_count(), frame->neighbours);
  LONGS_EQUAL(r.core.config().scene->nodes, frame->nodes);
  CHECK(frame->k >= ticks - 12);
  DOUBLES_EQUAL(r.core.x()[0], frame->x[0], 1e-6);  // this copy as of the newest published frame (x settles slowly)
}

// The live view says what the gate did: each frame carries the energy gate's trips and removed
// energy, the edge-drop events (here: the neighbours 3 and 4 of the rig never send, so their edges
// are dropped) and the worst port energy so far, and its JSON names them ("gate").
TEST(RunTick, TheLiveViewsFramesNameWhatTheGateAndTheDropRuleDid) {
  const int ticks = 120;
  OneStationRig r(ticks);
  auto view = std::make_unique<firmware::ViewPublisher>(1);
  r.in.view = view.get();
  auto frame = std::make_unique<firmware::ViewFrame>();
  double port_min = 0;
  for (std::int64_t k = 0; k < ticks; ++k) {
    r.step(k);
    port_min = std::min(port_min, r.core.energy().port_J);
  }
  CHECK_TRUE(view->take(*frame));
  CHECK(r.core.edge_drop_events() > 0);
  CHECK_EQUAL(r.core.edge_drop_events(), frame->edge_drops);
  CHECK_EQUAL(r.core.edge_gate().trips(), frame->gate_trips);
  DOUBLES_EQUAL(r.core.edge_gate().removed_J(), frame->gate_removed_J, 0);
  DOUBLES_EQUAL(port_min, frame->port_min_J, 0);
  frame->gate_trips = 3, frame->gate_removed_J = 0.012, frame->port_min_J = -0.014;
  const auto j = firmware::view_frame_json(*frame);
  CHECK_EQUAL(3u, j["gate"]["trips"].get<std::uint64_t>());
  CHECK_TRUE(j["gate"]["held"].get<bool>());
  DOUBLES_EQUAL(0.012, j["gate"]["removed_J"].get<double>(), 0);
  CHECK_EQUAL(r.core.edge_drop_events(), j["gate"]["edge_drops"].get<std::uint64_t>());
  DOUBLES_EQUAL(-0.014, j["gate"]["port_min_J"].get<double>(), 0);
}

// With station.period_min_s/max_s the tick hands the core the measured wake-to-wake period; the
// session log stores that T_k per tick (/ticks/step_s), and replay hands the same T_k to the core:
// bit-exact, including the ticks the core clamped.
TEST(RunTick, TheLogStoresEachTicksMeasuredStepAndReplaysBitExactlyWithIt) {
  const int ticks = 120;
  OneStationRig r(ticks, 0.0018, 0.0022);
  const std::string path = "/tmp/haptic-run-tick-steps-" + std::to_string(getpid()) + ".h5";
  const auto recorder = record_into(r, path);
  std::vector<double> want(ticks);
  std::int64_t prev_us = 0;
  for (std::int64_t k = 0; k < ticks; ++k) {
    const std::int64_t wake_us = 1000 + 2000 * k + 37 * (k % 7);  // +37 us six ticks in seven, -222 us (clamped) in the seventh
    r.info.wake_ns = wake_us * 1000;
    want[static_cast<std::size_t>(k)] = k == 0 ? 0.002 : static_cast<double>(wake_us - prev_us) * 1e-6;
    prev_us = wake_us;
    r.step(k);
  }
  recorder->finish();
  CHECK(r.core.step_clamped_ticks() > 10);
  {
    firmware::h5::Id f = firmware::h5::open_file_read(path);
    const std::vector<firmware::TickRecord> rows = firmware::read_tick_records(f.get());
    LONGS_EQUAL(ticks, rows.size());
    for (int k = 0; k < ticks; ++k) DOUBLES_EQUAL(want[static_cast<std::size_t>(k)], rows[static_cast<std::size_t>(k)].step_s, 1e-12);
  }
  const firmware::ReplayResult rr = firmware::replay_session(path, {});
  std::remove(path.c_str());
  LONGS_EQUAL(ticks, rr.ticks);
  CHECK_TEXT(rr.bit_exact(), rr.summary().c_str());
}

TEST(RunTick, TheJitterWorkloadIsTheRealStationTickAndAllocatesNothing) {
  tools::StationJitterWorkload w;
  LONGS_EQUAL(3, w.core().neighbor_count());
  platform::TickInfo info;
  for (std::uint64_t k = 0; k < 100; ++k) {
    info.index = k;
    w.tick(info);
  }
  std::uint64_t allocations = 0;
  {
    test::AllocationCounter counter;
    for (std::uint64_t k = 100; k < 1500; ++k) {  // through the push (contact onset at 0.5 s)
      info.index = k;
      w.tick(info);
    }
    allocations = counter.allocations();
  }
  LONGS_EQUAL(0, allocations);
  CHECK(w.core().in_contact());
  CHECK((w.flags_seen() & rt::kDiverged) == 0);
}

TEST(RunTick, TheCoreTicksTheCallersCycleIndexSoSkippedCyclesCountAsDelay) {
  const firmware::BuiltScenario b = firmware::build_scenario(firmware::make_scenario("paper-best"));
  rt::StationConfig sc = b.station_config(0);
  for (auto& n : sc.neighbors) n.index_delay_bound_ticks = 5;
  rt::StationCore core(sc);
  const int dofs = b.scene.dofs;
  std::vector<double> x0(b.scene.x_d.data(), b.scene.x_d.data() + dofs), v0(static_cast<std::size_t>(dofs), 0.0);
  const rt::Vec3 q = b.vp_start[0];
  for (int n = 0; n < core.neighbor_count(); ++n) core.rx(n).offer(0, 0.0, x0.data(), v0.data(), dofs);
  CHECK((core.tick(0, q).flags & rt::kEdgeDropped) == 0);
  LONGS_EQUAL(0, core.sequence());
  // The loop skipped cycles 1..19 (an overrun): cycle 20 sees data 20 cycles old, beyond the bound.
  CHECK((core.tick(20, q).flags & rt::kEdgeDropped) != 0);
  LONGS_EQUAL(20, core.sequence());
  LONGS_EQUAL(20, core.rx(0).counters().max_index_delay);
}
