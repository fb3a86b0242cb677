// GPIO toggler: configuration errors are clear; with no chip present it says so and is a no-op.
#include <stdexcept>

#include "platform/gpio.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

using haptic::platform::GpioConfig;
using haptic::platform::GpioToggler;

namespace {
std::string error_of(const GpioConfig& c) {
  try {
    GpioToggler g(c);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_GROUP(Gpio){};

TEST(Gpio, disabled_is_a_quiet_no_op) {
  GpioToggler g(GpioConfig{});
  CHECK_FALSE(g.active());
  STRCMP_CONTAINS("disabled", g.status().c_str());
  g.tick_high();
  g.tick_low();
  LONGS_EQUAL(0, g.errors());
}

TEST(Gpio, missing_chip_name_is_an_error) {
  GpioConfig c;
  c.enabled = true;
  c.tick_line = 3;
  STRCMP_CONTAINS("gpio.chip is empty", error_of(c).c_str());
}

TEST(Gpio, negative_or_duplicate_lines_are_errors) {
  GpioConfig c;
  c.enabled = true;
  c.chip = "gpiochip0";
  STRCMP_CONTAINS("gpio.tick_line = -1: allowed range is 0..", error_of(c).c_str());
  c.tick_line = 2;
  c.packet_line = -7;
  STRCMP_CONTAINS("gpio.packet_line = -7: allowed range is -1 (none) or 0..", error_of(c).c_str());
  c.packet_line = 2;
  STRCMP_CONTAINS("same line as gpio.tick_line", error_of(c).c_str());
}

TEST(Gpio, absent_chip_is_reported_and_toggles_are_no_ops) {
  GpioConfig c;
  c.enabled = true;
  c.chip = "haptic-no-such-chip";
  c.tick_line = 0;
  GpioToggler g(c);
  CHECK_FALSE(g.active());
  if (GpioToggler::any_chip_present()) {
    STRCMP_CONTAINS("chip \"haptic-no-such-chip\" not found", g.status().c_str());
  } else {
    STRCMP_CONTAINS("no GPIO chip present on this machine", g.status().c_str());
  }
  STRCMP_CONTAINS("running WITHOUT GPIO toggles", g.status().c_str());
  g.tick_high();
  g.packet_high();
  g.packet_low();
  g.tick_low();
  LONGS_EQUAL(0, g.errors());
}

TEST(Gpio, line_beyond_the_chip_is_an_error) {
  if (!GpioToggler::any_chip_present()) {
    UT_PRINT("NOT CHECKED: no /dev/gpiochip* on this machine (load gpio-sim or gpio-mockup to run this check)");
    return;
  }
  GpioConfig c;
  c.enabled = true;
  c.chip = "gpiochip0";
  c.tick_line = 100000;
  STRCMP_CONTAINS("gpio.tick_line = 100000: allowed range is 0..", error_of(c).c_str());
}
