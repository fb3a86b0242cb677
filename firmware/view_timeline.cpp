#include "firmware/view_timeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <thread>
#include <vector>

#include "firmware/view_frame.hpp"

namespace haptic::firmware {

namespace {

// Play position over the kept frames; touched only on the server thread.
struct Player {
  std::vector<std::string> frames;
  std::size_t index = 0;
  bool playing = true;
  int step = 1;  // frames advanced per server frame (recorded speed)

  bool next(std::string& out) {
    if (frames.empty()) return false;
    out = frames[index];
    if (playing) index = (index + static_cast<std::size_t>(step)) % frames.size();  // loops
    return true;
  }
  void command(const std::string& msg) {
    const auto j = nlohmann::json::parse(msg, nullptr, false);
    if (j.is_discarded() || !j.is_object()) return;
    if (j.contains("seek") && j["seek"].is_number_integer())
      index = std::min<std::size_t>(static_cast<std::size_t>(std::max<long>(0, j["seek"].get<long>())), frames.size() - 1);
    if (j.contains("play") && j["play"].is_boolean()) playing = j["play"].get<bool>();
  }
};

}  // namespace

ReplayResult serve_timeline(const std::string& log, const ReplayOptions& replay, const TimelineOptions& opt, const std::atomic<bool>& stop) {
  auto player = std::make_shared<Player>();
  std::string scene;
  std::unique_ptr<ViewPublisher> pub;
  ViewFrame frame;
  std::vector<nlohmann::json> kept;
  const ReplayResult r = replay_session(log, replay, [&](const rt::StationCore& core, const TickRecord& rec, std::int64_t) {
    if (!pub) {
      const double T = core.config().period_s;
      pub = std::make_unique<ViewPublisher>(static_cast<int>(std::lround(1.0 / (opt.server.rate_hz * T))));
      scene = view_scene_json(core, static_cast<int>(core.config().station_id) + 1, opt.mode).dump();
    }
    pub->on_tick(core, rec.k, core.config().period_s, rt::Vec3(rec.q[0], rec.q[1], rec.q[2]), rt::Vec3(rec.force[0], rec.force[1], rec.force[2]),
                 rec.flags, rec.exec_ns, rec.wake_latency_ns);
    if (pub->take(frame)) kept.push_back(view_frame_json(frame));
  });
  const std::size_t stride = kept.size() / 4000 + 1;
  for (std::size_t i = 0; i < kept.size(); i += stride) {
    kept[i]["index"] = player->frames.size();
    player->frames.push_back(kept[i].dump());
  }
  if (player->frames.empty()) throw std::runtime_error("live view: the log has no ticks to show");
  auto sc = nlohmann::json::parse(scene);
  sc["timeline_frames"] = player->frames.size();
  sc["replay"] = r.summary();
  const std::string scene_text = sc.dump();
  ViewCallbacks cb;
  cb.scene = [scene_text] { return scene_text; };
  cb.next_frame = [player](std::string& out) { return player->next(out); };
  cb.on_message = [player](const std::string& m) { player->command(m); };
  ViewServer server(opt.server, cb);
  std::cerr << "haptic-station: live view of " << log << " at " << server.url() << " (" << player->frames.size() << " frames"
            << (opt.serve_s > 0 ? ", for " + std::to_string(opt.serve_s) + " s" : ", until interrupted") << ")\n";
  const auto t0 = std::chrono::steady_clock::now();
  while (!stop.load(std::memory_order_acquire) &&
         (opt.serve_s <= 0 || std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < opt.serve_s))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ViewServerStats st = server.stats();
  std::replace(st.last_browser_status.begin(), st.last_browser_status.end(), '\n', '|');
  std::cerr << "haptic-station: live view served " << st.frames_sent << " frames to " << st.clients_total << " browser(s), " << st.frames_dropped
            << " dropped; last status a browser showed: " << (st.last_browser_status.empty() ? "(none)" : st.last_browser_status) << "\n";
  return r;
}

}  // namespace haptic::firmware
