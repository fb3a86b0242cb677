// haptic-jitter: cyclictest-style wake-up latency check of the station's periodic loop
// (platform/periodic_loop.hpp) at given periods, with and without a synthetic tick workload.
#include <algorithm>
#include <memory>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <thread>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "platform/rt_thread.hpp"
#include "platform/trace.hpp"
#include "tools/jitter/jitter.hpp"
#include "tools/jitter/station_workload.hpp"
#include "platform/command_line.hpp"

namespace {
std::atomic<bool> g_stop{false};  // set by SIGINT/SIGTERM (lock-free atomic: async-signal-safe)
void on_signal(int) { g_stop.store(true, std::memory_order_release); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// --record-blocks: pairs of station blocks, recording off and on, in alternating order (off-on,
// on-off, ...) so neither mode always runs first. Runs on the RT thread. Not RT-safe between blocks.
void record_compare_blocks(haptic::tools::StationJitterWorkload& station, const haptic::tools::JitterRunConfig& run, int pairs,
                           std::vector<haptic::tools::JitterResult>& results) {
  for (int i = 0; i < pairs && !g_stop.load(std::memory_order_acquire); ++i)
    for (int b = 0; b < 2; ++b) {
      station.set_recording((i % 2 == 0) == (b == 1));
      results.push_back(haptic::tools::run_jitter(run, station, g_stop));
      std::fputs(haptic::tools::format_result(results.back(), false).c_str(), stdout);
      std::fflush(stdout);
    }
  station.set_recording(false);
}

// Ratios recording on / off per block pair (medians over the pairs) of the wake-up latency P99
// and max and the tick execution time mean and P99, as text and as a JSON object.
std::string record_compare_summary(const std::vector<haptic::tools::JitterResult>& r, std::uint64_t dropped, std::string& json) {
  std::vector<double> p99, mx, ex, ex99;
  const auto on = [](const haptic::tools::JitterResult& x) { return x.workload.find("recording on") != std::string::npos; };
  for (std::size_t i = 0; i + 1 < r.size(); i += 2) {
    const auto& a = on(r[i]) ? r[i] : r[i + 1];
    const auto& b = on(r[i]) ? r[i + 1] : r[i];
    const auto ratio = [](double x, double y) { return y > 0 ? x / y : 0.0; };
    p99.push_back(ratio(a.stats.wake_latency.percentile_ns(0.99), b.stats.wake_latency.percentile_ns(0.99)));
    mx.push_back(ratio(a.stats.wake_latency.max_ns, b.stats.wake_latency.max_ns));
    ex.push_back(ratio(a.stats.exec_time.mean_ns(), b.stats.exec_time.mean_ns()));
    ex99.push_back(ratio(a.stats.exec_time.percentile_ns(0.99), b.stats.exec_time.percentile_ns(0.99)));
  }
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "recording on / off, median over %zu block pairs: wake-up latency P99 %.3f, max %.3f; tick execution time mean %.3f, "
                "P99 %.3f; records dropped %llu\n",
                p99.size(), median(p99), median(mx), median(ex), median(ex99), static_cast<unsigned long long>(dropped));
  char js[512];
  std::snprintf(js, sizeof js,
                "{\"pairs\": %zu, \"median_ratio_on_off\": {\"latency_p99\": %.4f, \"latency_max\": %.4f, \"exec_mean\": %.4f, "
                "\"exec_p99\": %.4f}, \"records_dropped\": %llu}",
                p99.size(), median(p99), median(mx), median(ex), median(ex99), static_cast<unsigned long long>(dropped));
  json = js;
  return buf;
}

// The command line: every option, its default and range, and what follows from them.
struct JitterOptions {
  std::vector<double> periods_us{1000, 2000};
  std::vector<double> workloads_us{0, 500};
  double duration_s = 10.0;
  std::uint64_t loops = 0;
  std::uint64_t overrun_every = 0;
  double histogram_bin_us = 1.0;
  bool histogram = false;
  bool quiet = false;
  double main_wake_ms = 10.0;  // like cyclictest's main loop (usleep(10000))
  bool no_isolate = false;
  bool no_mlock = false;
  bool station_workload = false;
  std::string json_path;
  int record_blocks = 0;
  std::string record_file = "/tmp/haptic-jitter-record.h5";
  haptic::platform::RtConfig rt;

