#pragma once
// The clocks of the project, one implementation: reading a POSIX clock in integer nanoseconds,
// CLOCK_MONOTONIC in ns and s (the clock of every deadline, wire timestamp and device sample),
// ns -> timespec, and an absolute CLOCK_MONOTONIC sleep that survives signals.
// All RT-safe: a vDSO read or one clock_nanosleep, no allocation.
#include <time.h>

#include <cerrno>
#include <cstdint>

namespace haptic::platform {

// The clock `id` in ns (0 if the clock cannot be read, e.g. a CPU-time clock of a gone thread).
inline std::int64_t clock_ns(clockid_t id) noexcept {
  timespec ts{};
  if (clock_gettime(id, &ts) != 0) return 0;
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
inline std::int64_t monotonic_ns() noexcept { return clock_ns(CLOCK_MONOTONIC); }
inline double monotonic_s() noexcept { return static_cast<double>(monotonic_ns()) * 1e-9; }

// ns >= 0 -> timespec.
inline timespec to_timespec(std::int64_t ns) noexcept {
  return timespec{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}

// Sleeps until the absolute CLOCK_MONOTONIC time deadline_ns (TIMER_ABSTIME; EINTR resumes).
inline void sleep_until_monotonic_ns(std::int64_t deadline_ns) noexcept {
  const timespec ts = to_timespec(deadline_ns);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace haptic::platform
