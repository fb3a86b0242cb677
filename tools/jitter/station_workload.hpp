#pragma once
// The real station tick as a haptic-jitter workload (jitter.hpp): user 1 of the
// paper's scene (4 users, 33 nodes, 3 neighbours in the best topology), its neighbours' receive
// links fed one synthetic packet each per tick (the neighbours' copies at rest, index delay 3),
// the simulated user's device advanced by the commanded force. It lives with haptic-jitter (which
// links haptic_firmware), so nothing in firmware/ includes tools/ (DESIGN.md: dependencies point down).
// Construction builds and factors the scene (not RT-safe); tick() is RT-safe.
#include <string>
#include <vector>

#include "firmware/scenario.hpp"
#include "firmware/session/recorder.hpp"
#include "rt/station.hpp"
#include "rt/tick_driver.hpp"
#include "rt/user_model.hpp"
#include "tools/jitter/jitter.hpp"

namespace haptic::tools {

class StationJitterWorkload final : public JitterWorkload {
 public:
  explicit StationJitterWorkload(const std::string& scenario = "paper-best")
      : built_(firmware::build_scenario(firmware::make_scenario(scenario))),
        core_(built_.station_config(0)),
        user_(built_.spec.device, built_.spec.hand, built_.goal_script(0)),
        x0_(built_.scene.x_d.data(), built_.scene.x_d.data() + built_.scene.dofs),
        v0_(static_cast<std::size_t>(built_.scene.dofs), 0.0) {
    user_.reset(built_.vp_start[0]);
  }
  // One station tick (rt::drive_tick, as the station's run_tick drives it): one synthetic packet
  // per neighbour offered, the step at the nominal period, the device step; with recording on,
  // the session recorder's RT calls as run_tick makes them (every packet offered, then the tick
  // row). The tick index is the core's own next one, not info.index: that restarts with every
  // run_jitter() call while the core goes on (--record-blocks runs block after block). RT-safe.
  void tick(const platform::TickInfo&) override {
    const std::int64_t k = core_.sequence() + 1;
    const double T = built_.spec.period_s;
    const bool rec = recording_ && recorder_ != nullptr;
    const rt::TickDrive drive{k, 0, user_.position_m(), T};
    const auto out = rt::drive_tick(
        core_, drive,
        [&](auto&& offer) {
          for (int n = 0; n < core_.neighbor_count(); ++n)
            offer(rt::ReceivedState{n, k - 3, static_cast<double>(k - 3) * T, x0_.data(), v0_.data(), built_.scene.dofs});
        },
        firmware::RecordOffered{rec ? recorder_ : nullptr, k});
    if (rec) recorder_->rt_tick(firmware::make_tick_record(core_, k, drive.device_position_m, out, T));
    user_.advance(static_cast<double>(k) * T, T, out.device_force_N);
    flags_ |= out.flags;
  }
  std::string name() const override {
    return "station (" + built_.spec.name + ", user 1, " + std::to_string(built_.scene.nodes) + " nodes, 3 neighbours" +
           (recorder_ ? (recording_ ? ", recording on" : ", recording off") : "") + ")";
  }
  // The session recorder the tick feeds while recording is on (set before the RT thread starts;
  // set_recording between runs). Not RT-safe / RT-safe.
  void attach_recorder(firmware::SessionRecorder* recorder) { recorder_ = recorder; }
  void set_recording(bool on) { recording_ = on; }
  std::uint32_t flags_seen() const { return flags_; }
  const rt::StationCore& core() const { return core_; }

 private:
  firmware::BuiltScenario built_;
  rt::StationCore core_;
  rt::SimulatedUser user_;
  std::vector<double> x0_, v0_;
  std::uint32_t flags_ = 0;
  firmware::SessionRecorder* recorder_ = nullptr;
  bool recording_ = false;
};

}  // namespace haptic::tools
