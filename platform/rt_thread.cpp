#include "platform/rt_thread.hpp"

#include <alloca.h>
#include <dirent.h>
#include <sys/syscall.h>
#include <fcntl.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace haptic::platform {
namespace {

constexpr int kMinPriority = 1;
constexpr int kMaxPriority = 98;
constexpr std::size_t kPage = 4096;
constexpr std::size_t kStackMargin = 64 * 1024;
constexpr int kCapIpcLock = 14;
constexpr int kCapSysNice = 23;

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s;
}

std::string errno_text(int err) { return std::string(std::strerror(err)) + " (errno " + std::to_string(err) + ")"; }

// Effective capability bit from /proc/self/status (CapEff), false when unreadable.
bool has_capability(int bit) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("CapEff:", 0) == 0) {
      const std::uint64_t caps = std::strtoull(line.c_str() + 7, nullptr, 16);
      return ((caps >> bit) & 1u) != 0;
    }
  }
  return false;
}

std::string rlimit_text(int resource) {
  rlimit lim{};
  if (getrlimit(resource, &lim) != 0) return "unknown";
  if (lim.rlim_cur == RLIM_INFINITY) return "unlimited";
  return std::to_string(lim.rlim_cur);
}

// Touches `bytes` of this thread's stack so the pages are resident (and locked under mlockall).
__attribute__((noinline)) void prefault_stack(std::size_t bytes) {
  auto* p = static_cast<volatile unsigned char*>(alloca(bytes));
  for (std::size_t i = 0; i < bytes; i += kPage) p[i] = 0;
}

std::size_t current_stack_size() {
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
  std::size_t size = 0;
  pthread_attr_getstacksize(&attr, &size);
  pthread_attr_destroy(&attr);
  return size;
}

// Keeps freed heap in the process (no trim, no mmap for big blocks) and touches `bytes` of it,
// so later allocations from init code reuse resident, locked pages.
bool prefault_heap(std::size_t bytes) {
  if (mallopt(M_TRIM_THRESHOLD, -1) == 0 || mallopt(M_MMAP_MAX, 0) == 0) return false;
  auto* p = static_cast<volatile unsigned char*>(std::malloc(bytes));
  if (p == nullptr) return false;
  for (std::size_t i = 0; i < bytes; i += kPage) p[i] = 0;
  std::free(const_cast<unsigned char*>(p));
  return true;
}

}  // namespace

void validate(const RtConfig& config) {
  if (config.sched_fifo && (config.priority < kMinPriority || config.priority > kMaxPriority)) {
    throw std::invalid_argument("rt.priority = " + std::to_string(config.priority) + ": allowed range is " +
                                std::to_string(kMinPriority) + ".." + std::to_string(kMaxPriority) +
                                " (99 is left to the kernel's watchdog/migration threads)");
  }
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  if (config.cpu < -1 || config.cpu >= online) {
    throw std::invalid_argument("rt.cpu = " + std::to_string(config.cpu) + ": allowed range is -1 (don't pin) or 0.." +
                                std::to_string(online - 1) + " (online cpus)");
  }
  if (config.prefault_heap_bytes > (std::size_t{1} << 30)) {
    throw std::invalid_argument("rt.prefault_heap_bytes = " + std::to_string(config.prefault_heap_bytes) +
                                ": allowed range is 0..1073741824");
  }
  if (config.prefault_stack_bytes > (std::size_t{256} << 20)) {
    throw std::invalid_argument("rt.prefault_stack_bytes = " + std::to_string(config.prefault_stack_bytes) +
                                ": allowed range is 0..268435456 and below the thread's stack size");
  }
}

bool is_preempt_rt(const std::string& sys_kernel_realtime, const std::string& uname_version) {
  if (trim(sys_kernel_realtime) == "1") return true;
  return uname_version.find("PREEMPT_RT") != std::string::npos ||
         uname_version.find("PREEMPT RT") != std::string::npos;
}

