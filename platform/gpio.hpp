#pragma once
// GPIO toggles for an oscilloscope (libgpiod 1.6, Debian 12): one line raised at tick begin and
// lowered at tick end, optionally a second line pulsed per packet sent. The lines are requested
// once at start-up and held; the toggle functions are one ioctl each, no allocation: RT-safe.
// With no GPIO chip on the machine (or the configured chip absent) the toggler says so in
// status() and every toggle is a no-op. Bad configuration throws at construction.
#include <string>

namespace haptic::platform {

struct GpioConfig {
  bool enabled = false;        // gpio.enabled: false = no GPIO at all (default)
  std::string chip;            // gpio.chip: "gpiochip0", "/dev/gpiochip0", a chip label or number
  int tick_line = -1;          // gpio.tick_line: 0..(lines on the chip - 1); required when enabled
  int packet_line = -1;        // gpio.packet_line: -1 = none, else 0..(lines - 1), != tick_line
  std::string consumer = "haptic-station";  // gpio.consumer: label shown by gpioinfo
};

class GpioToggler {
 public:
  // Throws std::invalid_argument (config key + allowed range) for bad configuration, and
  // std::runtime_error when the chip exists but the lines cannot be requested. Not RT-safe.
  explicit GpioToggler(const GpioConfig& config);
  ~GpioToggler();
  GpioToggler(const GpioToggler&) = delete;
  GpioToggler& operator=(const GpioToggler&) = delete;

  bool active() const { return tick_line_ != nullptr; }
  const std::string& status() const { return status_; }  // one line for the start-up log

  // RT-safe (no-op when inactive). Errors are counted, never thrown.
  void tick_high() { set(tick_line_, 1); }
  void tick_low() { set(tick_line_, 0); }
  void packet_high() { set(packet_line_, 1); }
  void packet_low() { set(packet_line_, 0); }
  unsigned long errors() const { return errors_; }  // failed set-value calls (read from the RT thread)

  // True when /dev holds at least one gpiochip device. Not RT-safe.
  static bool any_chip_present();

 private:
  void set(void* line, int value);
  void* chip_ = nullptr;         // gpiod_chip*
  void* tick_line_ = nullptr;    // gpiod_line*
  void* packet_line_ = nullptr;  // gpiod_line*
  unsigned long errors_ = 0;
  std::string status_;
};

}  // namespace haptic::platform
