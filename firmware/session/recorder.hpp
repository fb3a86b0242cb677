#pragma once
// Session recorder: the RT tick hands fixed-size slots to a lock-free SPSC ring
// (platform/spsc_ring.hpp); a non-RT writer thread drains it every 5 ms and appends to the HDF5
// session log (firmware/session/log.hpp). The tick never waits: a record that does not fit is
// dropped and counted (the next tick row says how many were lost, so replay knows where its
// inputs are incomplete). The file is bounded: past `max_bytes` the writer stops appending and the
// log says at which tick (truncated_at_tick). Or it is a ring of the last minutes (ring_ticks > 0):
// the tick rows and the packet rows are fixed-size rings in the file (h5::Appendable), so memory
// and disk stay bounded however long the session runs; the log then says which ticks it holds
// (first_tick, and packets_complete_from_tick: the oldest tick with all its packets).
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "firmware/session/log.hpp"
#include "platform/spsc_ring.hpp"
#include "rt/tick_driver.hpp"

namespace haptic::firmware {

struct RecorderConfig {
  std::string path;                         // the .h5 file (created, truncated)
  std::uint64_t max_bytes = 1ull << 30;     // stop appending past this many bytes of rows (station.record_max_mb)
  bool lossless = false;                    // the recording side waits for room (the simulator; never the RT station)
  int deflate_level = 0;                    // HDF5 deflate on the packet values, 0 = none
  std::uint64_t ring_ticks = 0;             // > 0: keep only the newest this many ticks (station.record_ring_s / T)
};

// Rows of the packet ring for a tick ring of `ring_ticks` at a station with `neighbours`: one
// packet per neighbour and tick plus a quarter for duplicates and bursts.
inline std::uint64_t ring_packet_rows(std::uint64_t ring_ticks, int neighbours) {
  const std::uint64_t per_tick = static_cast<std::uint64_t>(neighbours < 1 ? 1 : neighbours);
  return ring_ticks * per_tick + (ring_ticks * per_tick + 3) / 4;
}
// Bytes of the two rings (tick rows 128 B; packet rows 32 B + 2 dofs values).
inline std::uint64_t ring_bytes(std::uint64_t ring_ticks, int neighbours, int dofs, bool float32) {
  return ring_ticks * 128 + ring_packet_rows(ring_ticks, neighbours) * (32 + 2 * static_cast<std::uint64_t>(dofs) * (float32 ? 4 : 8));
}

struct RecorderStats {
  std::uint64_t ticks = 0, packets = 0;     // rows written
  std::uint64_t dropped_records = 0;        // records the tick could not hand over (ring full)
  std::uint64_t bytes = 0;                  // bytes of rows written (before HDF5 overhead)
  std::int64_t truncated_at_tick = -1;      // first tick not written because of max_bytes (-1: none)
  std::int64_t first_tick = 0;              // the oldest tick row in the log (> 0: a ring that wrapped)
  std::int64_t packets_complete_from_tick = 0;  // the oldest tick whose packets are all in the log
  std::uint64_t lossy_packet_values = 0;    // float32 storage: values that were not floats
  std::string error;                        // the writer's I/O error, if any
};

// One ring slot: 512 bytes. A packet or the initial state is a head slot followed by data slots.
inline constexpr std::size_t kSlotDoubles = 60;
struct RecordSlot {
  std::uint32_t type = 0;
  std::uint32_t aux = 0;   // packet: neighbour index
  std::int64_t a = 0;      // packet: tick; data: -
  std::int64_t b = 0;      // packet: seq
  double c = 0;            // packet: send time
  double payload[kSlotDoubles] = {};
};
static_assert(sizeof(TickRecord) <= sizeof(RecordSlot::payload), "a tick row fits one slot");

class SessionRecorder {
 public:
  static constexpr std::size_t kRingSlots = 1u << 14;  // 8 MB
  // Creates the file, writes the header (SessionInfo, the core's configuration) and starts the
  // writer thread. Throws std::runtime_error naming the file. Not RT-safe.
  SessionRecorder(const RecorderConfig& config, const SessionInfo& info, const rt::StationConfig& core);
  ~SessionRecorder();
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  // Recording side (one thread, the tick). Wait-free and allocation-free unless `lossless`.
  void rt_initial_state(const double* x, const double* v);
  void rt_packet(std::int64_t kr, int neighbour, std::int64_t seq, double send_time_s, const double* x, const double* v);
  void rt_tick(const TickRecord& r);

  // Stops the writer after it drained the ring, writes the counters, closes the file. Not RT-safe.
  RecorderStats finish();
  // Records dropped so far (any thread).
  std::uint64_t dropped_records() const { return dropped_total_.load(std::memory_order_relaxed); }
  const std::string& path() const { return cfg_.path; }

 private:
  struct Writer;
  bool reserve(std::size_t slots);
  void push_values(std::uint32_t type, std::uint32_t aux, std::int64_t a, std::int64_t b, double c, const double* x, const double* v);
  void writer_main();

  RecorderConfig cfg_;
  int dofs_ = 0;
  std::unique_ptr<platform::SpscRing<RecordSlot, kRingSlots>> ring_;
  std::unique_ptr<Writer> writer_;
  std::uint32_t dropped_since_tick_ = 0;         // recording side only
  std::atomic<std::uint64_t> dropped_total_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
  bool finished_ = false;
  RecorderStats final_{};
};

// rt::drive_tick's observer that records every packet offered to tick k, as offered (recorder null:
// records nothing). RT-safe.
struct RecordOffered {
  SessionRecorder* recorder = nullptr;
  std::int64_t k = 0;
  void offered(const rt::ReceivedState& p, std::int64_t index, rt::RxVerdict) {
    if (recorder) recorder->rt_packet(k, p.link, index, p.send_time_s, p.x_hat, p.v_hat);
  }
  void stepping() {}
};

}  // namespace haptic::firmware