KernelInfo detect_kernel() {
  KernelInfo info;
  std::ifstream f("/sys/kernel/realtime");
  if (f) std::getline(f, info.sys_kernel_realtime);
  utsname u{};
  if (uname(&u) == 0) {
    info.uname_release = u.release;
    info.uname_version = u.version;
  }
  info.preempt_rt = is_preempt_rt(info.sys_kernel_realtime, info.uname_version);
  return info;
}

DmaLatencyHold::~DmaLatencyHold() {
  if (fd_ >= 0) ::close(fd_);
}
DmaLatencyHold::DmaLatencyHold(DmaLatencyHold&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
DmaLatencyHold& DmaLatencyHold::operator=(DmaLatencyHold&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}
std::string DmaLatencyHold::acquire(int latency_us) {
  if (fd_ >= 0) return "";
  const int fd = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd < 0) return "cannot open /dev/cpu_dma_latency: " + errno_text(errno);
  const std::int32_t value = latency_us;
  if (::write(fd, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
    const int err = errno;
    ::close(fd);
    return "cannot write /dev/cpu_dma_latency: " + errno_text(err);
  }
  fd_ = fd;
  return "";
}

bool RtReport::fully_real_time() const { return kernel.preempt_rt && sched_fifo && memory_locked; }

std::string RtReport::summary() const {
  std::ostringstream os;
  os << "rt: kernel " << kernel.uname_release << (kernel.preempt_rt ? " (PREEMPT_RT)" : " (NOT PREEMPT_RT)") << "\n";
  os << "rt: scheduling " << (sched_fifo ? "SCHED_FIFO priority " + std::to_string(priority) : std::string("SCHED_OTHER"))
     << ", cpu " << (pinned ? std::to_string(cpu) : std::string("not pinned"))
     << (threads_moved_off >= 0 ? " (" + std::to_string(threads_moved_off) + " other threads moved off it)" : std::string())
     << ", memory " << (memory_locked ? "locked" : "NOT locked")
     << ", stack " << (stack_prefaulted ? "prefaulted" : "not prefaulted")
     << ", heap " << (heap_prefaulted ? "prefaulted" : "not prefaulted")
     << ", cpu_dma_latency " << (dma_latency.held() ? "held at 0 us" : "not held") << "\n";
  for (const auto& w : warnings) os << "rt: WARNING: " << w << "\n";
  return os.str();
}

namespace {
// Every thread of this process but the caller: affinity = the process's allowed cpus minus
// `cpu`. Returns "" or why it could not (the other threads then share the RT core).
std::string move_other_threads_off(int cpu, int& moved) {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return "rt.isolate_cpu: sched_getaffinity failed";
  // The caller is pinned to `cpu` by now; the process-wide set is the main thread's.
  cpu_set_t main_set;
  CPU_ZERO(&main_set);
  if (sched_getaffinity(getpid(), sizeof main_set, &main_set) == 0) CPU_OR(&allowed, &allowed, &main_set);
  CPU_CLR(cpu, &allowed);
  if (CPU_COUNT(&allowed) == 0)
    return "rt.isolate_cpu: no other cpu is allowed to this process (systemd CPUAffinity / cpuset): housekeeping threads share cpu " +
           std::to_string(cpu);
  const pid_t self = static_cast<pid_t>(syscall(SYS_gettid));
  moved = 0;
  std::string errors;
  DIR* d = opendir("/proc/self/task");
  if (d == nullptr) return "rt.isolate_cpu: cannot list /proc/self/task";
  while (const dirent* e = readdir(d)) {
    const pid_t tid = static_cast<pid_t>(std::atoi(e->d_name));
    if (tid <= 0 || tid == self) continue;
    // Keep a thread's own pinning (e.g. net.io_cpu) and only take the RT cpu out of it; a
    // thread pinned to the RT cpu alone gets every other allowed cpu.
    cpu_set_t mine;
    CPU_ZERO(&mine);
    if (sched_getaffinity(tid, sizeof mine, &mine) != 0) continue;  // the thread has exited
    if (!CPU_ISSET(cpu, &mine)) continue;
    CPU_CLR(cpu, &mine);
    const cpu_set_t& target = CPU_COUNT(&mine) > 0 ? mine : allowed;
    if (sched_setaffinity(tid, sizeof target, &target) == 0) ++moved;
    else errors += (errors.empty() ? "" : ", ") + std::to_string(tid) + " (" + errno_text(errno) + ")";
  }
  closedir(d);
  return errors.empty() ? "" : "rt.isolate_cpu: could not move threads " + errors + " off cpu " + std::to_string(cpu);
}

// Each step below records what it could not do in report.warnings; a step that rt.require_rt does
// not accept also goes to `refusals` (apply_rt_config throws on any when require_rt is set).
struct RtSetup {
  RtReport& report;
  std::vector<std::string>& refusals;
  void fail(const std::string& what) {
    report.warnings.push_back(what);
    refusals.push_back(what);
  }
};

void check_kernel(RtSetup& setup) {
  RtReport& report = setup.report;
  report.kernel = detect_kernel();
  if (!report.kernel.preempt_rt) {
    setup.fail("kernel " + report.kernel.uname_release + " is not PREEMPT_RT (/sys/kernel/realtime " +
               (report.kernel.sys_kernel_realtime.empty() ? std::string("absent") : "= " + report.kernel.sys_kernel_realtime) +
               ", uname -v '" + report.kernel.uname_version + "'): wake-up latency is not bounded");
  }
}

// mlockall, then the heap and stack prefaults (only with rt.lock_memory).
void lock_memory(const RtConfig& config, RtSetup& setup) {
  RtReport& report = setup.report;
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    report.memory_locked = true;
  } else {
    const int err = errno;
    setup.fail("mlockall(MCL_CURRENT|MCL_FUTURE) failed: " + errno_text(err) + "; RLIMIT_MEMLOCK = " +
               rlimit_text(RLIMIT_MEMLOCK) + " bytes, CAP_IPC_LOCK " + (has_capability(kCapIpcLock) ? "present" : "absent") +
               " (set LimitMEMLOCK=infinity in the systemd unit)");
  }
  if (config.prefault_heap_bytes > 0) {
    report.heap_prefaulted = prefault_heap(config.prefault_heap_bytes);
    if (!report.heap_prefaulted) report.warnings.push_back("heap prefault of " + std::to_string(config.prefault_heap_bytes) + " bytes failed");
  }
  if (config.prefault_stack_bytes > 0) {
    const std::size_t stack = current_stack_size();
    if (stack != 0 && config.prefault_stack_bytes + kStackMargin > stack) {
      report.warnings.push_back("rt.prefault_stack_bytes = " + std::to_string(config.prefault_stack_bytes) +
                                " does not fit this thread's stack of " + std::to_string(stack) +
                                " bytes; stack not prefaulted (use RtThread, which sizes the stack)");
    } else {
      prefault_stack(config.prefault_stack_bytes);
      report.stack_prefaulted = true;
    }
  }
}

// Pins the calling thread to rt.cpu and, with rt.isolate_cpu, moves the process's other threads off it.
void pin_to_cpu(const RtConfig& config, RtSetup& setup) {
  RtReport& report = setup.report;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(config.cpu, &set);
  const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
  if (rc == 0) {
    report.pinned = true;
    report.cpu = config.cpu;
  } else {
    setup.fail("pinning to cpu " + std::to_string(config.cpu) + " failed: " + errno_text(rc) +
               " (is the cpu in this process's cpuset / systemd CPUAffinity?)");
  }
  if (report.pinned && config.isolate_cpu) {
    const std::string why = move_other_threads_off(config.cpu, report.threads_moved_off);
    if (!why.empty()) report.warnings.push_back(why);
  }
}

void set_scheduling(const RtConfig& config, RtSetup& setup) {
  RtReport& report = setup.report;
  sched_param param{};
  param.sched_priority = config.priority;
  const int rc = config.sched_fifo ? pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) : -1;
  if (!config.sched_fifo) {
    // SCHED_OTHER requested: nothing to do, nothing failed.
  } else if (rc == 0) {
    report.sched_fifo = true;
    report.priority = config.priority;
  } else {
    setup.fail("SCHED_FIFO priority " + std::to_string(config.priority) + " refused: " + errno_text(rc) +
               "; CAP_SYS_NICE " + (has_capability(kCapSysNice) ? "present" : "absent") + ", RLIMIT_RTPRIO = " +
               rlimit_text(RLIMIT_RTPRIO) + " (set LimitRTPRIO in the systemd unit); running SCHED_OTHER");
  }
}
}  // namespace

