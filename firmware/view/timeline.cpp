#include "firmware/view/timeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <regex>
#include <thread>
#include <vector>

#include "firmware/view/frame.hpp"

namespace haptic::firmware {

namespace {

// Play position over the kept frames; touched only on the server thread.
struct Player {
  std::vector<std::string> frames;
  std::vector<double> times;  // each frame's run time t (s), ascending: {"seek_t": s} finds the frame at s
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
    if (j.contains("seek_t") && j["seek_t"].is_number()) {  // run time: the first frame at or after it (one timeline for a lab's stations)
      const auto at = std::lower_bound(times.begin(), times.end(), j["seek_t"].get<double>());
      index = std::min<std::size_t>(static_cast<std::size_t>(at - times.begin()), frames.size() - 1);
    }
    if (j.contains("play") && j["play"].is_boolean()) playing = j["play"].get<bool>();
  }
};

// The plots' values of every kept frame (sent once in the scene message, so the page plots the
// whole recording and moves a cursor: a paused or sought timeline still shows the curves).
// Row: t, force x/y/z, port, controller, VO energies, received-copy distance (mm), tick time and
// wake-up latency (us), then index delay and bound per link, then delay (ms) and loss (%) per link.
nlohmann::json history_row(const nlohmann::json& f) {
  nlohmann::json row = {f["t"], f["force"][0], f["force"][1], f["force"][2], f["port_J"], f["controller_J"], f["vo_J"],
                        f["received_copy_distance_m"].get<double>() * 1e3, f["exec_max_us"], f["wake_max_us"]};
  for (const auto& l : f["links"]) row.push_back(l["index_delay"]), row.push_back(l["bound"]);
  for (const auto& l : f["links"]) row.push_back(l.value("delay_ms", 0.0)), row.push_back(100 * l.value("loss", 0.0));
  return row;
}

// Per-link delay and loss of a recording, from its packets (what the live page gets from the
// endpoint): a packet's age when the core got it, (tick - seq) T, averaged over the packets since
// the previous frame (a one-way delay to within a tick, both run indices counting from the common
// epoch), and the fraction of the neighbour's sequence numbers up to the newest one seen that never
// arrived (cumulative).
class LinkAges {
 public:
  LinkAges(const std::string& log, int neighbours) : seen_(static_cast<std::size_t>(neighbours)), newest_(static_cast<std::size_t>(neighbours), -1),
                                                      count_(static_cast<std::size_t>(neighbours), 0), last_delay_ms_(static_cast<std::size_t>(neighbours), 0.0) {
    h5::Id file = h5::open_file_read(log);
    period_s_ = h5::attr_f64(file.get(), "period_s");
    h5::Id g = h5::open_group(file.get(), "packets");
    tick_ = h5::read_i64(g.get(), "tick");
    seq_ = h5::read_i64(g.get(), "seq");
    nbr_ = h5::read_i64(g.get(), "neighbour");
  }
  // Adds delay_ms and loss to each of the frame's links from the packets used up to its tick.
  void annotate(nlohmann::json& frame) {
    const std::int64_t k = frame["k"].get<std::int64_t>();
    std::vector<double> age_sum(seen_.size(), 0.0);
    std::vector<int> n_age(seen_.size(), 0);
    for (; next_ < tick_.size() && tick_[next_] <= k; ++next_) {
      const auto n = static_cast<std::size_t>(nbr_[next_]);
      const std::int64_t q = seq_[next_];
      if (n >= seen_.size() || q < 0) continue;
      age_sum[n] += static_cast<double>(tick_[next_] - q);
      ++n_age[n];
      auto& seen = seen_[n];
      if (static_cast<std::size_t>(q) >= seen.size()) seen.resize(static_cast<std::size_t>(q) + 1, false);
      if (!seen[static_cast<std::size_t>(q)]) seen[static_cast<std::size_t>(q)] = true, ++count_[n];
      newest_[n] = std::max(newest_[n], q);
    }
    auto& links = frame["links"];
    for (std::size_t n = 0; n < links.size() && n < seen_.size(); ++n) {
      if (n_age[n] > 0) last_delay_ms_[n] = 1e3 * period_s_ * age_sum[n] / n_age[n];  // else the last one seen
      links[n]["delay_ms"] = last_delay_ms_[n];
      links[n]["loss"] = newest_[n] >= 0 ? 1.0 - static_cast<double>(count_[n]) / static_cast<double>(newest_[n] + 1) : 0.0;
    }
  }

