// What the live view and the session recorder cost the tick, in one run so the figures
// are ratios on the same loaded machine. One "station tick" = user 1 of the paper's scene (or a
// lattice ball of about N nodes) with three neighbours' packets offered per tick (their copies at
// rest, index delay 3), core.tick, the simulated user advanced by the force, plus:
//   mode 0: nothing else (baseline)
//   mode 1: the session recorder (every packet, the tick row with its state hash; ring + writer thread)
//   mode 2: the live view's frame hand-off (ViewPublisher) and its server running, no browser
//   mode 3: as 2 with two headless Chromium pages connected (skipped without Debian's chromium)
// Counters: log_MB_per_min (rows written per recorded tick x 30,000 ticks), dropped_fraction of
// records the ring could not take, browsers connected. Run: build/bin/bench-view-record.
#include <benchmark/benchmark.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "firmware/scenario.hpp"
#include "firmware/session/recorder.hpp"
#include "firmware/view/frame.hpp"
#include "firmware/view/server.hpp"
#include "rt/station.hpp"
#include "rt/user_model.hpp"

extern char** environ;

namespace {

using namespace haptic;

struct Rig {
  firmware::BuiltScenario built;
  rt::StationCore core;
  rt::SimulatedUser user;
  std::vector<double> x0, v0;
  std::int64_t k = 0;
  explicit Rig(int nodes)
      : built(firmware::build_scenario([nodes] {
          auto s = firmware::make_scenario("paper-best");
          s.scene_nodes = nodes;
          return s;
        }())),
        core(built.station_config(0)),
        user(built.spec.device, built.spec.hand, built.goal_script(0)),
        x0(built.scene.x_d.data(), built.scene.x_d.data() + built.scene.dofs),
        v0(static_cast<std::size_t>(built.scene.dofs), 0.0) {
    user.reset(built.vp_start[0]);
  }
  // One station tick (rt::drive_tick) with the optional recorder and view hand-off. RT-safe.
  void tick(firmware::SessionRecorder* rec, firmware::ViewPublisher* view) {
    const double T = built.spec.period_s;
    const rt::Vec3 q = user.position_m();
    const auto out = rt::drive_tick(
        core, rt::TickDrive{k, 0, q, T},
        [&](auto&& offer) {
          for (int n = 0; n < core.neighbor_count(); ++n)
            offer(rt::ReceivedState{n, k - 3, static_cast<double>(k - 3) * T, x0.data(), v0.data(), built.scene.dofs});
        },
        firmware::RecordOffered{rec, k});
    if (rec) rec->rt_tick(firmware::make_tick_record(core, k, q, out, T));
    if (view) view->on_tick(core, k, T, q, out.device_force_N, out.flags, 0, 0);
    user.advance(static_cast<double>(k) * T, T, out.device_force_N);
    ++k;
  }
};

// Two headless Chromium pages on `url`, killed (by PID) on destruction.
struct Browsers {
  std::vector<pid_t> pids;
  Browsers(const std::string& url, int n) {
    for (int i = 0; i < n; ++i) {
      const std::string base = "/tmp/bench-view-chrome-" + std::to_string(getpid()) + "-" + std::to_string(i);
      const std::string profile = "--user-data-dir=" + base;
      std::vector<std::string> args = {"chromium", "--headless=new", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                                       "--use-angle=swiftshader", profile, "--window-size=1400,900", "--timeout=600000",
                                       "--screenshot=" + base + ".png", url};  // a .png name: chromium refuses any other (it quit at once with /dev/null)
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      pid_t pid = 0;
      if (posix_spawnp(&pid, "chromium", nullptr, nullptr, argv.data(), environ) == 0) pids.push_back(pid);
      bases.push_back(base);
    }
  }
  ~Browsers() {
    for (pid_t p : pids) kill(p, SIGTERM);
    for (pid_t p : pids) waitpid(p, nullptr, 0);
    for (const auto& b : bases) std::filesystem::remove_all(b), std::filesystem::remove(b + ".png");
  }
  std::vector<std::string> bases;
};

bool have_chromium() { return std::system("command -v chromium > /dev/null 2>&1") == 0; }

void BM_StationTick(benchmark::State& state) {
  const int nodes = static_cast<int>(state.range(0));
  const int mode = static_cast<int>(state.range(1));
  if (mode == 3 && !have_chromium()) {
    state.SkipWithError("chromium not installed (apt-get install chromium)");
    return;
  }
  Rig rig(nodes);
  std::unique_ptr<firmware::SessionRecorder> rec;
  std::unique_ptr<firmware::ViewPublisher> view;
  std::unique_ptr<firmware::ViewServer> server;
  std::unique_ptr<Browsers> browsers;
  const std::string path = "/tmp/bench-view-record-" + std::to_string(getpid()) + ".h5";
  if (mode == 1) {
    firmware::RecorderConfig rc;
    rc.path = path;
    rc.max_bytes = ~0ull;
    rec = std::make_unique<firmware::SessionRecorder>(rc, firmware::SessionInfo{}, rig.core.config());
  }
  if (mode >= 2) {
    view = std::make_unique<firmware::ViewPublisher>(17);
    const std::string scene = firmware::view_scene_json(rig.core, 1, "station").dump();
    auto frame = std::make_shared<firmware::ViewFrame>();
    firmware::ViewCallbacks cb;
    cb.scene = [scene] { return scene; };
    firmware::ViewPublisher* v = view.get();
    cb.next_frame = [v, frame](std::string& out) {
      if (!v->take(*frame)) return false;
      out = firmware::view_frame_json(*frame).dump();
      return true;
    };
    firmware::ViewServerConfig vc;
    vc.port = 46900 + static_cast<int>(getpid() % 50);
    vc.assets_dir = std::string(HAPTIC_SOURCE_DIR) + "/tools/view";
    server = std::make_unique<firmware::ViewServer>(vc, cb);
    if (mode == 3) {
      browsers = std::make_unique<Browsers>(server->url(), 2);
      for (int i = 0; i < 300 && server->stats().clients < 2; ++i) {  // bounded: 30 s
        for (int t = 0; t < 50; ++t) rig.tick(nullptr, view.get());  // frames flow while they connect
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
      if (server->stats().clients < 2) {
        state.SkipWithError("the two Chromium pages did not connect within 30 s");
        return;
      }
    }
  }
  for (int t = 0; t < 300; ++t) rig.tick(rec.get(), view.get());  // through contact onset
  for (auto _ : state) rig.tick(rec.get(), view.get());
  if (rec) {
    const firmware::RecorderStats st = rec->finish();
    const double per_tick = st.ticks ? static_cast<double>(st.bytes) / static_cast<double>(st.ticks) : 0;
    state.counters["log_MB_per_min"] = per_tick * 30000.0 / 1e6;
    state.counters["dropped_fraction"] = static_cast<double>(st.dropped_records) /
                                         static_cast<double>(st.dropped_records + st.packets + st.ticks + 1);
    std::remove(path.c_str());
  }
  if (server) {
    state.counters["browsers"] = server->stats().clients;
    state.counters["frames_sent"] = static_cast<double>(server->stats().frames_sent);
  }
  state.counters["nodes"] = rig.built.scene.nodes;
}
BENCHMARK(BM_StationTick)
    ->ArgsProduct({{33, 3000}, {0, 1, 2, 3}})
    ->ArgNames({"nodes", "mode"})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