RtReport apply_rt_config(const RtConfig& config) {
  validate(config);
  RtReport report;
  std::vector<std::string> refusals;  // steps that require_rt does not accept
  RtSetup setup{report, refusals};

  check_kernel(setup);
  if (config.lock_memory) lock_memory(config, setup);
  if (config.cpu >= 0) pin_to_cpu(config, setup);
  set_scheduling(config, setup);
  if (config.hold_dma_latency) {
    const std::string why = report.dma_latency.acquire(0);
    if (!why.empty()) setup.fail(why + "; CPU idle states may add wake-up latency");
  }

  if (config.require_rt && !refusals.empty()) {
    std::string msg = "rt.require_rt is set and real-time set-up is incomplete:";
    for (const auto& r : refusals) msg += "\n  - " + r;
    throw std::runtime_error(msg);
  }
  return report;
}

struct RtThread::Shared {
  RtConfig config;
  std::function<void(const RtReport&)> body;
  std::mutex mutex;
  std::condition_variable cv;
  bool started = false;
  std::exception_ptr error;
  std::string summary;
  std::vector<std::string> warnings;
};

namespace {
void* rt_thread_main(void* arg) {
  auto* shared = static_cast<RtThread::Shared*>(arg);
  RtReport report;
  try {
    report = apply_rt_config(shared->config);
  } catch (...) {
    std::lock_guard lock(shared->mutex);
    shared->error = std::current_exception();
    shared->started = true;
    shared->cv.notify_all();
    return nullptr;
  }
  {
    std::lock_guard lock(shared->mutex);
    shared->summary = report.summary();
    shared->warnings = report.warnings;
    shared->started = true;
  }
  shared->cv.notify_all();
  shared->body(report);
  return nullptr;
}
}  // namespace