 private:
  double period_s_ = 0;
  std::vector<std::int64_t> tick_, seq_, nbr_;
  std::vector<std::vector<bool>> seen_;
  std::vector<std::int64_t> newest_, count_;
  std::vector<double> last_delay_ms_;
  std::size_t next_ = 0;
};

// The other users' proxies in a recording, from their own logs of the same run: the files named
// station-<j>.h5 next to it with the same source, scene fingerprint and number of users (and, from
// the simulator, the same command line). Their run indices count from the run's common epoch, so
// the proxy shown with frame k is the newest one logged at or before k, if within 0.1 s.
class OtherProxies {
 public:
  explicit OtherProxies(const std::string& log) {
    h5::Id mine = h5::open_file_read(log);
    window_ticks_ = std::max<std::int64_t>(1, std::llround(0.1 / h5::attr_f64(mine.get(), "period_s")));
    const std::regex name(R"(station-([0-9]+)\.h5)");
    const std::filesystem::path own(log);
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(own.has_parent_path() ? own.parent_path() : ".", ec)) {
      if (!std::regex_match(e.path().filename().string(), name) || std::filesystem::equivalent(e.path(), own, ec)) continue;
      try {
        add(mine.get(), e.path().string());
      } catch (const std::exception& err) {
        std::cerr << "haptic-station: live view: not drawing the proxy of " << e.path().string() << ": " << err.what() << "\n";
      }
    }
    std::sort(users_.begin(), users_.end(), [](const User& a, const User& b) { return a.station < b.station; });
  }
  // The 1-based stations whose proxies come from their logs.
  std::vector<int> stations() const {
    std::vector<int> s;
    for (const auto& u : users_) s.push_back(u.station);
    return s;
  }
  // Adds "proxies": [{"station": j, "vp": [x, y, z]}] (m) of the users logged near the frame's tick.
  void annotate(nlohmann::json& frame) const {
    const std::int64_t k = frame["k"].get<std::int64_t>();
    nlohmann::json proxies = nlohmann::json::array();
    for (const auto& u : users_) {
      auto it = std::upper_bound(u.rows.begin(), u.rows.end(), k, [](std::int64_t key, const TickRecord& r) { return key < r.k; });
      if (it == u.rows.begin() || k - std::prev(it)->k > window_ticks_) continue;
      const auto& r = *std::prev(it);
      proxies.push_back({{"station", u.station}, {"vp", {r.vp[0], r.vp[1], r.vp[2]}}});
    }
    frame["proxies"] = std::move(proxies);
  }

 private:
  struct User {
    int station = 0;
    std::vector<TickRecord> rows;  // by k
  };
  void add(hid_t mine, const std::string& path) {
    h5::Id f = h5::open_file_read(path);
    for (const char* a : {"source", "fingerprint"})
      if (h5::attr_str(f.get(), a) != h5::attr_str(mine, a)) throw std::runtime_error(std::string("another run (its ") + a + " differs)");
    if (h5::attr_i64(f.get(), "users") != h5::attr_i64(mine, "users")) throw std::runtime_error("another run (its number of users differs)");
    if (h5::attr_str(mine, "source") == "sim" && h5::attr_str(f.get(), "config_text") != h5::attr_str(mine, "config_text"))
      throw std::runtime_error("another simulation (its command line differs)");
    User u{static_cast<int>(h5::attr_i64(f.get(), "station_id")), read_tick_records(f.get())};
    std::sort(u.rows.begin(), u.rows.end(), [](const TickRecord& a, const TickRecord& b) { return a.k < b.k; });
    if (u.station != static_cast<int>(h5::attr_i64(mine, "station_id"))) users_.push_back(std::move(u));
  }
  std::vector<User> users_;
  std::int64_t window_ticks_ = 1;
};

// Eq. (18)'s minimum B_i and whether it is met, as the station or the simulator recorded them.
void add_passivity(nlohmann::json& scene, const std::string& log) {
  h5::Id file = h5::open_file_read(log);
  if (!h5::has_attr(file.get(), "damping_min_Ns_per_m")) return;  // logs from builds that did not record it
  scene["damping_min_Ns_per_m"] = h5::attr_f64(file.get(), "damping_min_Ns_per_m");
  scene["passivity_condition_met"] = h5::attr_i64(file.get(), "passivity_condition_met") != 0;
}

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
  const OtherProxies others(log);
  if (!kept.empty()) {
    LinkAges ages(log, static_cast<int>(kept.front()["links"].size()));
    for (auto& f : kept) ages.annotate(f);
    LinkSince since;
    for (auto& f : kept) since.annotate(f);
    for (auto& f : kept) others.annotate(f);
  }
  const std::size_t stride = kept.size() / 4000 + 1;
  nlohmann::json history = nlohmann::json::array();
  for (std::size_t i = 0; i < kept.size(); i += stride) {
    kept[i]["index"] = player->frames.size();
    history.push_back(history_row(kept[i]));
    player->frames.push_back(kept[i].dump());
    player->times.push_back(kept[i]["t"].get<double>());
  }
  if (player->frames.empty()) throw std::runtime_error("live view: the log has no ticks to show");
  auto sc = nlohmann::json::parse(scene);
  sc["timeline_frames"] = player->frames.size();
  sc["history"] = std::move(history);
  add_passivity(sc, log);
  sc["proxies_from"] = {{"stations", others.stations()}, {"source", "their logs"},
                        {"missing", "no log of the same run next to " + std::filesystem::path(log).filename().string()}};
  sc["replay"] = r.summary();
  const std::string scene_text = sc.dump();
  ViewCallbacks cb;
  cb.scene = [scene_text] { return scene_text; };
  cb.next_frame = [player](std::string& out) { return player->next(out); };
  cb.on_message = [player](const std::string& m) { player->command(m); };
  ViewServer server(opt.server, cb);
  std::string others_text;
  for (int j : others.stations()) others_text += (others_text.empty() ? "" : ", ") + std::to_string(j);
  std::cerr << "haptic-station: live view of " << log << " at " << server.url() << " (" << player->frames.size() << " frames"
            << "; other users' proxies from their logs: " << (others_text.empty() ? "none" : "stations " + others_text)
            << (opt.serve_s > 0 ? ", for " + std::to_string(std::lround(opt.serve_s)) + " s" : ", until interrupted") << ")\n";
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
