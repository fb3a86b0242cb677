// RT set-up: PREEMPT_RT detection, config validation, fallback reporting without privileges
// (exercised for real in a child process that drops CAP_SYS_NICE/CAP_IPC_LOCK), require_rt refusal.
#include <linux/capability.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>

#include "platform/rt_thread.hpp"

// CppUTest last: its leak-detector macros redefine new.
#include <CppUTest/TestHarness.h>

using haptic::platform::apply_rt_config;
using haptic::platform::detect_kernel;
using haptic::platform::is_preempt_rt;
using haptic::platform::RtConfig;
using haptic::platform::RtReport;
using haptic::platform::RtThread;

namespace {

// Drops capabilities from the effective, permitted and inheritable sets of this process.
bool drop_capabilities(std::initializer_list<int> caps) {
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2]{};
  if (syscall(SYS_capget, &header, data) != 0) return false;
  for (int cap : caps) {
    const unsigned mask = ~(1u << (cap % 32));
    data[cap / 32].effective &= mask;
    data[cap / 32].permitted &= mask;
    data[cap / 32].inheritable &= mask;
  }
  return syscall(SYS_capset, &header, data) == 0;
}

// Runs `body` in a forked child (so privilege drops and mlockall don't leak into the test
// process) and returns what it wrote to the pipe.
template <class Body>
std::string in_child(Body body) {
  int fds[2];
  if (pipe(fds) != 0) return "pipe failed";
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    const std::string out = body();
    const ssize_t n = write(fds[1], out.data(), out.size());
    _exit(n == static_cast<ssize_t>(out.size()) ? 0 : 1);
  }
  close(fds[1]);
  std::string out;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return out;
}

std::string unprivileged_setup(bool require_rt) {
  if (!drop_capabilities({CAP_SYS_NICE, CAP_IPC_LOCK})) return "capset failed";
  rlimit rt{0, 0};
  rlimit mem{64 * 1024, 64 * 1024};
  if (setrlimit(RLIMIT_RTPRIO, &rt) != 0 || setrlimit(RLIMIT_MEMLOCK, &mem) != 0) return "setrlimit failed";
  RtConfig c;
  c.priority = 50;
  c.require_rt = require_rt;
  c.prefault_heap_bytes = 1u << 20;
  c.prefault_stack_bytes = 64 * 1024;
  try {
    const RtReport r = apply_rt_config(c);
    return std::string("fifo=") + (r.sched_fifo ? "1" : "0") + " locked=" + (r.memory_locked ? "1" : "0") +
           " policy=" + std::to_string(sched_getscheduler(0)) + "\n" + r.summary();
  } catch (const std::runtime_error& e) {
    return std::string("THROW ") + e.what();
  }
}

}  // namespace

TEST_GROUP(RtSetup){};

