#include "firmware/session/recorder.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "platform/clock.hpp"

namespace haptic::firmware {

namespace {
enum SlotType : std::uint32_t { kTick = 1, kPacket = 2, kInitial = 3, kData = 4 };
constexpr std::int64_t kDrainPeriodNs = 5'000'000;

std::size_t data_slots(int dofs) { return (2 * static_cast<std::size_t>(dofs) + kSlotDoubles - 1) / kSlotDoubles; }
}  // namespace

// The writer thread's side: the file, its appendable datasets, the rows assembled from slots.
struct SessionRecorder::Writer {
  h5::Id file;
  h5::Id ticks_g, packets_g;
  h5::Appendable k, q, force, vp, port, ctrl, vo, hash, flags, contact, wake, exec, dropped, step;
  h5::Appendable p_tick, p_nbr, p_seq, p_send, p_x, p_v;
  int dofs = 0;
  bool float32 = false;
  RecorderStats st;
  bool stopped_writing = false;  // max_bytes reached or I/O error
  // Assembly of a multi-slot record
  RecordSlot head{};
  std::vector<double> values;
  std::size_t filled = 0;
  // Rows waiting for the next append
  std::vector<TickRecord> tick_rows;
  std::vector<std::int64_t> pk_tick, pk_seq, pk_nbr;
  std::vector<double> pk_send, pk_x, pk_v;

  Writer(const RecorderConfig& cfg, const SessionInfo& info, const rt::StationConfig& core) {
    dofs = core.scene->dofs;
    float32 = info.packets_float32;
    file = h5::create_file(cfg.path);
    write_session_header(file.get(), info, core);
    ticks_g = h5::create_group(file.get(), kTicksGroup);
    packets_g = h5::create_group(file.get(), kPacketsGroup);
    const hid_t t = ticks_g.get(), p = packets_g.get();
    const std::uint64_t rt = cfg.ring_ticks, rp = rt ? ring_packet_rows(rt, static_cast<int>(core.neighbors.size())) : 0;
    const auto n = static_cast<std::uint64_t>(dofs);
    const auto tick_field = [&](TickField f) { return create_field(t, kTickFields[f], n, float32, 4096, 0, rt); };
    k = tick_field(kTickK), q = tick_field(kTickQ), force = tick_field(kTickForce), vp = tick_field(kTickVp);
    port = tick_field(kTickPortJ), ctrl = tick_field(kTickControllerJ), vo = tick_field(kTickVoJ), hash = tick_field(kTickHash);
    flags = tick_field(kTickFlags), contact = tick_field(kTickContact), wake = tick_field(kTickWakeLatency), exec = tick_field(kTickExec);
    dropped = tick_field(kTickDropped), step = tick_field(kTickStep);
    const auto chunk = std::max<std::uint64_t>(1, (1u << 18) / (n * (float32 ? 4 : 8)));
    // A ring overwrites its chunks in place; deflated chunks change size, so a ring is not deflated.
    const int deflate = rt ? 0 : cfg.deflate_level;
    p_tick = create_field(p, kPacketFields[kPacketTick], n, float32, 4096, 0, rp);
    p_nbr = create_field(p, kPacketFields[kPacketNeighbour], n, float32, 4096, 0, rp);
    p_seq = create_field(p, kPacketFields[kPacketSeq], n, float32, 4096, 0, rp);
    p_send = create_field(p, kPacketFields[kPacketSendTime], n, float32, 4096, 0, rp);
    p_x = create_field(p, kPacketFields[kPacketX], n, float32, chunk, deflate, rp);
    p_v = create_field(p, kPacketFields[kPacketV], n, float32, chunk, deflate, rp);
  }

  // The ticks the log holds, as attributes (ring or not). Not RT-safe.
  void write_extent_attrs(const RecorderConfig& cfg) {
    const auto oldest = [](const h5::Appendable& a, hid_t g, const char* name) -> std::int64_t {
      if (a.rows() == 0) return 0;
      const std::vector<std::int64_t> v = h5::read_i64(g, name);
      return *std::min_element(v.begin(), v.end());
    };
    st.first_tick = oldest(k, ticks_g.get(), "k");
    st.packets_complete_from_tick = p_tick.total() > p_tick.rows() ? oldest(p_tick, packets_g.get(), "tick") + 1 : 0;
    const hid_t f = file.get();
    h5::attr(f, "ring_ticks", static_cast<std::int64_t>(cfg.ring_ticks));
    h5::attr(f, "first_tick", st.first_tick);
    h5::attr(f, "packets_complete_from_tick", std::max(st.first_tick, st.packets_complete_from_tick));
    h5::attr(ticks_g.get(), "ring_next_row", static_cast<std::int64_t>(k.next_row() % std::max<std::uint64_t>(1, k.rows())));
    h5::attr(packets_g.get(), "ring_next_row", static_cast<std::int64_t>(p_tick.next_row() % std::max<std::uint64_t>(1, p_tick.rows())));
  }

