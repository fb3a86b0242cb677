#include "drivers/device.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace haptic::drivers {

const char* fault_name(DeviceFault fault) {
  switch (fault) {
    case DeviceFault::kNone: return "none";
    case DeviceFault::kNotStarted: return "not started";
    case DeviceFault::kUnplugged: return "unplugged";
    case DeviceFault::kStaleSample: return "stale sample (device stopped updating)";
    case DeviceFault::kOutOfRange: return "out-of-range sample";
    case DeviceFault::kServoError: return "servo error reported by the vendor library";
    case DeviceFault::kCalibrationNeeded: return "calibration needed";
    case DeviceFault::kBadCommand: return "non-finite force commanded";
  }
  return "unknown";
}

namespace {
void require(bool ok, const char* key, const char* range, double value) {
  if (!ok)
    throw std::invalid_argument(std::string("device.") + key + " = " + std::to_string(value) +
                                " is out of range; allowed " + range);
}
}  // namespace

void validate_limits(const SafetyLimits& l) {
  require(l.max_force_N > 0.0 && !std::isnan(l.max_force_N), "max_force_N", "(0, inf)", l.max_force_N);
  require(l.max_power_W >= 0.0 && l.max_power_W <= 1000.0, "max_power_W", "[0, 1000] (0 disables)",
          l.max_power_W);
  require(l.max_stale_reads >= 1 && l.max_stale_reads <= 100000, "max_stale_reads", "[1, 100000]",
          l.max_stale_reads);
  require(l.max_reads_before_first_sample >= 1 && l.max_reads_before_first_sample <= 10000000,
          "max_reads_before_first_sample", "[1, 10000000]", l.max_reads_before_first_sample);
  require(l.workspace_margin >= 1.0 && l.workspace_margin <= 100.0, "workspace_margin", "[1, 100]",
          l.workspace_margin);
  require(l.max_speed_m_per_s > 0.0 && l.max_speed_m_per_s <= 1000.0, "max_speed_m_per_s", "(0, 1000]",
          l.max_speed_m_per_s);
}

HapticDevice::HapticDevice(const DeviceCapabilities& capabilities, const SafetyLimits& limits)
    : caps_(capabilities), limits_(limits) {
  validate_limits(limits);
  set_capabilities(capabilities);
}

void HapticDevice::set_capabilities(const DeviceCapabilities& c) {
  if (!(c.max_force_N >= 0.0) || !std::isfinite(c.max_force_N))
    throw std::invalid_argument("device capabilities: max_force_N must be finite and >= 0");
  if (!(c.workspace_radius_m > 0.0) || !std::isfinite(c.workspace_radius_m))
    throw std::invalid_argument("device capabilities: workspace_radius_m must be finite and > 0");
  if (!(c.servo_rate_hz > 0.0)) throw std::invalid_argument("device capabilities: servo_rate_hz must be > 0");
  if (!(c.min_damping_Ns_per_m >= 0.0))
    throw std::invalid_argument("device capabilities: min_damping_Ns_per_m must be >= 0");
  caps_ = c;
}

double HapticDevice::force_limit_N() const {
  return caps_.max_force_N < limits_.max_force_N ? caps_.max_force_N : limits_.max_force_N;
}

void HapticDevice::arm() {
  DeviceFault expected = DeviceFault::kNotStarted;
  fault_.compare_exchange_strong(expected, DeviceFault::kNone, std::memory_order_acq_rel);
}

void HapticDevice::disarm() {
  fault_detail_.store(0, std::memory_order_release);
  fault_.store(DeviceFault::kNotStarted, std::memory_order_release);
}

void HapticDevice::clear_fault() {
  fault_detail_.store(0, std::memory_order_release);
  fault_.store(DeviceFault::kNone, std::memory_order_release);
}

void HapticDevice::raise_fault(DeviceFault fault, std::int32_t detail) {
  DeviceFault expected = DeviceFault::kNone;
  if (fault_.compare_exchange_strong(expected, fault, std::memory_order_acq_rel)) {
    fault_detail_.store(detail, std::memory_order_release);
  }
}

bool HapticDevice::sample_in_range(const DeviceSample& s) const {
  double p2 = 0.0, v2 = 0.0;
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(s.position_m[i]) || !std::isfinite(s.velocity_m_per_s[i])) return false;
    if (!caps_.sensed_axes[i]) continue;
    p2 += s.position_m[i] * s.position_m[i];
    v2 += s.velocity_m_per_s[i] * s.velocity_m_per_s[i];
  }
  if (!std::isfinite(s.time_s)) return false;
  const double r = limits_.workspace_margin * caps_.workspace_radius_m;
  if (p2 > r * r) return false;
  if (v2 > limits_.max_speed_m_per_s * limits_.max_speed_m_per_s) return false;
  if (have_sample_ && (s.time_s < last_.time_s || s.sequence <= last_.sequence)) return false;
  return true;
}