RtThread::RtThread(const RtConfig& config, std::function<void(const RtReport&)> body) {
  validate(config);
  shared_ = new Shared{};
  shared_->config = config;
  shared_->body = std::move(body);
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  const std::size_t stack = std::max<std::size_t>(8u << 20, config.prefault_stack_bytes + 4 * kStackMargin);
  pthread_attr_setstacksize(&attr, stack);
  pthread_t tid{};
  const int rc = pthread_create(&tid, &attr, &rt_thread_main, shared_);
  pthread_attr_destroy(&attr);
  if (rc != 0) {
    delete shared_;
    shared_ = nullptr;
    throw std::runtime_error("RtThread: pthread_create failed: " + errno_text(rc));
  }
  handle_ = static_cast<unsigned long>(tid);
  joined_ = false;
  std::unique_lock lock(shared_->mutex);
  shared_->cv.wait(lock, [&] { return shared_->started; });
  if (shared_->error) {
    const auto error = shared_->error;
    lock.unlock();
    join();
    std::rethrow_exception(error);
  }
  summary_ = shared_->summary;
  warnings_ = shared_->warnings;
}

void RtThread::join() {
  if (!joined_) {
    pthread_join(static_cast<pthread_t>(handle_), nullptr);
    joined_ = true;
  }
  delete shared_;
  shared_ = nullptr;
}

RtThread::~RtThread() { join(); }

}  // namespace haptic::platform