  std::uint64_t packet_bytes() const { return 32 + 2 * static_cast<std::uint64_t>(dofs) * (float32 ? 4 : 8); }

  // Accepts (or, past the size bound, refuses) the row of tick k with `bytes`.
  bool admit(std::int64_t tick, std::uint64_t bytes, std::uint64_t max_bytes, bool ring) {
    if (stopped_writing) return false;
    if (!ring && st.bytes + bytes > max_bytes) {  // a ring's size is bounded by its rows (checked at plan time)
      stopped_writing = true;
      st.truncated_at_tick = tick;
      return false;
    }
    st.bytes += bytes;
    return true;
  }

  void count_lossy(const double* x, std::size_t n) {
    if (!float32) return;
    for (std::size_t i = 0; i < n; ++i)
      if (static_cast<double>(static_cast<float>(x[i])) != x[i] && x[i] == x[i]) ++st.lossy_packet_values;
  }

  void complete(const RecorderConfig& cfg) {
    const auto n = static_cast<std::size_t>(dofs);
    if (head.type == kInitial) {
      write_initial_state(file.get(), values.data(), values.data() + n, n);
      return;
    }
    if (!admit(head.a, packet_bytes(), cfg.max_bytes, cfg.ring_ticks > 0)) return;
    count_lossy(values.data(), 2 * n);
    pk_tick.push_back(head.a);
    pk_seq.push_back(head.b);
    pk_nbr.push_back(head.aux);
    pk_send.push_back(head.c);
    pk_x.insert(pk_x.end(), values.begin(), values.begin() + static_cast<std::ptrdiff_t>(n));
    pk_v.insert(pk_v.end(), values.begin() + static_cast<std::ptrdiff_t>(n), values.end());
  }

  void take(const RecordSlot& s, const RecorderConfig& cfg) {
    if (s.type == kTick) {
      TickRecord r;
      std::memcpy(&r, s.payload, sizeof r);
      if (admit(r.k, 128, cfg.max_bytes, cfg.ring_ticks > 0)) tick_rows.push_back(r);
    } else if (s.type == kPacket || s.type == kInitial) {
      head = s;
      values.assign(2 * static_cast<std::size_t>(dofs), 0.0);
      filled = 0;
    } else if (s.type == kData) {
      const std::size_t m = std::min<std::size_t>(s.aux, values.size() - filled);
      std::copy(s.payload, s.payload + m, values.begin() + static_cast<std::ptrdiff_t>(filled));
      filled += m;
      if (filled == values.size()) complete(cfg);
    }
  }

