#pragma once
// Rejoin: a station started after its session's probing phase (a restart after a crash or
// SIGKILL; StationTimes::rejoin) joins the running session instead of probing from k = 0
// (DESIGN.md "The station process"). Its new incarnation (net/) makes its
// neighbours accept it afresh. In order, on the calling (non-RT) thread, before the RT thread:
//   1. rejoin_stage(): for station.rejoin_probe_s it sends its rest state every period (a stage of
//      the station's loop, loop.hpp, on a timeline of its own) with provisional sequence numbers 0, 1, ...
//      below the session's run_k0 (the neighbours' ticks ignore them, their endpoints echo them), measures the round trips from its own send records
//      and the clock offset to each neighbour, and learns the session's epoch from the neighbours'
//      packets: epoch = min(send stamp - seq T) - clock offset, from the neighbour whose clock
//      offset is the most certain (smallest round trip) -- not from its own start time.
//   2. build (station/probe.hpp) on those round trips.
//   3. adopt_neighbour_state(): the newest neighbour packet's x_hat, v_hat become the core's
//      x, v (rt::StationCore::set_state), so nobody feels a jolt when it couples;
//   4. only then the run stage, the loop moved onto the session's tick grid, from the current k on.
// Not RT-safe.
#include <atomic>
#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "firmware/station/loop.hpp"
#include "firmware/station/neighbours.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/probe.hpp"
#include "net/endpoint.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

struct RejoinResult {
  ProbeResult probe;                  // status, round-trip bounds, statistics, grid, clock check
  std::int64_t epoch_ns = 0;          // the session's epoch learned from the neighbours (our CLOCK_MONOTONIC)
  double epoch_shift_s = 0;           // learned - planned epoch (0 when both agree)
  double epoch_uncertainty_s = 0;     // half the round trip of the clock-offset sample used
  int epoch_from_station = 0;         // whose packets gave it
  std::uint64_t provisional_pushes = 0;
};
// Step 1 as a stage of the station's loop, into r (which must outlive the loop): a timeline of its
// own, tick 0 one period after now_ns (the session's epoch is not known yet).
LoopStage rejoin_stage(const StationPlan& plan, net::Endpoint& ep, RejoinResult& r, std::int64_t now_ns);
// After that stage ended: round trips, the session's epoch, the clock check (r.probe.status).
void end_rejoin_probe(const StationPlan& plan, net::Endpoint& ep, const std::atomic<bool>& stop, const StageOutcome& o, RejoinResult& r);

struct AdoptedState {
  bool ok = false;
  int from_station = 0;     // whose state was adopted
  std::uint64_t seq = 0;    // of the packet adopted (the neighbour's tick index)
  std::string message;      // why not
};
// Drains the endpoint for up to wait_s (the caller must be its only consumer: before the RT
// thread starts) and sets the core's state to the newest neighbour state packet of the running
// session (seq >= run_k0). Not RT-safe.
AdoptedState adopt_neighbour_state(const StationPlan& plan, net::Endpoint& ep, rt::StationCore& core, double wait_s);

// The same at the rejoined station's first run tick, on the RT thread (the RT thread's set-up
// takes ~0.1 s after the adoption above): drains the RX ring and, if a newer neighbour state
// arrived, takes it over into the preallocated x, v (dofs each) and the core. RT-safe (no
// allocation, no wait); the drained packets are not offered to the receive links, so the first
// tick couples to nobody.
void refresh_adopted_state(const StationPlan& plan, net::Endpoint& ep, rt::StationCore& core, Eigen::VectorXd& x, Eigen::VectorXd& v,
                           AdoptedState& adopted);

}  // namespace haptic::firmware
