#pragma once
// COPY-ME: the smallest complete driver. To add a device:
//   1. copy template_device.{hpp,cpp} to <yours>_device.{hpp,cpp}, rename the class;
//   2. fill its DeviceCapabilities (max force, stiffness at the servo rate, workspace, b_d, axes);
//   3. start(): open the hardware (throw std::runtime_error saying what is missing), start your
//      I/O context (thread, vendor callback), then call arm();
//   4. in your I/O context, once per servo period: read the hardware, publish_sample(), then
//      take_force() and write exactly that force to the hardware (it is already limited, and zero
//      in the safe state); on any error call raise_fault(<cause>, <code>);
//   5. stop(): disarm() first (forces zero), let one more period run, then release the hardware.
// The base class does the mailboxes, the limits and the safe state; you never touch them.
// This template "hardware" is a fixed point that never moves, serviced by the owner's service().
#include "drivers/device.hpp"

#include <cstdint>

namespace haptic::drivers {

class TemplateDevice final : public HapticDevice {
 public:
  explicit TemplateDevice(const SafetyLimits& limits = {});
  ~TemplateDevice() override { stop(); }
  void start() override;  // non-RT
  void stop() override;   // non-RT
  // The I/O context of this template (a real driver runs this from its own thread or callback).
  // RT-safe.
  void service(double t_s);
  void last_output_force(double force_N[3]) const;

 private:
  std::uint64_t sequence_ = 0;
  double output_force_N_[3] = {0.0, 0.0, 0.0};  // stands in for the hardware's force registers
};

}  // namespace haptic::drivers
