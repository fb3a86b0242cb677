#include "platform/gpio.hpp"

#include <dirent.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#if HAPTIC_WITH_GPIOD
#include <gpiod.h>
#endif

namespace haptic::platform {

bool GpioToggler::any_chip_present() {
  DIR* dir = opendir("/dev");
  if (dir == nullptr) return false;
  bool found = false;
  while (dirent* e = readdir(dir)) {
    if (std::strncmp(e->d_name, "gpiochip", 8) == 0) {
      found = true;
      break;
    }
  }
  closedir(dir);
  return found;
}

GpioToggler::GpioToggler(const GpioConfig& config) {
  if (!config.enabled) {
    status_ = "gpio: disabled (gpio.enabled = false)";
    return;
  }
  if (config.chip.empty()) {
    throw std::invalid_argument("gpio.chip is empty: set the chip to use (e.g. \"gpiochip0\"; `gpiodetect` lists them)");
  }
  if (config.tick_line < 0) {
    throw std::invalid_argument("gpio.tick_line = " + std::to_string(config.tick_line) +
                                ": allowed range is 0..(number of lines on " + config.chip + " - 1)");
  }
  if (config.packet_line < -1) {
    throw std::invalid_argument("gpio.packet_line = " + std::to_string(config.packet_line) +
                                ": allowed range is -1 (none) or 0..(number of lines on " + config.chip + " - 1)");
  }
  if (config.packet_line == config.tick_line) {
    throw std::invalid_argument("gpio.packet_line = " + std::to_string(config.packet_line) +
                                " is the same line as gpio.tick_line: use another line or -1 (none)");
  }
#if HAPTIC_WITH_GPIOD
  gpiod_chip* chip = gpiod_chip_open_lookup(config.chip.c_str());
  if (chip == nullptr) {
    const int err = errno;
    if (err == EACCES || err == EPERM) {
      throw std::runtime_error("gpio.chip = \"" + config.chip + "\": permission denied (" + std::strerror(err) +
                               "); install firmware/deploy/99-haptic.rules or run the station in group 'haptic'");
    }
    status_ = any_chip_present()
                  ? "gpio: chip \"" + config.chip + "\" not found (" + std::strerror(err) +
                        "); `gpiodetect` lists the chips present; running WITHOUT GPIO toggles"
                  : "gpio: no GPIO chip present on this machine (/dev/gpiochip* absent); running WITHOUT GPIO toggles";
    return;
  }
  const unsigned int lines = gpiod_chip_num_lines(chip);
  auto out_of_range = [&](const char* key, int line) {
    gpiod_chip_close(chip);
    throw std::invalid_argument(std::string(key) + " = " + std::to_string(line) + ": allowed range is 0.." +
                                std::to_string(lines - 1) + " (chip " + config.chip + " has " + std::to_string(lines) + " lines)");
  };
  if (static_cast<unsigned int>(config.tick_line) >= lines) out_of_range("gpio.tick_line", config.tick_line);
  if (config.packet_line >= 0 && static_cast<unsigned int>(config.packet_line) >= lines) {
    out_of_range("gpio.packet_line", config.packet_line);
  }
  auto request = [&](int offset) {
    gpiod_line* line = gpiod_chip_get_line(chip, static_cast<unsigned int>(offset));
    if (line == nullptr || gpiod_line_request_output(line, config.consumer.c_str(), 0) != 0) {
      const int err = errno;
      gpiod_chip_close(chip);  // releases any line already requested
      throw std::runtime_error("gpio: cannot request line " + std::to_string(offset) + " of " + config.chip +
                               " as output: " + std::strerror(err) + " (`gpioinfo` shows who holds it)");
    }
    return line;
  };
  gpiod_line* tick = request(config.tick_line);
  gpiod_line* packet = config.packet_line >= 0 ? request(config.packet_line) : nullptr;
  chip_ = chip;
  tick_line_ = tick;
  packet_line_ = packet;
  status_ = "gpio: " + std::string(gpiod_chip_name(chip)) + " (" + gpiod_chip_label(chip) + ") tick line " +
            std::to_string(config.tick_line) +
            (packet ? ", packet line " + std::to_string(config.packet_line) : std::string(", no packet line"));
#else
  status_ = "gpio: built without libgpiod (install libgpiod-dev and rebuild); running WITHOUT GPIO toggles";
#endif
}

GpioToggler::~GpioToggler() {
#if HAPTIC_WITH_GPIOD
  if (chip_ != nullptr) gpiod_chip_close(static_cast<gpiod_chip*>(chip_));  // releases the lines
#endif
}

void GpioToggler::set([[maybe_unused]] void* line, [[maybe_unused]] int value) {
#if HAPTIC_WITH_GPIOD
  if (line != nullptr && gpiod_line_set_value(static_cast<gpiod_line*>(line), value) != 0) ++errors_;
#endif
}

}  // namespace haptic::platform
