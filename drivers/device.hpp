#pragma once
// The one haptic-device interface (chai3d-like capability struct, libfranka-like flat structs).
//
// Threads: the station tick calls read_newest() then command_force() (both RT-safe: two
// lock-free latest-value mailboxes, never device I/O). The backend's own I/O context (a servo
// callback, a reader thread, or the owner's service() call) publishes samples and takes the
// newest force on the other side of those mailboxes.
//
// Safe state: any fault (unplug, stale sample, out-of-range data, servo error, calibration
// needed, a non-finite command) is latched; from then on read_newest() returns false, every
// force that leaves the driver is exactly zero, and fault() names the cause. The station sees
// it in the tick where it happens (read_newest() is the first call of the tick) and must
// disconnect the user's port passively. Only clear_fault() (non-RT, operator action) re-arms.
//
// Force and power limits apply on the way out, in command_force(): non-actuated axes zeroed,
// norm clamped to min(capabilities.max_force_N, limits.max_force_N), then the power the device
// would deliver into the hand, F . v (v from the newest sample), capped at limits.max_power_W.
#include "platform/latest_mailbox.hpp"

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace haptic::drivers {

struct DeviceSample {
  double position_m[3];
  double velocity_m_per_s[3];
  std::uint32_t buttons;
  double time_s;           // device clock (CLOCK_MONOTONIC for hardware, simulated time for sim)
  std::uint64_t sequence;  // increases by one per sample the backend produced
};

struct DeviceCapabilities {
  double max_force_N;
  double max_stiffness_N_per_m;  // at servo_rate_hz
  double servo_rate_hz;
  double workspace_radius_m;
  double min_damping_Ns_per_m;   // b_d for the paper's eq. (26)
  bool sensed_axes[3];
  bool actuated_axes[3];
  const char* name;              // static string
};

enum class DeviceFault : std::uint8_t {
  kNone = 0,
  kNotStarted,        // start() has not succeeded (or stop() was called)
  kUnplugged,         // USB removal seen by the hotplug monitor, or the backend lost the device
  kStaleSample,       // no new sample for more than limits.max_stale_reads ticks
  kOutOfRange,        // non-finite, outside the workspace margin, faster than max_speed, time going back
  kServoError,        // the vendor servo loop reported an error (fault_detail() = its code)
  kCalibrationNeeded, // the vendor library says the device must be calibrated first
  kBadCommand,        // the controller commanded a non-finite force
};

// Static name of a fault ("unplugged", ...). RT-safe.
const char* fault_name(DeviceFault fault);

// Safety configuration (keys of the [device] table of the station file, same names). Defaults documented
// per field; validate_limits() throws std::invalid_argument naming the key and allowed range.
struct SafetyLimits {
  double max_force_N = 1.0e9;        // extra clamp below capabilities.max_force_N; (0, inf)
  double max_power_W = 3.0;          // cap on F.v delivered into the hand; 0 disables; [0, 1000]
  std::uint32_t max_stale_reads = 5; // consecutive ticks without a new sample before the fault; [1, 100000]
  std::uint32_t max_reads_before_first_sample = 500;  // start-up grace; [1, 10000000]
  double workspace_margin = 1.5;     // out of range when |p| > margin * workspace_radius_m; [1, 100]
  double max_speed_m_per_s = 3.0;    // out of range above this speed; (0, 1000]
};

void validate_limits(const SafetyLimits& limits);

// Counters since start (relaxed atomics: readable from any thread for telemetry).
struct DeviceCounters {
  std::uint64_t samples_read;     // fresh samples delivered to the tick
  std::uint64_t held_reads;       // ticks that reused the previous sample
  std::uint64_t force_clamps;     // commands clamped by the force limit
  std::uint64_t power_limits;     // commands scaled by the power limit
  std::uint64_t forces_out;       // forces taken by the backend
};

class HapticDevice {
 public:
  HapticDevice(const DeviceCapabilities& capabilities, const SafetyLimits& limits);
  virtual ~HapticDevice() = default;
  HapticDevice(const HapticDevice&) = delete;
  HapticDevice& operator=(const HapticDevice&) = delete;

  // Non-RT. Brings the device up; throws std::runtime_error saying what is missing or wrong.
  // Must end with arm() on success (clears kNotStarted).
  virtual void start() = 0;
  // Non-RT, idempotent. Forces zero output, then releases the device.
  virtual void stop() = 0;

  // RT-safe (tick thread only). Newest sample into out; true when out is usable (fresh, or the
  // previous one held for at most limits.max_stale_reads ticks). False in the safe state.
  bool read_newest(DeviceSample& out);
  // RT-safe (tick thread only). Applies the limits and posts the force to the backend.
  // In the safe state the posted force is zero whatever is commanded.
  void command_force(const double force_N[3]);

  DeviceFault fault() const { return fault_.load(std::memory_order_acquire); }  // any thread
  std::int32_t fault_detail() const { return fault_detail_.load(std::memory_order_acquire); }
  // Non-RT: operator re-arm after the cause is gone (re-plugged, calibrated).
  void clear_fault();
  // Any thread, RT-safe: the hotplug monitor (UsbMonitor::watch) says the device is gone.
  void notify_unplugged() { raise_fault(DeviceFault::kUnplugged, 0); }

  const DeviceCapabilities& capabilities() const { return caps_; }
  const SafetyLimits& limits() const { return limits_; }
  DeviceCounters counters() const;
  // The last kHistory fresh samples the tick read, oldest first (libfranka habit: every failure
  // comes with its history). Non-RT; consistent once fault() != kNone, because the tick stops
  // recording in the safe state. Returns how many were copied.
  static constexpr std::size_t kHistory = 64;
  std::size_t history(DeviceSample* out, std::size_t max) const;
  // The force limit actually applied: min(capabilities.max_force_N, limits.max_force_N).
  double force_limit_N() const;

 protected:
  // Backend side. RT-safe. Publishes a new sample to the tick.
  void publish_sample(const DeviceSample& sample);
  // Backend side. RT-safe. Writes the force to send to the hardware now: the newest limited
  // command, or exactly zero in the safe state. True when a new command arrived since last time.
  bool take_force(double force_N[3]);
  // Any thread, RT-safe. Latches the first fault (later ones keep the first cause).
  void raise_fault(DeviceFault fault, std::int32_t detail = 0);
  // Non-RT: called by start() implementations after the hardware is up.
  void arm();
  // Non-RT: called by stop() implementations; forces zero output until the next arm().
  void disarm();
  // Non-RT, before arm(): the backend learned its real limits (e.g. from the vendor library).
  void set_capabilities(const DeviceCapabilities& capabilities);

 private:
  bool sample_in_range(const DeviceSample& s) const;

  DeviceCapabilities caps_;
  SafetyLimits limits_;
  platform::LatestMailbox<DeviceSample> samples_;
  struct ForceCommand { double force_N[3]; };
  platform::LatestMailbox<ForceCommand> forces_;
  std::atomic<DeviceFault> fault_{DeviceFault::kNotStarted};
  std::atomic<std::int32_t> fault_detail_{0};

  // Tick-thread state.
  DeviceSample last_{};
  bool have_sample_ = false;
  std::uint32_t reads_without_new_ = 0;
  std::array<DeviceSample, kHistory> history_{};
  std::uint64_t history_count_ = 0;

  // Backend-side state.
  double held_force_N_[3] = {0.0, 0.0, 0.0};

  std::atomic<std::uint64_t> samples_read_{0}, held_reads_{0}, force_clamps_{0}, power_limits_{0},
      forces_out_{0};
};

}  // namespace haptic::drivers
