#include "drivers/template_device.hpp"

namespace haptic::drivers {

namespace {
DeviceCapabilities template_capabilities() {
  DeviceCapabilities c{};
  c.max_force_N = 1.0;
  c.max_stiffness_N_per_m = 500.0;
  c.servo_rate_hz = 1000.0;
  c.workspace_radius_m = 0.05;
  c.min_damping_Ns_per_m = 0.0;
  for (int i = 0; i < 3; ++i) c.sensed_axes[i] = c.actuated_axes[i] = true;
  c.name = "template device (copy me)";
  return c;
}
}  // namespace

TemplateDevice::TemplateDevice(const SafetyLimits& limits) : HapticDevice(template_capabilities(), limits) {}

void TemplateDevice::start() {
  sequence_ = 0;
  arm();
}

void TemplateDevice::stop() { disarm(); }

void TemplateDevice::service(double t_s) {
  DeviceSample s{};  // read the hardware here; this template's hardware sits at the origin
  s.time_s = t_s;
  s.sequence = ++sequence_;
  publish_sample(s);
  take_force(output_force_N_);  // write output_force_N_ to the hardware here
}

void TemplateDevice::last_output_force(double force_N[3]) const {
  for (int i = 0; i < 3; ++i) force_N[i] = output_force_N_[i];
}

}  // namespace haptic::drivers
