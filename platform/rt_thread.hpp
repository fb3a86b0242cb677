#pragma once
// Real-time set-up of a thread: SCHED_FIFO priority, CPU pinning, mlockall with stack and heap
// prefaulting, optional hold of /dev/cpu_dma_latency, PREEMPT_RT detection. Every step that
// fails either falls back with a human-readable warning in the RtReport or, with
// RtConfig::require_rt, makes the set-up throw. None of this is real-time safe: call it once,
// before the periodic loop starts.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace haptic::platform {

struct RtConfig {
  int priority = 80;          // rt.priority: SCHED_FIFO priority, 1..98 (99 is left to the kernel's own threads)
  bool sched_fifo = true;     // false: stay SCHED_OTHER (priority unused), e.g. an I/O thread without RT priority
  int cpu = -1;               // rt.cpu: core to pin to, 0..(online cpus - 1); -1: don't pin
  bool lock_memory = true;    // rt.lock_memory: mlockall(MCL_CURRENT|MCL_FUTURE) + prefaulting
  bool hold_dma_latency = false;  // rt.hold_dma_latency: write 0 to /dev/cpu_dma_latency and keep it open
  bool require_rt = false;    // rt.require_rt: refuse (throw) instead of falling back
  // rt.isolate_cpu: with cpu >= 0, move every other thread of this process (and so the threads
  // they create later) off that cpu: a thread keeps its own pinning minus that cpu, or gets the
  // other cpus the process may use when it was pinned to that cpu alone. The kernel here
  // may not preempt kernel code (PREEMPT_NONE/VOLUNTARY): a housekeeping thread inside a
  // syscall on the RT core delays the tick until it leaves the kernel.
  bool isolate_cpu = true;
  std::size_t prefault_stack_bytes = 512 * 1024;  // rt.prefault_stack_bytes: 0..(stack size - 64 KiB)
  std::size_t prefault_heap_bytes = 8u << 20;     // rt.prefault_heap_bytes
};

// Throws std::invalid_argument naming the key and its allowed range. Not RT-safe.
void validate(const RtConfig& config);

// What the running kernel is. Not RT-safe.
struct KernelInfo {
  bool preempt_rt = false;        // /sys/kernel/realtime == 1 or uname -v says PREEMPT_RT
  std::string sys_kernel_realtime;  // file contents ("" when the file is absent)
  std::string uname_release;
  std::string uname_version;
};
KernelInfo detect_kernel();
// Pure decision used by detect_kernel(), exposed for tests.
bool is_preempt_rt(const std::string& sys_kernel_realtime, const std::string& uname_version);

// Holds /dev/cpu_dma_latency open with a 0 us request (the kernel honours it while open).
class DmaLatencyHold {
 public:
  DmaLatencyHold() = default;
  ~DmaLatencyHold();
  DmaLatencyHold(DmaLatencyHold&& other) noexcept;
  DmaLatencyHold& operator=(DmaLatencyHold&& other) noexcept;
  DmaLatencyHold(const DmaLatencyHold&) = delete;
  DmaLatencyHold& operator=(const DmaLatencyHold&) = delete;
  // Returns "" on success, otherwise why it failed.
  std::string acquire(int latency_us = 0);
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

// What RT set-up achieved. A step that was not requested is neither ok nor failed.
struct RtReport {
  KernelInfo kernel;
  bool sched_fifo = false;        // SCHED_FIFO at the requested priority is in effect
  int priority = 0;               // effective priority (0 when SCHED_OTHER)
  bool pinned = false;            // affinity set to the requested cpu
  int cpu = -1;
  int threads_moved_off = -1;     // rt.isolate_cpu: other threads moved off `cpu` (-1: not done)
  bool memory_locked = false;     // mlockall succeeded
  bool stack_prefaulted = false;
  bool heap_prefaulted = false;
  DmaLatencyHold dma_latency;     // held() when /dev/cpu_dma_latency is held
  std::vector<std::string> warnings;  // one line per fallback, human readable
  // True when everything a hard real-time deployment needs is in place.
  bool fully_real_time() const;
  // Multi-line summary for logs ("rt: ..." lines).
  std::string summary() const;
};

// Applies `config` to the calling thread. Falls back with warnings; with require_rt throws
// std::runtime_error listing every failed step. Invalid config throws std::invalid_argument.
RtReport apply_rt_config(const RtConfig& config);

// A thread created with a stack big enough for the prefault, which applies `config` first and
// then runs body(report). The constructor waits until the set-up is done and rethrows its
// exception (require_rt refusals, invalid config) in the caller. Not RT-safe.
class RtThread {
 public:
  RtThread(const RtConfig& config, std::function<void(const RtReport&)> body);
  ~RtThread();  // joins
  RtThread(const RtThread&) = delete;
  RtThread& operator=(const RtThread&) = delete;
  void join();
  // Copy of the set-up report's text (the report itself lives on the RT thread).
  const std::string& setup_summary() const { return summary_; }
  const std::vector<std::string>& setup_warnings() const { return warnings_; }

  struct Shared;  // implementation detail (state shared with the new thread)

 private:
  Shared* shared_ = nullptr;
  unsigned long handle_ = 0;
  bool joined_ = true;
  std::string summary_;
  std::vector<std::string> warnings_;
};

}  // namespace haptic::platform
