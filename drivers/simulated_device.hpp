#pragma once
// Simulated device: the passive device + hand model of rt/user_model.hpp (mass m_d, damping b_d,
// hand spring-damper towards a scripted goal) behind the HapticDevice interface, so a station
// runs with no hardware. Two modes:
//   kOwnerStepped: deterministic; the owner (station loop, simulator, test) calls
//                  service(t_s, dt_s) once per tick AFTER command_force(); the device advances
//                  over [t_s, t_s + dt_s) with that force held and publishes the new sample.
//   kOwnThread:    its own thread advances the model at servo_rate_hz on absolute deadlines
//                  (CLOCK_MONOTONIC), like a real device's servo loop.
#include "drivers/device.hpp"
#include "rt/user_model.hpp"

#include <atomic>
#include <cstdint>
#include <thread>

namespace haptic::drivers {

enum class SimulatedDeviceMode : std::uint8_t { kOwnerStepped, kOwnThread };

struct SimulatedDeviceConfig {
  rt::DeviceModelParams device{};    // mass and b_d (b_d goes to capabilities.min_damping_Ns_per_m)
  rt::HandParams hand{};
  rt::GoalScript script{rt::Vec3::Zero()};
  int substeps_per_tick = 20;
  double start_position_m[3] = {0.0, 0.0, 0.0};
  SimulatedDeviceMode mode = SimulatedDeviceMode::kOwnerStepped;
  double servo_rate_hz = 1000.0;     // kOwnThread rate; [100, 20000]
  // Capabilities of the simulated device (defaults: Touch-class numbers, see README).
  double max_force_N = 3.3;
  double max_stiffness_N_per_m = 1260.0;
  double workspace_radius_m = 0.1;
};

// The capabilities a SimulatedDevice with this configuration reports (b_d = the model's). Non-RT.
DeviceCapabilities simulated_capabilities(const SimulatedDeviceConfig& config);

class SimulatedDevice final : public HapticDevice {
 public:
  explicit SimulatedDevice(const SimulatedDeviceConfig& config, const SafetyLimits& limits = {});
  ~SimulatedDevice() override;

  void start() override;  // non-RT; publishes the initial sample at time 0
  void stop() override;   // non-RT

  // kOwnerStepped only. RT-safe. Applies the newest commanded force (zero in the safe state)
  // over [t_s, t_s + dt_s) and publishes the sample at t_s + dt_s.
  void service(double t_s, double dt_s);

  // Test/diagnostic hooks. simulate_unplug(): the device vanishes (no more samples) and the
  // unplug fault is raised, as the USB monitor does for hardware. Any thread, RT-safe.
  void simulate_unplug();
  // Force that reached the simulated hardware in the last service/servo step (servo side).
  void last_output_force(double force_N[3]) const;
  const rt::SimulatedUser& user() const { return user_; }  // owner-stepped mode only

 private:
  void step(double t_s, double dt_s);
  void thread_main();

  SimulatedDeviceConfig config_;
  rt::SimulatedUser user_;
  std::uint64_t sequence_ = 0;
  std::atomic<bool> unplugged_{false};
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::atomic<double> last_force_N_[3] = {0.0, 0.0, 0.0};
};

}  // namespace haptic::drivers
