#pragma once
// Tracepoints of provider `haptic` (LTTng-UST). Each function is RT-safe: when no session
// enables the event it costs one predictable branch; when enabled it writes into a per-CPU
// lock-free buffer. With HAPTIC_WITH_LTTNG=0 every function compiles to nothing.
// Event list and fields: platform/trace_provider.h. Stage ids below are in the trace.
#include <cstdint>

#if HAPTIC_WITH_LTTNG
#include "platform/trace_provider.h"
#endif

namespace haptic::platform::trace {

extern const bool kCompiledIn;  // true when built with HAPTIC_WITH_LTTNG

// Stage ids of stage_begin/stage_end; tools/trace/analyze.py has the same table.
enum class Stage : std::uint8_t {
  device_read = 1,
  rx_drain = 2,
  solve = 3,
  publish = 4,
  tx = 5,
  monitor = 6,
  telemetry = 7,
  workload = 8,  // synthetic workload of haptic-jitter
};

#if HAPTIC_WITH_LTTNG
#define HAPTIC_TP(name, ...) lttng_ust_tracepoint(haptic, name, __VA_ARGS__)
#else
#define HAPTIC_TP(name, ...) ((void)0)
#endif

inline void tick_begin([[maybe_unused]] std::uint64_t tick, [[maybe_unused]] std::int64_t scheduled_ns,
                       [[maybe_unused]] std::int64_t wake_latency_ns) {
  HAPTIC_TP(tick_begin, tick, scheduled_ns, wake_latency_ns);
}
inline void tick_end([[maybe_unused]] std::uint64_t tick, [[maybe_unused]] std::int64_t exec_ns) {
  HAPTIC_TP(tick_end, tick, exec_ns);
}
inline void stage_begin([[maybe_unused]] Stage stage) { HAPTIC_TP(stage_begin, static_cast<std::uint8_t>(stage)); }
inline void stage_end([[maybe_unused]] Stage stage) { HAPTIC_TP(stage_end, static_cast<std::uint8_t>(stage)); }
inline void solve_begin() { stage_begin(Stage::solve); }
inline void solve_end() { stage_end(Stage::solve); }
inline void packet_rx([[maybe_unused]] std::uint32_t peer, [[maybe_unused]] std::uint64_t seq,
                      [[maybe_unused]] std::uint32_t bytes) {
  HAPTIC_TP(packet_rx, peer, seq, bytes);
}
inline void packet_tx([[maybe_unused]] std::uint32_t peer, [[maybe_unused]] std::uint64_t seq,
                      [[maybe_unused]] std::uint32_t bytes) {
  HAPTIC_TP(packet_tx, peer, seq, bytes);
}
inline void device_read([[maybe_unused]] std::uint32_t device, [[maybe_unused]] std::uint64_t sample_seq) {
  HAPTIC_TP(device_read, device, sample_seq);
}
inline void device_write([[maybe_unused]] std::uint32_t device, [[maybe_unused]] std::uint64_t command_seq) {
  HAPTIC_TP(device_write, device, command_seq);
}
inline void overrun([[maybe_unused]] std::uint64_t tick, [[maybe_unused]] std::uint64_t missed_cycles,
                    [[maybe_unused]] std::int64_t late_ns) {
  HAPTIC_TP(overrun, tick, missed_cycles, late_ns);
}

// Scoped stage: stage_begin on construction, stage_end on destruction. RT-safe.
class StageScope {
 public:
  explicit StageScope(Stage stage) : stage_(stage) { stage_begin(stage_); }
  ~StageScope() { stage_end(stage_); }
  StageScope(const StageScope&) = delete;
  StageScope& operator=(const StageScope&) = delete;

 private:
  Stage stage_;
};

}  // namespace haptic::platform::trace