  void flush() {
    using h5::Type;
    const auto nt = tick_rows.size();
    if (nt > 0) {
      std::vector<std::int64_t> kk(nt);
      std::vector<double> q3(3 * nt), f3(3 * nt), y3(3 * nt), pj(nt), cj(nt), vj(nt), sk(nt);
      std::vector<std::uint64_t> hh(nt);
      std::vector<std::uint32_t> fl(nt), dr(nt);
      std::vector<std::uint8_t> ct(nt);
      std::vector<std::int32_t> wl(nt), ex(nt);
      for (std::size_t i = 0; i < nt; ++i) {
        const TickRecord& r = tick_rows[i];
        kk[i] = r.k;
        for (int a = 0; a < 3; ++a) {
          q3[3 * i + a] = r.q[a];
          f3[3 * i + a] = r.force[a];
          y3[3 * i + a] = r.vp[a];
        }
        pj[i] = r.port_J, cj[i] = r.controller_J, vj[i] = r.vo_J, hh[i] = r.hash, fl[i] = r.flags, dr[i] = r.dropped;
        ct[i] = r.contact, wl[i] = r.wake_latency_ns, ex[i] = r.exec_ns, sk[i] = r.step_s;
      }
      k.append(Type::kI64, kk.data(), nt), q.append(Type::kF64, q3.data(), nt), force.append(Type::kF64, f3.data(), nt);
      vp.append(Type::kF64, y3.data(), nt), port.append(Type::kF64, pj.data(), nt), ctrl.append(Type::kF64, cj.data(), nt);
      vo.append(Type::kF64, vj.data(), nt), hash.append(Type::kU64, hh.data(), nt), flags.append(Type::kU32, fl.data(), nt);
      contact.append(Type::kU8, ct.data(), nt), wake.append(Type::kI32, wl.data(), nt), exec.append(Type::kI32, ex.data(), nt);
      dropped.append(Type::kU32, dr.data(), nt), step.append(Type::kF64, sk.data(), nt);
      st.ticks += nt;
      tick_rows.clear();
    }
    const auto np = pk_tick.size();
    if (np > 0) {
      p_tick.append(Type::kI64, pk_tick.data(), np), p_seq.append(Type::kI64, pk_seq.data(), np), p_nbr.append(Type::kI64, pk_nbr.data(), np);
      p_send.append(Type::kF64, pk_send.data(), np), p_x.append(Type::kF64, pk_x.data(), np), p_v.append(Type::kF64, pk_v.data(), np);
      st.packets += np;
      pk_tick.clear(), pk_seq.clear(), pk_nbr.clear(), pk_send.clear(), pk_x.clear(), pk_v.clear();
    }
  }
};

SessionRecorder::SessionRecorder(const RecorderConfig& config, const SessionInfo& info, const rt::StationConfig& core)
    : cfg_(config), dofs_(core.scene->dofs) {
  if (data_slots(dofs_) + 2 > kRingSlots / 4) throw std::runtime_error("session recorder: scene too large for the ring (" + std::to_string(dofs_) + " dofs)");
  writer_ = std::make_unique<Writer>(cfg_, info, core);
  ring_ = std::make_unique<platform::SpscRing<RecordSlot, kRingSlots>>();
  thread_ = std::thread([this] { writer_main(); });
}

SessionRecorder::~SessionRecorder() {
  try {
    finish();
  } catch (...) {  // a destructor must not throw; finish() reported nothing we could act on here
  }
}

bool SessionRecorder::reserve(std::size_t slots) {
  for (;;) {
    if (kRingSlots - ring_->size() >= slots) return true;  // size() over-estimates from this side: room is certain
    if (!cfg_.lossless) return false;
    std::this_thread::yield();
  }
}

void SessionRecorder::push_values(std::uint32_t type, std::uint32_t aux, std::int64_t a, std::int64_t b, double c, const double* x, const double* v) {
  const std::size_t n = static_cast<std::size_t>(dofs_), total = 2 * n;
  if (!reserve(1 + data_slots(dofs_))) {
    ++dropped_since_tick_;
    dropped_total_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  RecordSlot s;
  s.type = type, s.aux = aux, s.a = a, s.b = b, s.c = c;
  ring_->writer_try_push(s);
  for (std::size_t off = 0; off < total; off += kSlotDoubles) {
    RecordSlot d;
    d.type = kData;
    d.aux = static_cast<std::uint32_t>(std::min(kSlotDoubles, total - off));
    for (std::size_t i = 0; i < d.aux; ++i) d.payload[i] = off + i < n ? x[off + i] : v[off + i - n];
    ring_->writer_try_push(d);
  }
}

void SessionRecorder::rt_initial_state(const double* x, const double* v) { push_values(kInitial, 0, 0, 0, 0, x, v); }

void SessionRecorder::rt_packet(std::int64_t kr, int neighbour, std::int64_t seq, double send_time_s, const double* x, const double* v) {
  push_values(kPacket, static_cast<std::uint32_t>(neighbour), kr, seq, send_time_s, x, v);
}

void SessionRecorder::rt_tick(const TickRecord& r) {
  if (!reserve(1)) {
    ++dropped_since_tick_;
    dropped_total_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  RecordSlot s;
  s.type = kTick;
  TickRecord row = r;
  row.dropped = dropped_since_tick_;
  std::memcpy(s.payload, &row, sizeof row);
  ring_->writer_try_push(s);
  dropped_since_tick_ = 0;
}

void SessionRecorder::writer_main() {
  RecordSlot s;
  std::int64_t next = platform::monotonic_ns();
  for (;;) {
    const bool last = stop_.load(std::memory_order_acquire);  // drain once more after the stop request
    try {
      while (ring_->reader_try_pop(s)) writer_->take(s, cfg_);
      if (!writer_->stopped_writing || !writer_->tick_rows.empty() || !writer_->pk_tick.empty()) writer_->flush();
    } catch (const std::exception& e) {
      if (writer_->st.error.empty()) writer_->st.error = e.what();
      writer_->stopped_writing = true;
      writer_->tick_rows.clear();
      writer_->pk_tick.clear(), writer_->pk_seq.clear(), writer_->pk_nbr.clear(), writer_->pk_send.clear(), writer_->pk_x.clear(), writer_->pk_v.clear();
    }
    if (last) return;
    next += kDrainPeriodNs;
    platform::sleep_until_monotonic_ns(next);
  }
}

RecorderStats SessionRecorder::finish() {
  if (finished_) return final_;
  finished_ = true;
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  Writer& w = *writer_;
  w.st.dropped_records = dropped_total_.load(std::memory_order_relaxed);
  const hid_t f = w.file.get();
  h5::attr(f, "ticks", static_cast<std::int64_t>(w.st.ticks));
  h5::attr(f, "packets", static_cast<std::int64_t>(w.st.packets));
  h5::attr(f, "dropped_records", static_cast<std::int64_t>(w.st.dropped_records));
  h5::attr(f, "truncated_at_tick", w.st.truncated_at_tick);
  h5::attr(f, "lossy_packet_values", static_cast<std::int64_t>(w.st.lossy_packet_values));
  h5::attr(f, "bytes_limit", static_cast<std::int64_t>(cfg_.max_bytes));
  h5::attr(f, "writer_error", w.st.error);
  try {
    w.write_extent_attrs(cfg_);
  } catch (const std::exception& e) {
    if (w.st.error.empty()) w.st.error = e.what();
  }
  final_ = w.st;
  writer_.reset();  // closes the file
  return final_;
}

}  // namespace haptic::firmware
