#include "firmware/station/rejoin.hpp"

#include <time.h>

#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>


namespace haptic::firmware {

namespace {


// Step 1's result: the session epoch from the neighbour with the most certain clock offset.
bool learn_epoch(const StationPlan& plan, RejoinResult& r) {
  const auto& nbrs = plan.neighbours();
  double best_unc = INFINITY;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = r.probe.stats_at_end.peers[static_cast<std::size_t>(plan.peers.nbr_to_peer[n])];
    const double e = r.probe.grid.epoch_own_clock_s[n];
    if (p.clock_offset_samples == 0 || !std::isfinite(e) || r.probe.grid.newest_seq[n] < static_cast<double>(plan.times.run_k0)) continue;
    const double unc = p.clock_offset_rtt_s / 2.0;
    if (unc >= best_unc) continue;
    best_unc = unc;
    r.epoch_ns = std::llround((e - p.clock_offset_s) * 1e9);
    r.epoch_from_station = nbrs[n] + 1;
  }
  if (!std::isfinite(best_unc)) return false;
  r.epoch_uncertainty_s = best_unc;
  r.epoch_shift_s = static_cast<double>(r.epoch_ns - plan.times.epoch_ns) * 1e-9;
  return true;
}

}  // namespace

LoopStage rejoin_stage(const StationPlan& plan, net::Endpoint& ep, RejoinResult& r, std::int64_t now_ns) {
  r.probe.grid = NeighbourGrid(plan.neighbours().size());
  const BuiltScenario& b = *plan.built;
  const std::int64_t pace = send_interval_ticks(b.spec);  // the running neighbours' pace, and ours
  r.probe.loss_counter = ProbeLossCounter(plan.neighbours().size(), pace);
  const std::vector<double> x0(b.scene.x_d.data(), b.scene.x_d.data() + b.scene.dofs), v0(x0.size(), 0.0);  // the rest state
  const double T = b.spec.period_s;
  LoopStage s;
  s.timeline.period_ns = plan.times.period_ns;
  s.timeline.epoch_ns = now_ns + plan.times.period_ns;
  s.timeline.probe_ticks = rejoin_probe_ticks(plan.file.station.rejoin_probe_s, T);
  s.timeline.run_k0 = std::numeric_limits<std::int64_t>::max() / 4;  // no run on this timeline: set-up ticks until the session's stage
  s.last_phase = TickPhase::kProbe;
  s.k_first = 0;
  s.new_grid = true;
  s.tick = [&plan, &ep, &r, x0, v0, T, pace = rt::SendInterval(pace)](std::int64_t k, const platform::TickInfo&) mutable {
    ep.drain([&](std::uint16_t sender, std::uint64_t seq, double send_time_s, const double*, const double*, std::uint32_t) {
      r.probe.grid.add(plan.peers.sender_to_nbr[sender], seq, send_time_s, T);
      r.probe.loss_counter.add(plan.peers.sender_to_nbr[sender], seq);
    });
    // Provisional sequence numbers stay below the session's run_k0: the neighbours' ticks ignore them.
    // At the running session's pace (send_interval_ticks).
    if (static_cast<std::int64_t>(r.provisional_pushes) < plan.times.run_k0 - 1 && pace.take(k) &&
        ep.push_state(r.provisional_pushes, net::monotonic_s(), x0.data(), v0.data()))
      ++r.provisional_pushes;
    return true;
  };
  return s;
}

void end_rejoin_probe(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop, const StageOutcome& o, RejoinResult& r) {
  r.probe.loop_ticks = o.counts.ticks;
  r.probe.loop_overruns = o.counts.overruns;
  r.probe.loop_missed_cycles = o.counts.missed_cycles;
  if (stop.load(std::memory_order_acquire) || !o.ended) {
    r.probe.status = stop.load(std::memory_order_acquire) ? PhaseStatus::kStopped : PhaseStatus::kFailed;
    r.probe.message = stop.load(std::memory_order_acquire) ? "stopped by a signal while rejoining" : "the station loop ended while rejoining";
    return;
  }
  const bool all = ep.finish_probing();
  // Our allowance from the loss of the running neighbours' packets; theirs arrives in their
  // fingerprints (their cores were built before we came: they keep their own, agreement_ticks covers it).
  fix_loss_allowances(plan, ep, r.probe);
  fix_step_bounds(plan, ep, r.probe, false);  // the nominal step: inside the bounds the neighbours took for our earlier incarnation
  collect_probe_result(plan, ep, all, "station.rejoin_probe_s = " + std::to_string(plan.file.station.rejoin_probe_s) + " s", r.probe);
  if (r.probe.status != PhaseStatus::kOk) return;
  if (!learn_epoch(plan, r)) {
    r.probe.status = PhaseStatus::kNoNeighbour;
    r.probe.message = "rejoin: no neighbour is running the session (no packet with a sequence number >= the run start " +
                      std::to_string(plan.times.run_k0) + " and an echo), so there is no session to rejoin";
    return;
  }
  // The tick-grid check against the learned epoch (the planned one may be far off).
  check_clock(plan, r.epoch_ns, r.probe);
}

AdoptedState adopt_neighbour_state(const StationPlan& plan, net::Endpoint& ep, rt::StationCore& core, double wait_s) {
  AdoptedState a;
  const int dofs = plan.built->scene.dofs;
  Eigen::VectorXd x(dofs), v(dofs);
  const std::int64_t until = net::monotonic_ns() + static_cast<std::int64_t>(wait_s * 1e9);
  // Everything waiting (the newest of it), or, if none of the session yet, wait up to wait_s for one.
  for (;;) {
    ep.drain([&](std::uint16_t sender, std::uint64_t seq, double, const double* xh, const double* vh, std::uint32_t count) {
      const int n = plan.peers.sender_to_nbr[sender];
      if (n < 0 || static_cast<std::int64_t>(seq) < plan.times.run_k0 || static_cast<int>(count) != dofs) return;
      if (a.ok && seq <= a.seq) return;
      a.ok = true;
      a.seq = seq;
      a.from_station = plan.neighbours()[static_cast<std::size_t>(n)] + 1;
      x = Eigen::Map<const Eigen::VectorXd>(xh, dofs);
      v = Eigen::Map<const Eigen::VectorXd>(vh, dofs);
    });
    if (a.ok || net::monotonic_ns() >= until) break;
    ep.wait_rx(0.01);
  }
  if (!a.ok) {
    a.message = "rejoin: no state packet of the running session arrived to take over";
    return a;
  }
  core.set_state(x, v);
  return a;
}

}  // namespace haptic::firmware

namespace haptic::firmware {

void refresh_adopted_state(const StationPlan& plan, net::Endpoint& ep, rt::StationCore& core, Eigen::VectorXd& x, Eigen::VectorXd& v,
                           AdoptedState& a) {
  const int dofs = static_cast<int>(x.size());
  bool newer = false;
  ep.drain([&](std::uint16_t sender, std::uint64_t seq, double, const double* xh, const double* vh, std::uint32_t count) {
    const int n = plan.peers.sender_to_nbr[sender];
    if (n < 0 || seq <= a.seq || static_cast<int>(count) != dofs) return;
    a.seq = seq;
    a.from_station = plan.neighbours()[static_cast<std::size_t>(n)] + 1;
    x = Eigen::Map<const Eigen::VectorXd>(xh, dofs);  // same size: no allocation
    v = Eigen::Map<const Eigen::VectorXd>(vh, dofs);
    newer = true;
  });
  if (newer) core.set_state(x, v);
}

}  // namespace haptic::firmware
