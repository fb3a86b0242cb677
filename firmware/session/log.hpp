#pragma once
// Session log: one HDF5 file per station (readable with h5py) holding what
// its rt::StationCore ran with and every input it got, so `haptic-station replay LOG` can re-run
// the core bit for bit. Written by the real station (`run`, station.record = true) and by the
// simulator (`sim --record`), in the same layout:
//
//   /                attrs format = "haptic-session", version, source ("station" | "sim"),
//                    station_id (1-based), users, nodes, dofs, period_s, config_text (station
//                    file or sim command line), fingerprint, packet_values ("float32" | "float64"),
//                    damping_min_Ns_per_m and passivity_condition_met (eq. 18; the view's status),
//                    build_id (the writing program's GNU build ID),
//                    and at close: ticks, packets, dropped_records, dropped_ticks, truncated_at_tick,
//                    lossy_packet_values, bytes_limit, ring_ticks (0: the whole run), first_tick (the
//                    oldest tick row; > 0 only for a ring that wrapped), packets_complete_from_tick
//                    (the oldest tick all of whose packets are in the log)
//   /core            the core's configuration (rt::StationConfig: gains, B_i, bounds, VP, contact
//                    mesh, solver), /core/scene (mesh, M, B, K_int, K, x_d as CSR arrays),
//                    /core/gains/<e>/{P,D}: the exact matrices, so replay does not rebuild the scenario
//   /initial_state   x, v of the core before its first tick (a rejoining station's adopted state)
//   /ticks           one row per tick: k (run index), q (device sample used, 3), force (3), vp (3),
//                    port_J, controller_J, vo_J, hash (uint64, state_hash), flags, contact,
//                    wake_latency_ns, exec_ns, dropped (records this tick lost to a full ring),
//                    step_s (the step T_k handed to the core: the station's measured wake-to-wake
//                    period, the simulator's clock model; version 2, absent in version 1 = nominal)
//   /packets         one row per packet offered to rx(n) before that tick: tick, neighbour
//                    (index), seq (run index), send_time_s, x (dofs), v (dofs)
//   A ring log (station.record_ring_s, sim --record-ring-s): /ticks and /packets are rings of
//   fixed row counts; their attribute ring_next_row is the row of the oldest entry
//   (chronological order: numpy.roll(a, -ring_next_row, axis=0)). A wrapped ring is for
//   inspection; replay refuses it (no core state at first_tick).
//
// Packets are stored as float32 when the wire is float32 (lossless: the values are floats; the
// writer counts any that are not in lossy_packet_values), else float64.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "firmware/session/h5.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

inline constexpr std::int64_t kSessionLogVersion = 2;  // 2: /ticks/step_s (version 1 logs are read, steps nominal)

// 64-bit hash (XXH3) of the core's state after a tick: x, v, VP position, the tick's device
// force, the five energies and the flags. Two runs whose hashes agree at every tick computed the
// same doubles. RT-safe (no allocation).
std::uint64_t state_hash(const rt::StationCore& core, const rt::StationCore::TickOutput& out);

// One row of /ticks (flat; what the RT side hands to the recorder).
struct TickRecord {
  std::int64_t k = 0;
  double q[3] = {0, 0, 0}, force[3] = {0, 0, 0}, vp[3] = {0, 0, 0};
  double port_J = 0, controller_J = 0, vo_J = 0;
  std::uint64_t hash = 0;
  std::uint32_t flags = 0;
  std::int32_t wake_latency_ns = 0, exec_ns = 0;
  std::uint32_t dropped = 0;  // filled by the recorder
  std::uint8_t contact = 0;
  double step_s = 0;          // T_k given to core.tick (0: the nominal step, tick(k, q))
};
// The row for the tick the core just ran at run index kr with device sample q and step step_s
// (as given to tick(); 0: tick(k, q), the nominal step). RT-safe.
TickRecord make_tick_record(const rt::StationCore& core, std::int64_t kr, const rt::Vec3& q, const rt::StationCore::TickOutput& out,
                            double step_s);

// What the file says about where it came from.
struct SessionInfo {
  std::string source = "station";  // "station" | "sim"
  int station_id = 1;              // 1-based
  std::string config_text;         // the station file, or the sim command line
  std::string fingerprint;         // the scene fingerprint, human-readable
  bool packets_float32 = false;    // the wire carries float32 values
  double damping_min_Ns_per_m = -1;  // eq. (18)'s minimum B_i for this station (-1: not known)
  bool passivity_condition_met = false;  // B_i >= that minimum (eq. 18)
};

// The core's configuration with the scene and gains it points to, owned (read back from a log,
// or copied for tests). Not movable: config points into scene and gains.
struct CoreSetup {
  rt::Scene scene;
  std::vector<rt::EdgeGains> gains;
  rt::StationConfig config;
  CoreSetup() = default;
  CoreSetup(const CoreSetup&) = delete;
  CoreSetup& operator=(const CoreSetup&) = delete;
};

// The running program's GNU build ID (hex; "" when it has none): which binary wrote a log. A log
// replays bit-exactly with a build whose core does the same arithmetic; a different build ID is the
// first thing to check when it does not. Not RT-safe.
std::string program_build_id();

// Writes the header (attributes + /core) of a new log. Not RT-safe.
void write_session_header(hid_t file, const SessionInfo& info, const rt::StationConfig& core);
// Reads /core back. Throws std::runtime_error naming what is missing.
std::unique_ptr<CoreSetup> read_core_setup(hid_t file);

}  // namespace haptic::firmware
