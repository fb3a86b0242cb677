#pragma once
// `haptic-station run`: one station of the paper's system as a real-time process.
//
// Life of a run (times on CLOCK_MONOTONIC, k = tick index since the common epoch, the same on
// every station, so N_ij^k = k - seq is meaningful across processes):
//   start-up     parse the file, build the scenario (firmware/scenario.hpp, the simulator's),
//                open the device, open the transport, start the endpoint's I/O thread
//   k in [0, P)  probing: send the rest state, zero coupling; the endpoint measures round trips
//   k in [P, P+G) gap: keep sending the rest state; the non-RT thread finishes probing, sets
//                B_i from eq. (18) with the MEASURED bounds and builds rt::StationCore
//   k >= P+G     run: the tick of DESIGN.md (device read, RX drain, tick, force, push_state,
//                records), until duration_s, SIGINT/SIGTERM or a fatal start-up problem
//   end          write station-<id>.json, station-<id>-trace.csv, station-<id>-state.csv
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/device.hpp"
#include "drivers/simulated_device.hpp"
#include "firmware/scenario.hpp"
#include "firmware/station_config.hpp"
#include "net/endpoint.hpp"
#include "platform/gpio.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/telemetry.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

struct RunOverrides {
  double start_at = -1;      // --start-at (s on station.start_clock), < 0: from the file
  std::string out_dir;       // --out, "": from the file
  double duration_s = -1;    // --duration, < 0: from the file
  bool quiet = false;
};

// Applies the file's [station] keys to the scenario (start-up; throws naming the key).
ScenarioSpec station_scenario_spec(const StationFile& file, const RunOverrides& overrides);

// The per-neighbour bounds a station derives from its measured round trips (start-up).
struct MeasuredBounds {
  std::vector<int> round_trip_ticks;    // R_ij = measured bound (+ margin, net/) + loss allowance: Nbar_ij + Nbar_ji in eq. (18)
  std::vector<int> index_guard_ticks;   // Nbar_ij = ceil(R_ij / 2): the rt core drops data older than this
  std::vector<int> assumed_sum_ticks;   // Nbar_ij + Nbar_ji put into eq. (18): 2 Nbar_ij + agreement_ticks
                                        // (covers the peer's guard ceil(R_ji/2) while R_ji <= R_ij + 2 agreement_ticks)
  double damping_min_Ns_per_m = 0;      // eq. (18) with R_ij
  double damping_Ns_per_m = 0;          // B_i used
};
// eq. (18) for user `user` of `b` from measured endpoint bounds (ticks, one per neighbour).
MeasuredBounds bounds_from_round_trips(const BuiltScenario& b, int user, const std::vector<std::uint32_t>& rtt_bound_ticks,
                                       int loss_allowance_ticks, double damping_margin, double damping_override,
                                       int agreement_ticks = 2);

// One row of station-<id>-trace.csv (flat, preallocated).
struct TraceRec {
  std::int64_t k;
  double node[3], force[3], vp[3], device[3];
  double port_J, ctrl_J, vo_J, max_speed;
  std::uint32_t flags;
  std::int32_t wake_latency_ns;
  std::uint8_t contact;
};

// Everything one run tick touches: pointers to objects built at start-up, preallocated records
// and counters. Filled by run_station() (or a test) before the loop starts.
struct RunTick {
  rt::StationCore* core = nullptr;
  net::Endpoint* ep = nullptr;
  drivers::HapticDevice* device = nullptr;
  drivers::SimulatedDevice* simulated = nullptr;   // non-null: owner-stepped, service() per tick
  platform::GpioToggler* gpio = nullptr;
  platform::Telemetry* telemetry = nullptr;        // may be null
  const int* sender_to_nbr = nullptr;              // [65536]: wire sender id -> neighbour index, -1 = none
  int dofs = 0, trace_node = 0, trace_every = 1, state_every = 1;
  double T = 0.002;
  std::int64_t run_k0 = 0;                         // epoch tick of the run start (earlier seqs are probes)
  TraceRec* trace = nullptr;
  std::size_t trace_cap = 0, trace_n = 0;
  std::int64_t* state_k = nullptr;
  double* state_x = nullptr;                       // state_cap x dofs
  std::size_t state_cap = 0, state_n = 0;
  std::uint64_t foreign_packets = 0, probe_packets_after_run = 0, rx_offered = 0, push_failures = 0, device_fault_ticks = 0;
  std::int64_t ticks_run = 0;
  bool diverged = false;
  double diverged_at_s = -1, port_min = 0, max_speed = 0;
};

// One run tick at epoch index k (run index kr = k - run_k0), in the order of DESIGN.md: GPIO
// high, newest device sample, drain RX into rx(n).offer (sequence numbers translated to the
// core's k, minus the cycles skipped by overruns), tick, command force (+ service() of a
// simulated device), push_state(k, t, x_hat, v_hat), monitor, records, telemetry, GPIO low.
// RT-safe: no allocation, lock or blocking call (tests/station checks it with the allocation counter).
void run_tick(RunTick& c, std::int64_t k, std::int64_t kr, const platform::TickInfo& info);

// Runs one station to the end; returns the process exit code (0 ok, 2 configuration, 3 run-time
// failure). `stop` is set by the signal handler. Not RT-safe (owns the RT thread).
int run_station(const StationFile& file, const RunOverrides& overrides, std::atomic<bool>& stop);

}  // namespace haptic::firmware
