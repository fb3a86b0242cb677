#include "net/io_thread.hpp"

#include <pthread.h>
#include <linux/futex.h>
#include <sys/eventfd.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <system_error>

#include "platform/clock.hpp"
#include "platform/rt_thread.hpp"

namespace haptic::net {

namespace {
int make_eventfd() {
  const int fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "net: eventfd");
  return fd;
}
void write_one(int fd) {
  const std::uint64_t one = 1;
  [[maybe_unused]] auto r = ::write(fd, &one, sizeof one);  // EFD_NONBLOCK: never blocks
}
}  // namespace

IoThread::IoThread(int cpu, int priority) : cpu_(cpu), priority_(priority), wake_fd_(make_eventfd()) {}

IoThread::~IoThread() {
  stop();
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void IoThread::start(std::function<void()> body) {
  if (running()) return;
  running_.store(true, std::memory_order_release);
  platform::RtConfig rc;
  rc.sched_fifo = priority_ > 0;
  rc.priority = priority_ > 0 ? priority_ : 1;
  rc.cpu = cpu_;
  rc.lock_memory = false;  // the station's RT thread locks the process's memory
  rc.isolate_cpu = false;
  rc.prefault_stack_bytes = 0;
  rc.prefault_heap_bytes = 0;
  try {
    thread_ = std::make_unique<platform::RtThread>(rc, [body = std::move(body)](const platform::RtReport&) { body(); });
  } catch (const std::invalid_argument& e) {
    running_.store(false, std::memory_order_release);
    throw std::invalid_argument(std::string("net.io_cpu = ") + std::to_string(cpu_) + ": " + e.what());
  } catch (...) {
    running_.store(false, std::memory_order_release);
    throw;
  }
  warnings_.clear();
  bool fifo = priority_ > 0;
  for (const auto& w : thread_->setup_warnings()) {
    if (w.find("PREEMPT_RT") != std::string::npos) continue;  // the station's RT thread reports the kernel
    if (w.find("SCHED_FIFO") != std::string::npos) fifo = false;
    if (w.find("pinning to cpu") != std::string::npos) {
      stop();
      throw std::runtime_error("net.io_cpu = " + std::to_string(cpu_) + ": cannot pin the I/O thread (" + w + ")");
    }
    warnings_.push_back("I/O thread: " + w);
  }
  sched_ = fifo ? "SCHED_FIFO " + std::to_string(priority_) : std::string("SCHED_OTHER");
}

void IoThread::stop() {
  if (!thread_) return;
  running_.store(false, std::memory_order_release);
  wake();
  thread_->join();
  thread_.reset();
}

void IoThread::wake() { write_one(wake_fd_); }

void IoThread::clear_wake() {
  std::uint64_t v;
  [[maybe_unused]] auto r = ::read(wake_fd_, &v, sizeof v);
}

void IoThread::body_started() {
  clockid_t cid{};
  if (pthread_getcpuclockid(pthread_self(), &cid) == 0) clock_.store(static_cast<std::int64_t>(cid), std::memory_order_release);
}

void IoThread::body_stopping() {
  clockid_t cid{};
  if (pthread_getcpuclockid(pthread_self(), &cid) == 0)
    cpu_at_stop_ns_.store(static_cast<std::uint64_t>(platform::clock_ns(cid)), std::memory_order_relaxed);
  clock_.store(-1, std::memory_order_release);
}

double IoThread::cpu_s() const {
  const std::int64_t id = clock_.load(std::memory_order_acquire);
  if (!thread_ || id < 0) return static_cast<double>(cpu_at_stop_ns_.load(std::memory_order_relaxed)) * 1e-9;
  return static_cast<double>(platform::clock_ns(static_cast<clockid_t>(id))) * 1e-9;
}

namespace {
long futex(std::atomic<std::uint32_t>& word, int op, std::uint32_t val, const timespec* timeout) {
  return ::syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), op, val, timeout, nullptr, 0);
}
}  // namespace

void DeliveryWaiter::delivered() {
  // Either the waiter's look after enter() sees this delivery or we see the waiter.
  delivered_.fetch_add(1, std::memory_order_seq_cst);
  if (waiters_.load(std::memory_order_seq_cst) > 0) futex(delivered_, FUTEX_WAKE_PRIVATE, INT32_MAX, nullptr);
}

std::uint32_t DeliveryWaiter::enter() {
  // Register first, then look: a delivery either is seen by the caller's look or wakes it.
  waiters_.fetch_add(1, std::memory_order_seq_cst);
  return delivered_.load(std::memory_order_seq_cst);  // pairs with delivered()
}

void DeliveryWaiter::block(std::uint32_t seen, double timeout_s) {
  // Returns when woken, at once when a delivery came after enter() (the word is no longer seen),
  // on the timeout or a signal: the caller looks again either way.
  const timespec t = platform::to_timespec(static_cast<std::int64_t>(std::max(0.0, timeout_s) * 1e9));
  futex(delivered_, FUTEX_WAIT_PRIVATE, seen, &t);
}

}  // namespace haptic::net
