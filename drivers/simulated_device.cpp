#include "drivers/simulated_device.hpp"
#include "platform/clock.hpp"

#include <cerrno>
#include <stdexcept>
#include <string>
#include <time.h>

namespace haptic::drivers {

namespace {

const SimulatedDeviceConfig& checked(const SimulatedDeviceConfig& c) {
  if (!(c.servo_rate_hz >= 100.0 && c.servo_rate_hz <= 20000.0))
    throw std::invalid_argument("drivers.simulated.servo_rate_hz = " + std::to_string(c.servo_rate_hz) +
                                " is out of range; allowed [100, 20000]");
  if (!(c.max_force_N >= 0.0 && c.max_force_N <= 100.0))
    throw std::invalid_argument("device.sim_max_force_N = " + std::to_string(c.max_force_N) +
                                " is out of range; allowed [0, 100]");
  if (!(c.workspace_radius_m > 0.0 && c.workspace_radius_m <= 10.0))
    throw std::invalid_argument("drivers.simulated.workspace_radius_m = " +
                                std::to_string(c.workspace_radius_m) + " is out of range; allowed (0, 10]");
  return c;
}

}  // namespace

DeviceCapabilities simulated_capabilities(const SimulatedDeviceConfig& c) {
  DeviceCapabilities caps{};
  caps.max_force_N = c.max_force_N;
  caps.max_stiffness_N_per_m = c.max_stiffness_N_per_m;
  caps.servo_rate_hz = c.servo_rate_hz;
  caps.workspace_radius_m = c.workspace_radius_m;
  caps.min_damping_Ns_per_m = c.device.damping_Ns_per_m;
  for (int i = 0; i < 3; ++i) caps.sensed_axes[i] = caps.actuated_axes[i] = true;
  caps.name = "simulated device + hand (rt/user_model.hpp)";
  return caps;
}

SimulatedDevice::SimulatedDevice(const SimulatedDeviceConfig& config, const SafetyLimits& limits)
    : HapticDevice(simulated_capabilities(checked(config)), limits),
      config_(config),
      user_(config.device, config.hand, config.script, config.substeps_per_tick) {}

SimulatedDevice::~SimulatedDevice() { stop(); }

void SimulatedDevice::start() {
  stop();
  user_.reset(rt::Vec3(config_.start_position_m[0], config_.start_position_m[1], config_.start_position_m[2]));
  unplugged_.store(false, std::memory_order_release);
  sequence_ = 0;
  DeviceSample s{};
  for (int i = 0; i < 3; ++i) s.position_m[i] = config_.start_position_m[i];
  s.time_s = 0.0;
  s.sequence = ++sequence_;
  publish_sample(s);
  arm();
  if (config_.mode == SimulatedDeviceMode::kOwnThread) {
    running_.store(true, std::memory_order_release);
    thread_ = std::thread([this] { thread_main(); });
  }
}

void SimulatedDevice::stop() {
  disarm();
  running_.store(false, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SimulatedDevice::step(double t_s, double dt_s) {
  double f[3];
  take_force(f);
  for (int i = 0; i < 3; ++i) last_force_N_[i].store(f[i], std::memory_order_relaxed);
  if (unplugged_.load(std::memory_order_acquire)) return;  // a vanished device produces nothing
  user_.advance(t_s, dt_s, rt::Vec3(f[0], f[1], f[2]));
  DeviceSample s{};
  const rt::Vec3& q = user_.position_m();
  const rt::Vec3& qd = user_.velocity_m_per_s();
  for (int i = 0; i < 3; ++i) {
    s.position_m[i] = q[i];
    s.velocity_m_per_s[i] = qd[i];
  }
  s.buttons = 0;
  s.time_s = t_s + dt_s;
  s.sequence = ++sequence_;
  publish_sample(s);
}

void SimulatedDevice::service(double t_s, double dt_s) { step(t_s, dt_s); }

void SimulatedDevice::thread_main() {
  const long period_ns = static_cast<long>(1e9 / config_.servo_rate_hz);
  const double dt_s = static_cast<double>(period_ns) * 1e-9;
  std::int64_t next_ns = platform::monotonic_ns();
  std::uint64_t k = 0;
  while (running_.load(std::memory_order_acquire)) {
    step(static_cast<double>(k) * dt_s, dt_s);
    ++k;
    next_ns += period_ns;
    platform::sleep_until_monotonic_ns(next_ns);
  }
}

void SimulatedDevice::simulate_unplug() {
  unplugged_.store(true, std::memory_order_release);
  raise_fault(DeviceFault::kUnplugged, 0);
}

void SimulatedDevice::last_output_force(double force_N[3]) const {
  for (int i = 0; i < 3; ++i) force_N[i] = last_force_N_[i].load(std::memory_order_relaxed);
}

}  // namespace haptic::drivers
