#pragma once
// `haptic-station run`: one station of the paper's system as a real-time process, as a sequence
// of phases, each a small function returning a status (DESIGN.md, "The station process"):
//   plan    (station/plan.hpp)  pure: file -> scenario, epoch, peer table, link settings, fingerprint
//   open    (here)              the device, the transport + endpoint (its I/O thread), GPIO, telemetry
//   probe   (station/probe.hpp) k in [0, P): rest state every tick, round trips measured, fingerprints
//                               compared, clock offsets checked (station/neighbours.hpp)
//   rejoin  (station/rejoin.hpp) instead of probe when started after the probing phase: learn the
//                               session's epoch, round trips; after build adopt a neighbour's state
//   build   (station/probe.hpp) B_i from eq. (18) on the measured bounds, eq. (26), rt::StationCore
//   run     (station/tick.hpp)  k in [P+G, P+G+run): run_tick()
//   report  (station/report.hpp) station-<id>.json/-trace.csv/-state.csv, the exit code
// Probe, rejoin and run are stages of the station's one periodic loop (station/loop.hpp: one
// RtThread, one PeriodicLoop on the timeline's grid, from the first probing tick to the last run
// tick); build runs on the calling thread while the loop ticks the set-up gap.
// Times are on CLOCK_MONOTONIC; k is the tick index since the common epoch, the same on every
// station, so N_ij^k = k - seq is meaningful across processes.
#include <atomic>
#include <iosfwd>

#include "firmware/station/config.hpp"
#include "firmware/station/loop.hpp"
#include "firmware/station/phase.hpp"
#include "firmware/station/plan.hpp"
#include "firmware/station/probe.hpp"
#include "firmware/station/report.hpp"
#include "firmware/station/tick.hpp"

namespace haptic::firmware {

// `run --check-config`: the plan phase alone, without opening a socket or creating a file.
// Prints a one-line summary (and the plan's warnings) on `out`, or the error on `err`.
// Returns kExitOk or kExitConfigError. Not RT-safe.
int check_station_config(const StationFile& file, const RunOverrides& overrides, std::ostream& out, std::ostream& err);

// Runs one station through every phase; returns the process exit code (station/phase.hpp).
// `stop` is set by the signal handler. Not RT-safe (owns the RT thread).
int run_station(const StationFile& file, const RunOverrides& overrides, std::atomic<bool>& stop);

}  // namespace haptic::firmware
