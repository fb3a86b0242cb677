#pragma once
// One run tick of `haptic-station run` (DESIGN.md, "One tick of station i") and what it
// touches, split by lifetime: TickInputs (built at start-up, read by the tick), TickRecords
// (station/records.hpp: the windows of rows the tick fills), TickCounters (what the tick counts; read by the report
// after the loop ended).
#include <cstdint>
#include <vector>

#include "drivers/device.hpp"
#include "drivers/workspace_map.hpp"
#include "drivers/simulated_device.hpp"
#include "firmware/session/recorder.hpp"
#include "firmware/station/edge_events.hpp"
#include "firmware/station/records.hpp"
#include "firmware/station/outage.hpp"
#include "firmware/view/frame.hpp"
#include "net/endpoint.hpp"
#include "platform/gpio.hpp"
#include "platform/periodic_loop.hpp"
#include "platform/telemetry.hpp"
#include "rt/station.hpp"
#include "rt/tx_deadband.hpp"
#include "firmware/run/summary.hpp"

namespace haptic::firmware {

// Built at start-up; the tick only reads these (the objects pointed to are the tick's to use).
struct TickInputs {
  rt::StationCore* core = nullptr;
  rt::TxDeadband* tx_deadband = nullptr;  // null: send every tick
  net::Endpoint* ep = nullptr;
  drivers::HapticDevice* device = nullptr;
  drivers::SimulatedDevice* simulated = nullptr;  // non-null: owner-stepped, service() per tick
  platform::GpioToggler* gpio = nullptr;          // may be null
  platform::Telemetry* telemetry = nullptr;       // may be null
  SessionRecorder* recorder = nullptr;            // may be null: the session log (station.record)
  ViewPublisher* view = nullptr;                  // may be null: the live web view's frames (station.view_port)
  const int* sender_to_nbr = nullptr;             // [65536]: wire sender id -> neighbour index, -1 = none
  int dofs = 0, trace_node = 0, trace_every = 1, state_every = 1;
  double period_s = 0.002;
  std::int64_t run_k0 = 0;  // epoch tick of the run start: earlier sequence numbers are probes
  // Per neighbour index: the echo-based age bound a packet may have (net/README.md, "Age guard":
  // (R_ij + station.age_slack_ticks) T); a packet beyond it, or with no echo of one of our own
  // sends, is not handed to the core (counted). Null: no age guard.
  const double* max_age_s = nullptr;
  // Per neighbour index: added to its sequence numbers to put them on our tick grid (the grid
  // offset measured while probing, station/neighbours.hpp ClockCheck::shift_ticks). Null: none.
  const std::int64_t* seq_shift_ticks = nullptr;
  const drivers::WorkspaceMap* map = nullptr;  // device -> object frame; null = identity
  std::int64_t ramp_ticks = 0;                 // force ramp-in over this many coupled ticks (0 = none)
  EdgeEventWatch* edge_events = nullptr;       // may be null: the edges' safeguard events for the log (edge_events.hpp)
};

// Counted by the tick; read by the non-RT side after the loop ended.
struct TickCounters {
  std::uint64_t foreign_packets = 0, probe_packets_after_run = 0, rx_offered = 0, push_failures = 0, device_fault_ticks = 0;
  std::uint64_t no_neighbour_ticks = 0;  // ticks with every neighbour's data beyond its index-delay bound
  std::uint64_t age_over_bound = 0, no_echo = 0;  // packets refused by the age guard (TickInputs::max_age_s)
  std::uint64_t outside_workspace_ticks = 0;  // device samples beyond its workspace radius (clamped onto it)
  std::uint64_t contact_ticks = 0;            // ticks with the proxy in contact with the object
  double device_force_max_N = 0;              // largest |force| told to the device (object frame, ramp-in applied)
  std::int64_t ticks_run = 0;
  std::int64_t last_wake_ns = 0;  // the previous tick's wake (the measured step T_k = wake - this)
  bool diverged = false;
  double diverged_at_s = -1, port_min_J = 0, max_speed_m_per_s = 0;
  OutageTracker outages;  // spans without a usable neighbour and the host's stalls, for the report's explanation
};

// The tick's receive stage: drains the endpoint's RX ring into the receive links. The endpoint has
// judged each packet (authentic, from its address, in sequence range, finite, in the envelope, the
// scene's size); here only what the tick alone knows: probing's packets left in the ring (counted,
// dropped), the age guard (a run packet that echoes none of our sends, or whose echo-based age bound
// now exceeds the neighbour's max_age_s, counted and dropped), then the link's tick rules
// (rt::RxLink::take: stale and duplicate counted there). Each packet is counted once. Sequence
// numbers become run indices (seq - run_k0); with a recorder every taken packet is recorded. RT-safe.
void receive_packets(const TickInputs& in, TickCounters& cnt, std::int64_t kr);

// Whether any neighbour's newest data is within its index-delay bound at run tick kr (the core
// couples to it). RT-safe.
bool any_neighbour_within_bound(rt::StationCore& core, std::int64_t kr);

// The force sent to the device for the core's object-frame force F at this tick: the ramp-in
// factor of the cnt.ticks_run-th coupled tick times F, mapped back to the device frame
// (scale R^T F). RT-safe.
void device_force_out(const TickInputs& in, const TickCounters& cnt, const rt::Vec3& force_object_N, double device_force_N[3]);

// The newest device sample mapped into the object frame (NaN when the device has none: the core's
// safe state for the tick); counts device-fault and outside-workspace ticks. RT-safe.
rt::Vec3 read_device(const TickInputs& in, TickCounters& cnt);

// A test seam, not an option: a test executable that links the station library (never the shipped
// station) may install a rewrite of the state the tick sends, to play an authenticated insider that
// lies (tests/firmware/station/insider_main.cpp). It gets the core and the run index and returns the
// x_hat and v_hat to send (dofs values each, its own buffers; a null one: the core's). Set before the
// run; RT-safe callers only.
struct OutgoingState {
  const double* x_hat = nullptr;
  const double* v_hat = nullptr;
};
using OutgoingStateRewrite = OutgoingState (*)(const rt::StationCore& core, std::int64_t kr);
void set_outgoing_state_rewrite(OutgoingStateRewrite rewrite);

// One run tick at epoch index k, run index kr = k - run_k0 (the index the core and the receive
// links use, so a packet's sequence number seq becomes seq - run_k0 and nothing else). In the order
// of DESIGN.md: GPIO high, newest device sample (none: NaN, the core's safe state for the tick),
// drain RX and step the core (rt::drive_tick: each packet offered at seq - run_k0, then
// core.tick(kr, q, T_k)), command force (+ service() of a simulated device),
// push_state(k, t, x_hat, v_hat), monitor, records, telemetry, GPIO low. With a recorder, the
// first tick hands it the core's initial state, every offered packet is recorded with kr, and
// every tick its row (device sample, force, flags, state hash; firmware/session/log.hpp). Returns the core's
// TickFlags. RT-safe: no allocation, lock or blocking call (tests/firmware/station checks it).
std::uint32_t run_tick(const TickInputs& in, TickRecords& rec, TickCounters& cnt, std::int64_t k, std::int64_t kr, const platform::TickInfo& info);

}  // namespace haptic::firmware