  // Returns -1 to go on, else the exit code (--help: 0; a usage error: CLI11's).
  int parse(int argc, char** argv);
};

int JitterOptions::parse(int argc, char** argv) {
  using namespace haptic;
  CLI::App app{
      "haptic-jitter: wake-up latency of the station's periodic loop (absolute CLOCK_MONOTONIC deadlines,\n"
      "clock_nanosleep TIMER_ABSTIME), measured like cyclictest: latency = actual wake-up - deadline.\n"
      "Runs every combination of --period-us x --workload-us one after the other on one real-time thread\n"
      "and prints min/avg/max, P99/P99.9/P99.99 and optionally the histogram. Without a PREEMPT_RT kernel,\n"
      "CAP_SYS_NICE or mlockall it says so and measures anyway (unless --require-rt)."};
  rt.prefault_heap_bytes = 1u << 20;
  app.add_option("-i,--period-us", periods_us, "loop periods to measure, microseconds")->default_str("1000 2000")->check(CLI::Range(10.0, 1e6));
  app.add_option("-w,--workload-us", workloads_us, "busy-loop workload per tick, microseconds (0 = none)")->default_str("0 500")->check(CLI::Range(0.0, 1e6));
  app.add_option("-D,--duration-s", duration_s, "duration of each run, seconds (ticks = duration / period)")->capture_default_str()->check(CLI::Range(0.001, 86400.0));
  app.add_option("-l,--loops", loops, "ticks per run; overrides --duration-s (0 = use --duration-s)")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("--overrun-every", overrun_every, "make every Nth tick's workload last 1.5 periods to provoke overruns (0 = never)")->capture_default_str()->check(haptic::platform::kNonNegativeInteger);
  app.add_option("-p,--priority", rt.priority, "SCHED_FIFO priority, 1..98")->capture_default_str()->check(CLI::Range(1, 98));
  app.add_option("-a,--cpu", rt.cpu, "CPU to pin the measuring thread to (-1 = don't pin)")->capture_default_str()->check(CLI::Range(-1, 4095));
  app.add_flag("--station", station_workload,
               "also measure each period with the real station tick as the workload (paper-best scene, user 1: 33 nodes, "
               "3 neighbours fed synthetic packets, simulated device)");
  app.add_flag("--sched-other", [this](std::int64_t) { rt.sched_fifo = false; },
               "measure at SCHED_OTHER, as a station's non-real-time threads run (its I/O thread at io_priority = 0, its start-up)");
  app.add_flag("--no-mlock", no_mlock, "don't mlockall/prefault (default: lock memory like cyclictest -m)");
  app.add_flag("--dma-latency", rt.hold_dma_latency, "hold /dev/cpu_dma_latency at 0 us during the runs");
  app.add_flag("--require-rt", rt.require_rt, "refuse to run without PREEMPT_RT, SCHED_FIFO and locked memory");
  app.add_option("--histogram-bin-us", histogram_bin_us, "histogram bin width, microseconds (10000 bins)")->capture_default_str()->check(CLI::Range(0.001, 1000.0));
  app.add_flag("-H,--histogram", histogram, "print the non-empty histogram bins");
  app.add_option("--json", json_path, "also write all results as JSON to this file ('-' = stdout)");
  app.add_flag("-q,--quiet", quiet, "print only the per-run summary (no RT set-up lines)");
  app.add_option("--main-wake-ms", main_wake_ms,
                 "while the measuring thread runs, the main thread wakes every N ms (0 = it just blocks in join); "
                 "cyclictest's main thread wakes every 10 ms, and on a VM that changes the tails (tools/jitter/README.md)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  app.add_flag("--no-isolate", no_isolate, "leave the process's other threads on the measuring CPU (default: move them off, rt.isolate_cpu)");
  app.add_option("--record-blocks", record_blocks,
                 "with the station's tick: N pairs of blocks (each --duration-s or --loops) with the session recorder off and on, in alternating "
                 "order, then the on/off ratios (recording must not change the tick's timing); the other runs are skipped")
      ->check(CLI::Range(1, 1000));
  app.add_option("--record-file", record_file, "the session log the recording blocks write (HDF5, overwritten)")->capture_default_str();
  platform::add_version_flag(app, "haptic-jitter");
  // --help/--version: 0; a usage error (an unknown option with "did you mean"): 2, like a failed set-up below.
  if (const int rc = platform::parse_command_line(app, argc, argv, 2); rc >= 0) return rc;
  if (record_blocks > 0) station_workload = true;
  rt.lock_memory = !no_mlock;
  rt.isolate_cpu = !no_isolate;
  return -1;
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

// One run at `period_us`: --loops ticks, else --duration-s worth of them.
haptic::tools::JitterRunConfig run_config(const JitterOptions& o, double period_us) {
  haptic::tools::JitterRunConfig run;
  run.period_ns = static_cast<std::int64_t>(period_us * 1e3);
  run.ticks = o.loops != 0 ? o.loops : static_cast<std::uint64_t>(o.duration_s * 1e6 / period_us);
  run.histogram_bin_ns = static_cast<std::int64_t>(o.histogram_bin_us * 1e3);
  return run;
}

// Every run at one period, printed as it ends: the recording blocks alone (--record-blocks), else
// each --workload-us busy loop and then the station's tick (--station). Runs on the RT thread.
void measure_period(const JitterOptions& o, double period_us, haptic::tools::StationJitterWorkload* station,
                    std::vector<haptic::tools::JitterResult>& results) {
  using namespace haptic;
  if (o.record_blocks > 0) {
    record_compare_blocks(*station, run_config(o, period_us), o.record_blocks, results);
    return;
  }
  for (double workload_us : o.workloads_us) {
    if (g_stop.load(std::memory_order_acquire)) break;
    const tools::JitterRunConfig run = run_config(o, period_us);
    tools::BusyLoopWorkload workload(static_cast<std::int64_t>(workload_us * 1e3), o.overrun_every, 1.5, run.period_ns);
    results.push_back(tools::run_jitter(run, workload, g_stop));
    std::fputs(tools::format_result(results.back(), o.histogram).c_str(), stdout);
    std::fflush(stdout);
  }
  if (station && !g_stop.load(std::memory_order_acquire)) {
    results.push_back(tools::run_jitter(run_config(o, period_us), *station, g_stop));
    std::fputs(tools::format_result(results.back(), o.histogram).c_str(), stdout);
    std::fflush(stdout);
  }
}

// Every run on one real-time thread; `json` gets the results (and the recording comparison).
// Returns 0, or 2 when the set-up failed (said on stderr).
int measure(const JitterOptions& o, std::vector<haptic::tools::JitterResult>& results, std::string& json) {
  using namespace haptic;
  try {
    // Built (and factored) before the real-time thread starts: construction allocates.
    std::unique_ptr<tools::StationJitterWorkload> station;
    if (o.station_workload) station = std::make_unique<tools::StationJitterWorkload>("paper-best");
    std::unique_ptr<firmware::SessionRecorder> recorder;
    if (o.record_blocks > 0) {
      firmware::RecorderConfig rc;
      rc.path = o.record_file;
      firmware::SessionInfo info;
      info.config_text = "haptic-jitter --record-blocks";
      recorder = std::make_unique<firmware::SessionRecorder>(rc, info, station->core().config());
      station->attach_recorder(recorder.get());
    }
    std::string compare_json;
    std::atomic<bool> finished{false};
    platform::RtThread thread(o.rt, [&](const platform::RtReport& report) {
      for (double period_us : o.periods_us) measure_period(o, period_us, station.get(), results);
      json = tools::to_json(results, report, o.rt);
      finished.store(true, std::memory_order_release);
    });
    if (!o.quiet) {
      std::fputs(thread.setup_summary().c_str(), stdout);
      std::printf("trace: LTTng tracepoints %s\n", platform::trace::kCompiledIn ? "compiled in (provider 'haptic')" : "compiled out");
      std::fflush(stdout);
    }
    if (o.main_wake_ms > 0) {
      const auto step = std::chrono::duration<double, std::milli>(o.main_wake_ms);
      while (!finished.load(std::memory_order_acquire)) std::this_thread::sleep_for(step);
    }
    thread.join();
    if (recorder) {
      const firmware::RecorderStats st = recorder->finish();
      std::fputs(record_compare_summary(results, st.dropped_records, compare_json).c_str(), stdout);
      json.erase(json.rfind('}'));
      json += ",\n  \"record_compare\": " + compare_json + ",\n  \"record_file\": \"" + o.record_file + "\"\n}\n";
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic-jitter: %s\n", e.what());
    return 2;
  }
  return 0;
}

// --json: to a file, or to stdout for '-'. Returns 0, or 1 when the file cannot be written.
int write_json(const std::string& json_path, const std::string& json) {
  if (json_path.empty()) return 0;
  if (json_path == "-") {
    std::fputs(json.c_str(), stdout);
    return 0;
  }
  std::ofstream out(json_path);
  out << json;
  if (!out) {
    std::fprintf(stderr, "haptic-jitter: cannot write %s\n", json_path.c_str());
    return 1;
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  JitterOptions options;
  if (const int rc = options.parse(argc, argv); rc >= 0) return rc;
  install_signal_handlers();
  std::vector<haptic::tools::JitterResult> results;
  std::string json;
  if (const int rc = measure(options, results, json); rc != 0) return rc;
  if (const int rc = write_json(options.json_path, json); rc != 0) return rc;
  return g_stop.load() ? 130 : 0;
}
