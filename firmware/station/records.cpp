#include "firmware/station/records.hpp"

#include <chrono>
#include <stdexcept>

namespace haptic::firmware {

void RowWindow::reset(std::size_t slots) {
  std::size_t n = 2;
  while (n < slots) n *= 2;
  mask_ = n - 1;
  head_.store(0, std::memory_order_relaxed);
  tail_.store(0, std::memory_order_relaxed);
  cached_tail_ = cached_head_ = 0;
}

void TickRecords::reserve(std::size_t trace_n, std::size_t state_n, int d) {
  trace_window.reset(trace_n);
  state_window.reset(state_n);
  dofs = d;
  trace.assign(trace_window.slots(), TraceRec{});
  state_k.assign(state_window.slots(), 0);
  state_x.assign(state_window.slots() * static_cast<std::size_t>(d), 0.0);
  trace_rows = state_rows = trace_lost = state_lost = 0;
}

std::size_t TickRecords::window_bytes(std::size_t trace_n, std::size_t state_n, int d) {
  RowWindow t, s;
  t.reset(trace_n);
  s.reset(state_n);
  return t.slots() * sizeof(TraceRec) + s.slots() * (sizeof(std::int64_t) + static_cast<std::size_t>(d) * sizeof(double));
}

void write_station_trace_header(std::FILE* f) {
  std::fprintf(f, "k,t_s,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,device_x_m,device_y_m,device_z_m,"
                  "port_energy_J,controller_energy_J,vo_energy_J,contact,flags,max_speed_m_per_s,wake_latency_ns,step_s\n");
}

void write_station_trace_row(std::FILE* f, const TraceRec& r, double T) {
  std::fprintf(f, "%lld,%.4f,%.9g,%.9g,%.9g,%.7g,%.7g,%.7g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%d,%u,%.6g,%d,%.9g\n", static_cast<long long>(r.k),
               static_cast<double>(r.k + 1) * T, r.node[0], r.node[1], r.node[2], r.force[0], r.force[1], r.force[2], r.vp[0], r.vp[1], r.vp[2], r.device[0],
               r.device[1], r.device[2], r.port_J, r.ctrl_J, r.vo_J, r.contact, r.flags, r.max_speed, r.wake_latency_ns, r.step_s);
}

void write_station_state_header(std::FILE* f, int dofs) {
  std::fprintf(f, "k");
  for (int d = 0; d < dofs; ++d) std::fprintf(f, ",x%d", d);
  std::fprintf(f, "\n");
}

void write_station_state_row(std::FILE* f, std::int64_t k, const double* x, int dofs) {
  std::fprintf(f, "%lld", static_cast<long long>(k));
  for (int d = 0; d < dofs; ++d) std::fprintf(f, ",%.10g", x[d]);
  std::fprintf(f, "\n");
}

namespace {
std::FILE* open_csv(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  return f;
}
}  // namespace

RecordFiles::RecordFiles(const std::string& base, double period_s, TickRecords& rec)
    : rec_(rec), period_s_(period_s), trace_path_(base + "-trace.csv"), state_path_(base + "-state.csv") {
  trace_ = open_csv(trace_path_);
  try {
    state_ = open_csv(state_path_);
  } catch (...) {
    std::fclose(trace_);
    throw;
  }
  write_station_trace_header(trace_);
  write_station_state_header(state_, rec_.dofs);
  thread_ = std::thread([this] { writer_main(); });
}

RecordFiles::~RecordFiles() { finish(); }

// Every filled slot of both windows, oldest first, appended to its file.
void RecordFiles::drain() {
  for (std::size_t i = rec_.trace_window.reader_slot(); i != RowWindow::kNone; i = rec_.trace_window.reader_slot()) {
    write_station_trace_row(trace_, rec_.trace[i], period_s_);
    rec_.trace_window.reader_release();
  }
  const auto d = static_cast<std::size_t>(rec_.dofs);
  for (std::size_t i = rec_.state_window.reader_slot(); i != RowWindow::kNone; i = rec_.state_window.reader_slot()) {
    write_station_state_row(state_, rec_.state_k[i], rec_.state_x.data() + i * d, rec_.dofs);
    rec_.state_window.reader_release();
  }
}

// Drains every 20 ms; after stop_ (set once the tick wrote its last row) one last drain.
void RecordFiles::writer_main() {
  for (;;) {
    const bool last = stop_.load(std::memory_order_acquire);
    drain();
    if (last) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

std::string RecordFiles::finish() {
  if (finished_) return error_;
  finished_ = true;
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  const bool trace_bad = std::ferror(trace_) != 0, state_bad = std::ferror(state_) != 0;
  if (std::fclose(trace_) != 0 || trace_bad) error_ = "cannot write " + trace_path_;
  if ((std::fclose(state_) != 0 || state_bad) && error_.empty()) error_ = "cannot write " + state_path_;
  return error_;
}

}  // namespace haptic::firmware
