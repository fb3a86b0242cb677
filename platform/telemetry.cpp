#include "platform/telemetry.hpp"
#include "platform/clock.hpp"

#include <time.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace haptic::platform {

const char* to_string(FaultKind kind) {
  switch (kind) {
    case FaultKind::none: return "none";
    case FaultKind::overrun_storm: return "overrun_storm";
    case FaultKind::device_fault: return "device_fault";
    case FaultKind::divergence: return "divergence";
    case FaultKind::other: return "other";
  }
  return "unknown";
}

Telemetry::Telemetry(const TelemetryConfig& config) : config_(config), ring_(std::make_unique<Ring>()) {
  if (!(config_.period_s > 0.0) || config_.period_s > 1.0) {
    throw std::invalid_argument("telemetry.period_s = " + std::to_string(config_.period_s) + ": allowed range is (0, 1]");
  }
  if (!(config_.postmortem_s >= 0.1) || config_.postmortem_s > 600.0) {
    throw std::invalid_argument("telemetry.postmortem_s = " + std::to_string(config_.postmortem_s) + ": allowed range is 0.1..600");
  }
  if (config_.max_dumps < 1) throw std::invalid_argument("telemetry.max_dumps = 0: allowed range is >= 1");
  if (config_.drain_period_ns < 100'000 || config_.drain_period_ns > 1'000'000'000) {
    throw std::invalid_argument("telemetry.drain_period_ns = " + std::to_string(config_.drain_period_ns) +
                                ": allowed range is 100000..1000000000");
  }
  if (config_.value_names.size() > TelemetryRecord::kValues) {
    throw std::invalid_argument("telemetry.value_names has " + std::to_string(config_.value_names.size()) +
                                " names: allowed range is 0.." + std::to_string(TelemetryRecord::kValues));
  }
  history_.resize(static_cast<std::size_t>(std::ceil(config_.postmortem_s / config_.period_s)));
  if (!config_.path.empty()) {
    file_ = std::fopen(config_.path.c_str(), "w");
    if (file_ == nullptr) {
      throw std::runtime_error("telemetry.path = \"" + config_.path + "\": cannot create: " + std::strerror(errno));
    }
    write_header(file_);
  }
  logger_ = std::thread([this] { logger_main(); });
}

Telemetry::~Telemetry() {
  stop_.store(true, std::memory_order_release);
  if (logger_.joinable()) logger_.join();
  if (file_ != nullptr) std::fclose(file_);
}

void Telemetry::write_header(std::FILE* f) const {
  std::fputs("tick,scheduled_ns,wake_latency_ns,exec_ns,overruns,status", f);
  for (const auto& name : config_.value_names) std::fprintf(f, ",%s", name.c_str());
  std::fputc('\n', f);
}

void Telemetry::write_line(std::FILE* f, const TelemetryRecord& r) const {
  std::fprintf(f, "%" PRIu64 ",%" PRId64 ",%" PRId32 ",%" PRId32 ",%" PRIu32 ",%" PRIu32, r.tick, r.scheduled_ns,
               r.wake_latency_ns, r.exec_ns, r.overruns, r.status);
  for (std::size_t i = 0; i < config_.value_names.size(); ++i) std::fprintf(f, ",%.9g", r.values[i]);
  std::fputc('\n', f);
}

std::size_t Telemetry::drain() {
  std::size_t n = 0;
  TelemetryRecord r;
  while (ring_->reader_try_pop(r)) {
    if (file_ != nullptr) write_line(file_, r);
    history_[history_next_] = r;
    history_next_ = (history_next_ + 1) % history_.size();
    if (history_count_ < history_.size()) ++history_count_;
    ++n;
  }
  if (n != 0) {
    if (file_ != nullptr) std::fflush(file_);
    written_.fetch_add(n, std::memory_order_release);
  }
  return n;
}

void Telemetry::dump(FaultKind kind, std::uint64_t tick) {
  if (dumps_.load(std::memory_order_relaxed) >= config_.max_dumps) return;
  const std::string path = config_.postmortem_dir + "/postmortem-" + to_string(kind) + "-tick" + std::to_string(tick) + ".csv";
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    std::fprintf(stderr, "telemetry: cannot write post-mortem %s: %s\n", path.c_str(), std::strerror(errno));
    return;
  }
  std::fprintf(f, "# post-mortem: fault %s reported at tick %" PRIu64 ", last %zu records\n", to_string(kind), tick, history_count_);
  write_header(f);
  const std::size_t start = (history_next_ + history_.size() - history_count_) % history_.size();
  for (std::size_t i = 0; i < history_count_; ++i) write_line(f, history_[(start + i) % history_.size()]);
  std::fclose(f);
  {
    std::lock_guard lock(dump_path_mutex_);
    last_dump_path_ = path;
  }
  dumps_.fetch_add(1, std::memory_order_release);
  std::fprintf(stderr, "telemetry: fault %s at tick %" PRIu64 ": post-mortem of %zu records in %s\n", to_string(kind), tick,
               history_count_, path.c_str());
}

void Telemetry::logger_main() {
  std::int64_t next_ns = monotonic_ns();
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    const std::uint64_t flush_wanted = flush_request_.load(std::memory_order_acquire);
    drain();
    const std::uint32_t fault = pending_fault_.load(std::memory_order_acquire);
    if (fault != 0) {
      dump(static_cast<FaultKind>(fault), pending_fault_tick_.load(std::memory_order_acquire));
      pending_fault_.store(0, std::memory_order_release);
    }
    flush_done_.store(flush_wanted, std::memory_order_release);
    if (stopping) break;
    next_ns += static_cast<std::int64_t>(config_.drain_period_ns);
    sleep_until_monotonic_ns(next_ns);
  }
}

void Telemetry::flush() {
  const std::uint64_t ticket = flush_request_.fetch_add(1, std::memory_order_acq_rel) + 1;
  while (flush_done_.load(std::memory_order_acquire) < ticket) {
    timespec ts{0, 1'000'000};
    nanosleep(&ts, nullptr);
  }
}

std::string Telemetry::last_dump_path() const {
  std::lock_guard lock(dump_path_mutex_);
  return last_dump_path_;
}

}  // namespace haptic::platform
