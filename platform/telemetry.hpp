#pragma once
// Telemetry and post-mortem. The tick writes fixed-size TelemetryRecords into a lock-free SPSC
// ring (record(): RT-safe, never blocks, counts a drop when full). A non-RT logger thread
// drains the ring every drain period, appends CSV lines to a file and keeps the last
// `postmortem_s` seconds of records in a history buffer. report_fault() (RT-safe: one atomic
// store) makes the logger write that history to a post-mortem file: the failure comes with
// its history (overrun storm, device fault, divergence).
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "platform/spsc_ring.hpp"

namespace haptic::platform {

enum class FaultKind : std::uint32_t { none = 0, overrun_storm = 1, device_fault = 2, divergence = 3, other = 4 };
const char* to_string(FaultKind kind);

struct TelemetryRecord {
  static constexpr std::size_t kValues = 16;
  std::uint64_t tick = 0;
  std::int64_t scheduled_ns = 0;     // CLOCK_MONOTONIC deadline of the tick
  std::int32_t wake_latency_ns = 0;
  std::int32_t exec_ns = 0;          // previous tick's execution time (the current one is not over yet)
  std::uint32_t overruns = 0;        // loop's overrun count so far
  std::uint32_t status = 0;          // station-defined status/fault bits
  std::array<double, kValues> values{};  // station-defined channels, named in TelemetryConfig::value_names
};

struct TelemetryConfig {
  std::string path;                  // telemetry.path: CSV file (truncated at start); "" = no file, history only
  std::string postmortem_dir = ".";  // telemetry.postmortem_dir: where postmortem-*.csv go
  double period_s = 0.002;           // telemetry.period_s: tick period, sizes the history (> 0)
  double postmortem_s = 5.0;         // telemetry.postmortem_s: seconds of history dumped on a fault, 0.1..600
  std::uint32_t max_dumps = 8;       // telemetry.max_dumps: post-mortem files per run (>= 1); later faults are counted only
  std::int64_t drain_period_ns = 5'000'000;  // telemetry.drain_period_ns: logger wake-up period, 100 us..1 s
  std::vector<std::string> value_names;      // column names of values[] (at most kValues; unnamed columns are skipped)
};

class Telemetry {
 public:
  static constexpr std::size_t kRingCapacity = 4096;  // 8 s at 500 Hz before the tick drops records

  // Opens the file and starts the logger thread. Throws std::invalid_argument for bad config,
  // std::runtime_error when the file cannot be created. Not RT-safe.
  explicit Telemetry(const TelemetryConfig& config);
  ~Telemetry();  // stops the logger after a final drain
  Telemetry(const Telemetry&) = delete;
  Telemetry& operator=(const Telemetry&) = delete;

  // RT-safe, producer side (one thread). False (and counted) when the ring is full.
  bool record(const TelemetryRecord& r) {
    if (ring_->writer_try_push(r)) return true;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  // RT-safe, producer side (the same single thread as record()): asks the logger to dump the
  // history; a fault reported while a dump is pending is counted only.
  void report_fault(FaultKind kind, std::uint64_t tick) {
    faults_.fetch_add(1, std::memory_order_relaxed);
    if (pending_fault_.load(std::memory_order_acquire) != 0) return;
    pending_fault_tick_.store(tick, std::memory_order_relaxed);
    pending_fault_.store(static_cast<std::uint32_t>(kind), std::memory_order_release);
  }

  // Non-RT: blocks until everything pushed before the call is written and any pending dump done.
  void flush();
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  std::uint64_t written() const { return written_.load(std::memory_order_acquire); }
  std::uint64_t faults() const { return faults_.load(std::memory_order_relaxed); }
  std::uint64_t dumps() const { return dumps_.load(std::memory_order_acquire); }
  std::string last_dump_path() const;
  std::size_t history_capacity() const { return history_.size(); }

 private:
  using Ring = SpscRing<TelemetryRecord, kRingCapacity>;
  void logger_main();
  std::size_t drain();
  void dump(FaultKind kind, std::uint64_t tick);
  void write_header(std::FILE* f) const;
  void write_line(std::FILE* f, const TelemetryRecord& r) const;

  TelemetryConfig config_;
  std::unique_ptr<Ring> ring_;
  std::FILE* file_ = nullptr;
  std::vector<TelemetryRecord> history_;  // circular, logger thread only
  std::size_t history_next_ = 0;
  std::size_t history_count_ = 0;
  std::atomic<std::uint64_t> dropped_{0}, written_{0}, faults_{0}, dumps_{0};
  std::atomic<std::uint32_t> pending_fault_{0};
  std::atomic<std::uint64_t> pending_fault_tick_{0};
  std::atomic<std::uint64_t> flush_request_{0}, flush_done_{0};
  std::atomic<bool> stop_{false};
  mutable std::mutex dump_path_mutex_;  // non-RT only
  std::string last_dump_path_;
  std::thread logger_;
};

}  // namespace haptic::platform