TEST(RtSetup, preempt_rt_is_recognised_from_sysfs_or_uname) {
  CHECK(is_preempt_rt("1\n", "#1 SMP PREEMPT_DYNAMIC"));
  CHECK(is_preempt_rt("", "#1 SMP PREEMPT_RT Debian 6.1.0-13-rt-amd64"));
  CHECK_FALSE(is_preempt_rt("", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.0-13-amd64"));
  CHECK_FALSE(is_preempt_rt("0", "#1 SMP PREEMPT"));
}

TEST(RtSetup, kernel_detection_reports_what_it_read) {
  const auto k = detect_kernel();
  CHECK(!k.uname_release.empty());
  UT_PRINT(("kernel " + k.uname_release + (k.preempt_rt ? " is PREEMPT_RT" : " is NOT PREEMPT_RT")).c_str());
}

TEST(RtSetup, bad_configuration_names_the_key_and_range) {
  RtConfig c;
  c.priority = 99;
  try {
    haptic::platform::validate(c);
    FAIL("priority 99 accepted");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("rt.priority = 99: allowed range is 1..98", e.what());
  }
  c.priority = 80;
  c.cpu = 4096;
  try {
    haptic::platform::validate(c);
    FAIL("cpu 4096 accepted");
  } catch (const std::invalid_argument& e) {
    STRCMP_CONTAINS("rt.cpu = 4096", e.what());
  }
}

TEST(RtSetup, without_privileges_it_falls_back_and_says_why) {
  const std::string out = in_child([] { return unprivileged_setup(false); });
  STRCMP_CONTAINS("fifo=0 locked=0 policy=0", out.c_str());  // SCHED_OTHER, memory not locked
  STRCMP_CONTAINS("SCHED_FIFO priority 50 refused", out.c_str());
  STRCMP_CONTAINS("CAP_SYS_NICE absent, RLIMIT_RTPRIO = 0", out.c_str());
  STRCMP_CONTAINS("mlockall(MCL_CURRENT|MCL_FUTURE) failed", out.c_str());
  STRCMP_CONTAINS("RLIMIT_MEMLOCK = 65536", out.c_str());
}

TEST(RtSetup, require_rt_refuses_instead_of_falling_back) {
  const std::string out = in_child([] { return unprivileged_setup(true); });
  STRCMP_CONTAINS("THROW rt.require_rt is set and real-time set-up is incomplete", out.c_str());
  STRCMP_CONTAINS("SCHED_FIFO priority 50 refused", out.c_str());
}

TEST(RtSetup, with_privileges_sched_fifo_and_pinning_take_effect) {
  rlimit rt{};
  getrlimit(RLIMIT_RTPRIO, &rt);
  const bool privileged = geteuid() == 0 || rt.rlim_cur >= 10;
  if (!privileged) {
    UT_PRINT("NOT CHECKED: no CAP_SYS_NICE / RLIMIT_RTPRIO here, SCHED_FIFO success path cannot run");
    return;
  }
  std::string summary;
  bool fifo = false, pinned = false;
  std::thread t([&] {
    RtConfig c;
    c.priority = 10;
    c.cpu = 0;
    c.lock_memory = false;  // keep the test process unlocked
    const RtReport r = apply_rt_config(c);
    fifo = r.sched_fifo && sched_getscheduler(0) == SCHED_FIFO;
    pinned = r.pinned && sched_getcpu() == 0;
    summary = r.summary();
  });
  t.join();
  CHECK_TEXT(fifo, summary.c_str());
  CHECK_TEXT(pinned, summary.c_str());
  STRCMP_CONTAINS("SCHED_FIFO priority 10, cpu 0", summary.c_str());
}

TEST(RtSetup, isolate_cpu_moves_the_other_threads_off_the_rt_core) {
  cpu_set_t before;
  CPU_ZERO(&before);
  sched_getaffinity(0, sizeof before, &before);
  if (CPU_COUNT(&before) < 2 || !CPU_ISSET(1, &before)) {
    UT_PRINT("NOT CHECKED: needs cpus 0 and 1 allowed to this process");
    return;
  }
  for (const bool isolate : {false, true}) {
    // A bystander thread that exists before the RT set-up (like LTTng's listener threads).
    std::atomic<bool> stop{false};
    std::atomic<pid_t> bystander_tid{0};
    std::thread bystander([&] {
      bystander_tid = static_cast<pid_t>(syscall(SYS_gettid));
      while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
    while (bystander_tid == 0) std::this_thread::yield();
    // And one pinned to the RT cpu alone: it must get the other cpus, not an empty set.
    std::atomic<pid_t> pinned_tid{0};
    std::thread pinned_there([&] {
      cpu_set_t one;
      CPU_ZERO(&one);
      CPU_SET(1, &one);
      sched_setaffinity(0, sizeof one, &one);
      pinned_tid = static_cast<pid_t>(syscall(SYS_gettid));
      while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
    while (pinned_tid == 0) std::this_thread::yield();
    int moved = -2;
    std::thread t([&] {
      RtConfig c;
      c.priority = 10;
      c.cpu = 1;
      c.lock_memory = false;
      c.isolate_cpu = isolate;
      moved = apply_rt_config(c).threads_moved_off;
    });
    t.join();
    cpu_set_t main_now, by_now, pinned_now;
    sched_getaffinity(0, sizeof main_now, &main_now);
    sched_getaffinity(bystander_tid, sizeof by_now, &by_now);
    sched_getaffinity(pinned_tid, sizeof pinned_now, &pinned_now);
    if (isolate) {
      CHECK(moved >= 3);  // at least this thread, the bystander and the pinned one
      CHECK_FALSE(CPU_ISSET(1, &main_now));
      CHECK_FALSE(CPU_ISSET(1, &by_now));
      CHECK(CPU_ISSET(0, &main_now));
      CHECK_FALSE(CPU_ISSET(1, &pinned_now));
      CHECK(CPU_ISSET(0, &pinned_now));
    } else {
      LONGS_EQUAL(-1, moved);
      CHECK(CPU_ISSET(1, &main_now));
      CHECK(CPU_ISSET(1, &by_now));
      CHECK(CPU_ISSET(1, &pinned_now) && CPU_COUNT(&pinned_now) == 1);
    }
    stop = true;
    bystander.join();
    pinned_there.join();
    sched_setaffinity(0, sizeof before, &before);  // leave the test process as it was
  }
}

TEST(RtSetup, rt_thread_rethrows_a_refusal_on_a_non_rt_kernel) {
  if (detect_kernel().preempt_rt) {
    UT_PRINT("NOT CHECKED: this kernel is PREEMPT_RT, so require_rt is not refused for the kernel");
    return;
  }
  RtConfig c;
  c.require_rt = true;
  c.lock_memory = false;
  bool body_ran = false;
  try {
    RtThread t(c, [&](const RtReport&) { body_ran = true; });
    FAIL("require_rt accepted on a non-PREEMPT_RT kernel");
  } catch (const std::runtime_error& e) {
    STRCMP_CONTAINS("is not PREEMPT_RT", e.what());
  }
  CHECK_FALSE(body_ran);
}

TEST(RtSetup, sched_other_thread_keeps_its_policy_and_reports_no_sched_fifo_failure) {
  // An I/O thread without RT priority (net: station.io_priority = 0): pinned if asked, no
  // SCHED_FIFO request, so no SCHED_FIFO warning and the thread runs SCHED_OTHER.
  RtConfig c;
  c.sched_fifo = false;
  c.priority = 0;  // unused, and not validated, without sched_fifo
  c.lock_memory = false;
  c.isolate_cpu = false;
  c.prefault_stack_bytes = 0;
  c.prefault_heap_bytes = 0;
  int policy = -1;
  RtThread t(c, [&](const RtReport&) { policy = sched_getscheduler(0); });
  t.join();
  CHECK_EQUAL(SCHED_OTHER, policy);
  for (const auto& w : t.setup_warnings()) CHECK_TEXT(w.find("SCHED_FIFO") == std::string::npos, w.c_str());
}
