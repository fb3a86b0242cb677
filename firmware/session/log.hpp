#pragma once
// Session log: one HDF5 file per station (readable with h5py) holding what
// its rt::StationCore ran with and every input it got, so `haptic-station replay LOG` can re-run
// the core bit for bit. Written by the real station (`run`, station.record = true) and by the
// simulator (`sim --record`), in the same layout:
//
//   /                attrs format = "haptic-session", version, source ("station" | "sim"),
//                    scenario, field_units, station_id (1-based), users, nodes, dofs, period_s, config_text (station
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
//   /ticks           one row per tick: kTickFields below (k, q, force, vp, energies, hash, flags, ...)
//   /packets         one row per packet offered to rx(n) before that tick: kPacketFields below
//   Every dataset carries the attributes `units` (SI: "N", "m", "m/s", "J", "s", "ns"; "1" for a
//   count, an index or a code) and `description`; /ticks/flags also `flag_bits`, one line per bit
//   "<bit> <name> <meaning>" (rt::kTickFlagNames). Logs written before these attributes (file
//   attribute field_units absent) have none; `haptic-station log info` says so.
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

// The columns of one row of a dataset: one value, x y z, or the scene's dofs (packet x and v).
enum class FieldCols { kScalar, kXyz, kDofs };

// One dataset of /ticks or /packets: the one definition of the rows of the log. The recorder
// creates its datasets from these tables (create_field: name, file type, columns, and the units
// and description as attributes); `haptic-station log` reads them back from the file.
struct LogField {
  const char* name;
  h5::Type type;  // the file type; a kDofs field is float32 or float64 as the log's packet_values
  FieldCols cols;
  const char* units;  // "1": a count, an index or a code
  const char* description;
};

inline constexpr const char* kTicksGroup = "ticks";
inline constexpr const char* kPacketsGroup = "packets";
inline constexpr const char* kUnitsAttr = "units";
inline constexpr const char* kDescriptionAttr = "description";
inline constexpr const char* kFlagBitsAttr = "flag_bits";
// File attribute: the log has units on its datasets (its value: the first program version that
// wrote them, for `log info` on older logs).
inline constexpr const char* kFieldUnitsAttr = "field_units";

enum TickField : std::size_t {
  kTickK, kTickQ, kTickForce, kTickVp, kTickPortJ, kTickControllerJ, kTickVoJ, kTickHash, kTickFlags, kTickContact,
  kTickWakeLatency, kTickExec, kTickDropped, kTickStep, kTickFieldCount
};
inline constexpr LogField kTickFields[kTickFieldCount] = {
    {"k", h5::Type::kI64, FieldCols::kScalar, "1", "run index of the tick (t = k T from the run's start)"},
    {"q", h5::Type::kF64, FieldCols::kXyz, "m", "device position sample the tick used"},
    {"force", h5::Type::kF64, FieldCols::kXyz, "N", "force commanded to the device"},
    {"vp", h5::Type::kF64, FieldCols::kXyz, "m", "virtual proxy position after the tick"},
    {"port_J", h5::Type::kF64, FieldCols::kScalar, "J", "energy into the VO through the contact port, cumulative (eq. 13)"},
    {"controller_J", h5::Type::kF64, FieldCols::kScalar, "J", "energy from the consensus control port, cumulative (eq. 14)"},
    {"vo_J", h5::Type::kF64, FieldCols::kScalar, "J", "energy of the virtual object at the start of the tick"},
    {"hash", h5::Type::kU64, FieldCols::kScalar, "1", "64-bit XXH3 hash of the core's state after the tick (replay compares it)"},
    {"flags", h5::Type::kU32, FieldCols::kScalar, "1", "status bits of the tick (rt::TickFlags; attribute flag_bits names them)"},
    {"contact", h5::Type::kU8, FieldCols::kScalar, "1", "1 while the virtual proxy touches the scene"},
    {"wake_latency_ns", h5::Type::kI32, FieldCols::kScalar, "ns", "how late the tick woke after its deadline (0 in a simulation)"},
    {"exec_ns", h5::Type::kI32, FieldCols::kScalar, "ns", "time the tick took on this host"},
    {"dropped", h5::Type::kU32, FieldCols::kScalar, "1", "records lost to a full recorder ring before this tick"},
    {"step_s", h5::Type::kF64, FieldCols::kScalar, "s", "step T_k handed to the core (0: the nominal period_s)"},
};
enum PacketField : std::size_t { kPacketTick, kPacketNeighbour, kPacketSeq, kPacketSendTime, kPacketX, kPacketV, kPacketFieldCount };
inline constexpr LogField kPacketFields[kPacketFieldCount] = {
    {"tick", h5::Type::kI64, FieldCols::kScalar, "1", "run index of the tick the packet was offered to"},
    {"neighbour", h5::Type::kI64, FieldCols::kScalar, "1", "index of the neighbour it came from (0-based, /core/neighbour_peer)"},
    {"seq", h5::Type::kI64, FieldCols::kScalar, "1", "the sender's run index of the state (its sequence number)"},
    {"send_time_s", h5::Type::kF64, FieldCols::kScalar, "s", "the sender's run time when it sent the state"},
    {"x", h5::Type::kF64, FieldCols::kDofs, "m", "the neighbour's VO node positions (x_hat, dofs)"},
    {"v", h5::Type::kF64, FieldCols::kDofs, "m/s", "the neighbour's VO node velocities (v_hat, dofs)"},
};

// The flag_bits attribute's text: one line per rt::kTickFlagNames entry, "<bit> <name> <meaning>".
std::string flag_bits_text();
// Sets a dataset's units and description attributes.
void set_units(hid_t dataset, const std::string& units, const std::string& description);
// Creates field f's appendable dataset in `group` (its kDofs columns: `dofs`, float32 when
// `float32`) with its units and description (and flag_bits for /ticks/flags). Not RT-safe.
h5::Appendable create_field(hid_t group, const LogField& f, std::uint64_t dofs, bool float32, std::uint64_t chunk_rows, int deflate_level,
                            std::uint64_t ring_rows);
// Writes /initial_state (x, v of `dofs` values each, with units). Not RT-safe.
void write_initial_state(hid_t file, const double* x, const double* v, std::uint64_t dofs);
// The run time (s) at the end of each tick row of a log, in the rows' (chronological) order:
// the first tick's nominal start k_0 T plus the recorded steps (step_s; 0 or absent: T; a gap in k,
// ticks not recorded, counts T each). As replay --trace's t_s when the core took the recorded steps.
std::vector<double> tick_end_times_s(const std::vector<std::int64_t>& k, const std::vector<double>& step_s, double period_s);

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
  std::string scenario;            // the scenario's name ("" : not written)
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
