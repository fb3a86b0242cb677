#pragma once
// The station's per-tick records (station-<id>-trace.csv and -state.csv) in fixed-size windows
// that stream to disk during the run: the tick writes each row into a slot of a single-writer/
// single-reader ring (wait-free, allocation-free), and a non-RT writer thread (RecordFiles) drains
// the rings every 20 ms and appends the rows to the CSV files, so the memory the records take is
// set by a time window (StationPlan::trace_capacity / state_capacity), not by the planned
// duration. The tick never waits for the writer: a row that finds its window full is dropped and
// counted (TickRecords::trace_lost / state_lost), and the run reports the count.
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "platform/spsc_ring.hpp"

namespace haptic::firmware {

// One row of station-<id>-trace.csv (flat, trivially copyable).
struct TraceRec {
  std::int64_t k;
  double node[3], force[3], vp[3], device[3];
  double port_J, ctrl_J, vo_J, max_speed;
  double step_s;  // T_k the core integrated this tick with (rt::StationCore::last_step_s)
  std::uint32_t flags;
  std::int32_t wake_latency_ns;
  std::uint8_t contact;
};

// The indices of a single-writer/single-reader ring of `slots()` rows whose storage the owner
// keeps (the rows can be of a size known only at run time, as a state row of dofs values). The
// writer fills the slot writer_slot() names and publishes it with writer_commit(); the reader
// reads the slot reader_slot() names and hands it back with reader_release(). Memory orders as
// platform::SpscRing: each side stores its own index with release after touching a slot and
// reads the other's with acquire. Both sides wait-free, lock-free, allocation-free.
class RowWindow {
 public:
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  // Not RT-safe, and only while neither side runs: `slots` rounded up to a power of two (>= 2).
  void reset(std::size_t slots);
  std::size_t slots() const { return mask_ + 1; }
  // Writer side: the slot to fill next, or kNone when the window is full.
  std::size_t writer_slot() {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - cached_tail_ > mask_) {
      cached_tail_ = tail_.load(std::memory_order_acquire);
      if (head - cached_tail_ > mask_) return kNone;
    }
    return head & mask_;
  }
  void writer_commit() { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  // Reader side: the oldest filled slot, or kNone when the window is empty.
  std::size_t reader_slot() {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == cached_head_) {
      cached_head_ = head_.load(std::memory_order_acquire);
      if (tail == cached_head_) return kNone;
    }
    return tail & mask_;
  }
  void reader_release() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

 private:
  std::size_t mask_ = 0;
  alignas(platform::kCacheLine) std::atomic<std::size_t> head_{0};  // written by the writer only
  std::size_t cached_tail_ = 0;
  alignas(platform::kCacheLine) std::atomic<std::size_t> tail_{0};  // written by the reader only
  std::size_t cached_head_ = 0;
};

// The tick's record windows. Preallocated by reserve() (not RT-safe); the tick writes rows into
// free slots and never grows them (record_trace / record_state in tick.cpp).
struct TickRecords {
  std::vector<TraceRec> trace;  // trace_window.slots() rows
  std::vector<std::int64_t> state_k;
  std::vector<double> state_x;  // state_window.slots() x dofs
  int dofs = 0;
  RowWindow trace_window, state_window;
  // Counted by the tick (read after the loop ended): rows written into the windows, rows dropped
  // because the window was full (the writer fell behind).
  std::uint64_t trace_rows = 0, state_rows = 0, trace_lost = 0, state_lost = 0;
  // Windows of at least `trace_rows` and `state_rows` rows (rounded up to powers of two).
  void reserve(std::size_t trace_rows, std::size_t state_rows, int dofs);
  // The bytes reserve() holds for these windows.
  static std::size_t window_bytes(std::size_t trace_rows, std::size_t state_rows, int dofs);
};

// The CSV text of the records, one function per line kind (the only formatting of these files).
void write_station_trace_header(std::FILE* f);
void write_station_trace_row(std::FILE* f, const TraceRec& r, double period_s);
void write_station_state_header(std::FILE* f, int dofs);
void write_station_state_row(std::FILE* f, std::int64_t k, const double* x, int dofs);

// The writer thread that drains a TickRecords' windows into `base`-trace.csv and `base`-state.csv.
// Not RT-safe (the tick only touches TickRecords).
class RecordFiles {
 public:
  // Creates both files (truncated), writes their headers and starts the writer thread. Throws
  // std::runtime_error naming the file it cannot write.
  RecordFiles(const std::string& base, double period_s, TickRecords& rec);
  ~RecordFiles();
  RecordFiles(const RecordFiles&) = delete;
  RecordFiles& operator=(const RecordFiles&) = delete;
  // Call after the tick's last row: the writer drains what is left, the files are closed.
  // Returns the first write error ("" none). Idempotent.
  std::string finish();

 private:
  void drain();
  void writer_main();
  TickRecords& rec_;
  double period_s_;
  std::string trace_path_, state_path_, error_;
  std::FILE* trace_ = nullptr;
  std::FILE* state_ = nullptr;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  bool finished_ = false;
};

}  // namespace haptic::firmware
