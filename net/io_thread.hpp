#pragma once
// The endpoint's I/O thread as a thread: a platform::RtThread (optionally SCHED_FIFO, optionally
// pinned) that runs a body until stop(), an eventfd other threads write to wake it (never blocks),
// the thread's CPU time, and its set-up warnings. What the body does is the endpoint's.
// start()/stop() and the accessors are non-RT; wake() is RT-safe (one non-blocking write).
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace haptic::platform {
class RtThread;
}

namespace haptic::net {

class IoThread {
 public:
  // cpu: pin to this CPU (-1: unpinned; net.io_cpu); priority: SCHED_FIFO priority (0: SCHED_OTHER).
  IoThread(int cpu, int priority);  // creates the wake eventfd (throws std::system_error)
  ~IoThread();
  IoThread(const IoThread&) = delete;
  IoThread& operator=(const IoThread&) = delete;

  // Runs body on the new thread (body returns once running() is false). Throws naming net.io_cpu
  // when the thread cannot be pinned; a refused SCHED_FIFO is a warning (warnings()).
  void start(std::function<void()> body);
  void stop();  // clears running(), wakes and joins the thread; idempotent
  bool started() const { return static_cast<bool>(thread_); }
  bool running() const { return running_.load(std::memory_order_acquire); }
  bool running_relaxed() const { return running_.load(std::memory_order_relaxed); }

  // Any thread: wakes the body's poll on wake_fd(). RT-safe (EFD_NONBLOCK: never blocks).
  void wake();
  int wake_fd() const { return wake_fd_; }
  void clear_wake();  // the body: consume the wake-ups

  // The body, first and last: the thread's CPU clock for cpu_s(), kept after the thread is gone.
  void body_started();
  void body_stopping();
  double cpu_s() const;  // CPU time the thread has used (spinning included); any thread
  const std::vector<std::string>& warnings() const { return warnings_; }
  const std::string& scheduling() const { return sched_; }  // "SCHED_FIFO <p>", "SCHED_OTHER" or "not started"

 private:
  int cpu_, priority_;
  int wake_fd_ = -1;
  std::atomic<bool> running_{false};
  std::unique_ptr<platform::RtThread> thread_;
  std::vector<std::string> warnings_;
  std::string sched_ = "not started";
  std::atomic<std::int64_t> clock_{-1};  // the thread's CPU clock id (clockid_t), -1 while not running
  std::atomic<std::uint64_t> cpu_at_stop_ns_{0};
};

// A non-RT thread waiting for deliveries (Endpoint::wait_rx) while the producer never pays a
// syscall unless someone waits: the waiter registers, then looks; the producer publishes, then
// looks for waiters (a Dekker pair, seq_cst on both sides, no fences: ThreadSanitizer checks it).
// The waiter sleeps on a futex, the delivery count: a delivery after its look changes the count,
// so its FUTEX_WAIT returns at once (no lost wake-up); one system call a side where an eventfd
// took a write, a ppoll and a read.
class DeliveryWaiter {
 public:
  DeliveryWaiter() = default;
  DeliveryWaiter(const DeliveryWaiter&) = delete;
  DeliveryWaiter& operator=(const DeliveryWaiter&) = delete;
  // Producer, after publishing a delivery: wakes the waiters if there are any. RT-safe.
  void delivered();
  // Waiter: up to timeout_s until ready() is true; ready()'s result. Not RT-safe.
  template <class Ready>
  bool wait(double timeout_s, Ready&& ready) {
    const std::uint32_t seen = enter();
    if (ready()) {
      leave();
      return true;
    }
    block(seen, timeout_s);
    leave();
    return ready();
  }

 private:
  std::uint32_t enter();
  void leave() { waiters_.fetch_sub(1, std::memory_order_relaxed); }
  void block(std::uint32_t seen, double timeout_s);
  std::atomic<int> waiters_{0};
  std::atomic<std::uint32_t> delivered_{0};  // the futex word
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t) && std::atomic<std::uint32_t>::is_always_lock_free);
};

}  // namespace haptic::net