bool HapticDevice::read_newest(DeviceSample& out) {
  if (fault() != DeviceFault::kNone) return false;
  DeviceSample fresh;
  if (samples_.reader_take(fresh)) {
    if (!sample_in_range(fresh)) {
      raise_fault(DeviceFault::kOutOfRange, 0);
      return false;
    }
    last_ = fresh;
    have_sample_ = true;
    history_[history_count_ % kHistory] = fresh;
    ++history_count_;
    reads_without_new_ = 0;
    samples_read_.fetch_add(1, std::memory_order_relaxed);
  } else {
    ++reads_without_new_;
    const std::uint32_t allowed =
        have_sample_ ? limits_.max_stale_reads : limits_.max_reads_before_first_sample;
    if (reads_without_new_ > allowed) {
      raise_fault(DeviceFault::kStaleSample, static_cast<std::int32_t>(reads_without_new_));
      return false;
    }
    if (!have_sample_) return false;  // still in the start-up grace: nothing to report yet
    held_reads_.fetch_add(1, std::memory_order_relaxed);
  }
  // A fault raised by another thread while we were reading wins.
  if (fault() != DeviceFault::kNone) return false;
  out = last_;
  return true;
}

void HapticDevice::command_force(const double force_N[3]) {
  ForceCommand cmd{{0.0, 0.0, 0.0}};
  if (fault() == DeviceFault::kNone) {
    bool finite = true;
    for (int i = 0; i < 3; ++i) finite = finite && std::isfinite(force_N[i]);
    if (!finite) {
      raise_fault(DeviceFault::kBadCommand, 0);
    } else {
      double f2 = 0.0;
      for (int i = 0; i < 3; ++i) {
        cmd.force_N[i] = caps_.actuated_axes[i] ? force_N[i] : 0.0;
        f2 += cmd.force_N[i] * cmd.force_N[i];
      }
      const double limit = force_limit_N();
      if (f2 > limit * limit) {
        const double scale = limit > 0.0 ? limit / std::sqrt(f2) : 0.0;
        for (double& f : cmd.force_N) f *= scale;
        force_clamps_.fetch_add(1, std::memory_order_relaxed);
      }
      if (limits_.max_power_W > 0.0 && have_sample_) {
        double power_W = 0.0;
        for (int i = 0; i < 3; ++i) power_W += cmd.force_N[i] * last_.velocity_m_per_s[i];
        if (power_W > limits_.max_power_W) {
          const double scale = limits_.max_power_W / power_W;
          for (double& f : cmd.force_N) f *= scale;
          power_limits_.fetch_add(1, std::memory_order_relaxed);
        }
      }
    }
  }
  if (fault() != DeviceFault::kNone) cmd = ForceCommand{{0.0, 0.0, 0.0}};
  forces_.writer_publish(cmd);
}

void HapticDevice::publish_sample(const DeviceSample& sample) { samples_.writer_publish(sample); }

bool HapticDevice::take_force(double force_N[3]) {
  ForceCommand cmd;
  const bool fresh = forces_.reader_take(cmd);
  if (fault() != DeviceFault::kNone) {
    // Safe state: drop whatever was queued so nothing from before the fault survives a re-arm.
    for (double& f : held_force_N_) f = 0.0;
  } else if (fresh) {
    for (int i = 0; i < 3; ++i) held_force_N_[i] = cmd.force_N[i];
  }
  for (int i = 0; i < 3; ++i) force_N[i] = held_force_N_[i];
  forces_out_.fetch_add(1, std::memory_order_relaxed);
  return fresh;
}

std::size_t HapticDevice::history(DeviceSample* out, std::size_t max) const {
  const std::size_t n = history_count_ < kHistory ? static_cast<std::size_t>(history_count_) : kHistory;
  const std::size_t count = n < max ? n : max;
  const std::uint64_t first = history_count_ - count;
  for (std::size_t i = 0; i < count; ++i) out[i] = history_[(first + i) % kHistory];
  return count;
}

DeviceCounters HapticDevice::counters() const {
  return DeviceCounters{samples_read_.load(std::memory_order_relaxed),
                        held_reads_.load(std::memory_order_relaxed),
                        force_clamps_.load(std::memory_order_relaxed),
                        power_limits_.load(std::memory_order_relaxed),
                        forces_out_.load(std::memory_order_relaxed)};
}

}  // namespace haptic::drivers
