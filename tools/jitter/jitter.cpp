#include "tools/jitter/jitter.hpp"

#include <cinttypes>
#include <cstdarg>
#include <cstdio>
#include <memory>
#include <sstream>

#include "platform/trace.hpp"

namespace haptic::tools {
namespace {

std::string fmt(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

double us(std::int64_t ns) { return static_cast<double>(ns) / 1e3; }

std::string json_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt("\\u%04x", c);
    } else {
      out += c;
    }
  }
  return out;
}

std::string histogram_json(const platform::LatencyHistogram& h) {
  std::ostringstream os;
  os << "{\"bin_us\": " << us(h.bin_ns) << ", \"overflow\": " << h.overflow << ", \"bins\": [";
  bool first = true;
  for (std::size_t i = 0; i < h.counts.size(); ++i) {
    if (h.counts[i] == 0) continue;
    os << (first ? "" : ", ") << "[" << us(static_cast<std::int64_t>(i) * h.bin_ns) << ", " << h.counts[i] << "]";
    first = false;
  }
  os << "]}";
  return os.str();
}

std::string summary_json(const platform::LatencyHistogram& h) {
  return fmt("{\"samples\": %" PRIu64 ", \"min\": %.3f, \"avg\": %.3f, \"max\": %.3f, \"p99\": %.3f, \"p999\": %.3f, \"p9999\": %.3f}",
             h.samples, h.samples ? us(h.min_ns) : 0.0, h.mean_ns() / 1e3, h.samples ? us(h.max_ns) : 0.0,
             us(h.percentile_ns(0.99)), us(h.percentile_ns(0.999)), us(h.percentile_ns(0.9999)));
}

}  // namespace

void BusyLoopWorkload::tick(const platform::TickInfo& info) {
  const std::int64_t spin = (overrun_every_ != 0 && info.index % overrun_every_ == overrun_every_ - 1) ? overrun_ns_ : busy_ns_;
  if (spin <= 0) return;
  platform::trace::StageScope stage(platform::trace::Stage::workload);
  const platform::MonotonicClock clock;
  const std::int64_t until = info.wake_ns + spin;
  while (clock.now_ns() < until) {
  }
}

std::string BusyLoopWorkload::name() const {
  std::string n = fmt("busy %.0f us", us(busy_ns_));
  if (overrun_every_ != 0) n += fmt(", every %" PRIu64 "th tick %.0f us", overrun_every_, us(overrun_ns_));
  return n;
}

JitterResult run_jitter(const JitterRunConfig& config, JitterWorkload& workload, const std::atomic<bool>& stop) {
  platform::LoopConfig loop_config;
  loop_config.period_ns = config.period_ns;
  loop_config.max_ticks = config.ticks;
  loop_config.histogram_bin_ns = config.histogram_bin_ns;
  auto loop = std::make_unique<platform::PeriodicLoop<>>(loop_config);  // ~35 KiB of histograms: heap, not stack
  loop->run(
      [&](const platform::TickInfo& info) {
        workload.tick(info);
        return true;
      },
      stop);
  JitterResult r;
  r.period_ns = config.period_ns;
  r.workload = workload.name();
  r.stats = loop->stats();
  r.interrupted = r.stats.ticks < config.ticks;
  return r;
}

std::string format_result(const JitterResult& r, bool with_histogram) {
  const auto& lat = r.stats.wake_latency;
  const auto& exec = r.stats.exec_time;
  std::string s = fmt("period %.0f us, workload %s: %" PRIu64 " ticks%s, %" PRIu64 " overruns (%" PRIu64 " missed cycles)\n",
                      us(r.period_ns), r.workload.c_str(), r.stats.ticks, r.interrupted ? " (interrupted)" : "",
                      r.stats.overruns, r.stats.missed_cycles);
  s += fmt("  wake-up latency us: min %.1f  avg %.1f  max %.1f  P99 %.1f  P99.9 %.1f  P99.99 %.1f\n", us(lat.min_ns),
           lat.mean_ns() / 1e3, us(lat.max_ns), us(lat.percentile_ns(0.99)), us(lat.percentile_ns(0.999)),
           us(lat.percentile_ns(0.9999)));
  s += fmt("  tick execution us: min %.1f  avg %.1f  max %.1f  P99 %.1f\n", us(exec.min_ns), exec.mean_ns() / 1e3,
           us(exec.max_ns), us(exec.percentile_ns(0.99)));
  if (with_histogram) {
    s += fmt("  histogram of wake-up latency (bin %.0f us: count)\n", us(lat.bin_ns));
    for (std::size_t i = 0; i < lat.counts.size(); ++i) {
      if (lat.counts[i] != 0) s += fmt("  %6.0f %" PRIu64 "\n", us(static_cast<std::int64_t>(i) * lat.bin_ns), lat.counts[i]);
    }
    if (lat.overflow != 0) s += fmt("  >=%.0f %" PRIu64 "\n", us(static_cast<std::int64_t>(lat.counts.size()) * lat.bin_ns), lat.overflow);
  }
  return s;
}

std::string to_json(const std::vector<JitterResult>& runs, const platform::RtReport& rt, const platform::RtConfig& rt_config) {
  std::ostringstream os;
  os << "{\n  \"tool\": \"haptic-jitter\",\n";
  os << "  \"kernel\": {\"release\": \"" << json_escape(rt.kernel.uname_release) << "\", \"version\": \""
     << json_escape(rt.kernel.uname_version) << "\", \"preempt_rt\": " << (rt.kernel.preempt_rt ? "true" : "false") << "},\n";
  os << "  \"rt\": {\"sched_fifo\": " << (rt.sched_fifo ? "true" : "false") << ", \"priority\": " << rt.priority
     << ", \"requested_priority\": " << rt_config.priority << ", \"cpu\": " << rt.cpu << ", \"memory_locked\": "
     << (rt.memory_locked ? "true" : "false") << ", \"dma_latency_held\": " << (rt.dma_latency.held() ? "true" : "false")
     << ", \"warnings\": [";
  for (std::size_t i = 0; i < rt.warnings.size(); ++i) os << (i ? ", " : "") << "\"" << json_escape(rt.warnings[i]) << "\"";
  os << "]},\n  \"runs\": [\n";
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    os << "    {\"period_us\": " << us(r.period_ns) << ", \"workload\": \"" << json_escape(r.workload) << "\", \"ticks\": "
       << r.stats.ticks << ", \"interrupted\": " << (r.interrupted ? "true" : "false") << ", \"overruns\": " << r.stats.overruns
       << ", \"missed_cycles\": " << r.stats.missed_cycles << ",\n     \"latency_us\": " << summary_json(r.stats.wake_latency)
       << ",\n     \"exec_us\": " << summary_json(r.stats.exec_time)
       << ",\n     \"latency_histogram\": " << histogram_json(r.stats.wake_latency) << "}" << (i + 1 < runs.size() ? "," : "")
       << "\n";
  }
  os << "  ]\n}\n";
  return os.str();
}

}  // namespace haptic::tools
