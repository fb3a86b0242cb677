#pragma once
// What the live web view shows of one station, as a fixed-size record the RT
// tick fills in place every few ticks and hands over through a latest-value mailbox
// (platform/latest_mailbox.hpp): the tick never waits, an unread frame is replaced (counted by the
// reader from the sequence numbers). The non-RT side turns frames into JSON for the browser.
#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "platform/latest_mailbox.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

inline constexpr int kViewMaxNodes = 4096;           // larger scenes show their first 4096 nodes
inline constexpr int kViewMaxCopies = 4;             // neighbours' copies shown (scenes up to kViewCopyNodes)
inline constexpr int kViewCopyNodes = 512;

struct ViewFrame {
  std::uint64_t seq = 0;        // frames published so far (gaps: frames the reader missed)
  std::int64_t k = 0;           // run tick
  double t_s = 0;
  int nodes = 0;
  float x[3 * kViewMaxNodes] = {};  // this station's copy x(k)
  int neighbours = 0;
  int peer[rt::kMaxNeighbors] = {};                 // 0-based station index of neighbour n
  std::int64_t index_delay[rt::kMaxNeighbors] = {}; // N_ij^k = k - newest sequence held
  std::int64_t bound[rt::kMaxNeighbors] = {};       // Nbar_ij (the core's index-delay guard)
  int copies = 0;                                   // neighbours' copies included (0 for large scenes)
  float copy_x[kViewMaxCopies][3 * kViewCopyNodes] = {};  // their last received x_hat_j
  double vp[3] = {}, device[3] = {}, force[3] = {};
  double port_J = 0, controller_J = 0, vo_J = 0;
  // max over neighbours and nodes of |x_p - x_hat_j,p| (last received copies; model::max_node_distance_m):
  // not the run's consensus error, which compares all copies at one instant
  double received_copy_distance_m = 0;
  std::int32_t exec_max_ns = 0, wake_max_ns = 0;  // largest tick time / wake-up latency since the last frame
  // This host since the last frame: ticks run, periods the loop skipped, and the period (for the
  // starving-host rule, platform::host_starving, with the largest wake-up as the P99 of so few)
  std::uint32_t window_ticks = 0, window_missed_cycles = 0;
  std::int64_t period_ns = 0;
  // The run loop's totals so far (platform::TickInfo): overruns and skipped periods since the start
  std::uint64_t overruns = 0, missed_cycles = 0;
  std::uint32_t flags = 0;       // TickFlags or-ed since the last frame
  // What the per-edge energy gate and the edge-drop rule did so far (firmware/run_summary.hpp
  // GateSummary): trips, the energy the gate removed, drop events, and the worst port energy.
  std::uint64_t gate_trips = 0, edge_drops = 0;
  double gate_removed_J = 0, port_min_J = 0;
  bool in_contact = false;
};

// The RT side's hand-off: fill the mailbox's slot every `every` ticks. Allocation-free.
class ViewPublisher {
 public:
  explicit ViewPublisher(int every_ticks) : every_(every_ticks < 1 ? 1 : every_ticks) {}
  // After the core's tick kr: accumulates the tick's timing and flags, every `every` ticks fills
  // and publishes a frame. RT-safe.
  void on_tick(const rt::StationCore& core, std::int64_t kr, double period_s, const rt::Vec3& q, const rt::Vec3& force, std::uint32_t flags,
               std::int64_t exec_ns, std::int64_t wake_ns);
  // Before on_tick: the run loop's skipped periods so far (platform::TickInfo::missed_cycles). RT-safe.
  void note_missed_cycles(std::uint64_t total) {
    if (have_missed_ && total > missed_total_) missed_ += static_cast<std::uint32_t>(total - missed_total_);
    missed_total_ = total;
    have_missed_ = true;
  }
  // Before on_tick: the run loop's overruns so far (platform::TickInfo::overruns). RT-safe.
  void note_overruns(std::uint64_t total) { overruns_total_ = total; }
  // Reader side (one non-RT thread): the newest frame, if a new one was published.
  bool take(ViewFrame& out) { return box_.reader_take(out); }
  int every() const { return every_; }

 private:
  platform::LatestMailbox<ViewFrame> box_;
  int every_;
  std::uint64_t seq_ = 0;
  std::int32_t exec_max_ = 0, wake_max_ = 0;
  std::uint32_t flags_ = 0;
  double port_min_J_ = 0;  // over every tick, not only the published ones
  std::uint32_t ticks_ = 0, missed_ = 0;  // since the last frame
  std::uint64_t missed_total_ = 0, overruns_total_ = 0;
  bool have_missed_ = false;
};

// The scene message (sent once per browser): rest positions, surface triangles, contact mesh,
// station and neighbours. Not RT-safe.
nlohmann::json view_scene_json(const rt::StationCore& core, int station_id, const std::string& mode);
// A frame as JSON (positions in micrometres as integers). Not RT-safe.
nlohmann::json view_frame_json(const ViewFrame& f);

// Each link's "since_s" in frames given in run order: the run time its state (links[].up where
// the endpoint says, else within its bound) last changed, or the first frame's time it was seen
// in, so that a page opened late says since when, not since it was opened. Not RT-safe.
class LinkSince {
 public:
  void annotate(nlohmann::json& frame);

 private:
  std::map<int, std::pair<bool, double>> state_;  // peer -> (up, since_s)
};

}  // namespace haptic::firmware
