#include "firmware/station/tick.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "firmware/station/device_coupling.hpp"
#include "platform/trace.hpp"
#include "rt/tick_driver.hpp"

namespace haptic::firmware {

namespace {

OutgoingStateRewrite g_outgoing_rewrite = nullptr;  // the test seam (tick.hpp); null in the shipped station

using platform::trace::Stage;
using platform::trace::StageScope;

// This tick's packets (rt::drive_tick's source): the RX ring drained; what the tick alone can judge
// here (the endpoint judged the rest, net/README.md "Receive-path sanity"): a sender with no link,
// probing's packets still in the ring, and the age guard (a packet whose echo-based age bound, now -
// our own send stamp of the sequence it echoes, exceeds the neighbour's limit, or that echoes none
// of our sends). Every other packet is handed to its link in its RX buffer (RxLink::take: the one
// copy of the payload is the decoder's into that buffer); the buffer the link gives back returns to
// the endpoint. Sequence numbers, mapped onto our tick grid (TickInputs::seq_shift_ticks: a
// neighbour's measured clock offset), become run indices (seq + shift - run_k0). RT-safe.
template <class Offer>
void drain_rx(const TickInputs& in, TickCounters& cnt, Offer&& offer) {
  StageScope stage(Stage::rx_drain);
  if (in.ep == nullptr) return;  // solo: no network
  const double now_s = in.max_age_s ? net::monotonic_s() : 0.0;
  in.ep->drain_packets([&](const net::RxPacket& p) -> bool {  // true: the link keeps the RX buffer
    const int n = in.sender_to_nbr[p.sender];
    if (n < 0) {  // the decoder knows the same neighbours (unknown_sender): a table out of step
      ++cnt.foreign_packets;
      return false;
    }
    const std::int64_t seq = static_cast<std::int64_t>(p.seq) + (in.seq_shift_ticks ? in.seq_shift_ticks[n] : 0);  // on our grid
    if (seq < in.run_k0) {  // probing's packets, still in the ring
      ++cnt.probe_packets_after_run;
      return false;
    }
    if (in.max_age_s) {
      if (!p.has_echo) {
        ++cnt.no_echo;
        return false;
      }
      if (p.age_bound_s(now_s) > in.max_age_s[n]) {
        ++cnt.age_over_bound;
        return false;
      }
    }
    platform::trace::packet_rx(static_cast<std::uint32_t>(p.sender), p.seq, static_cast<std::uint32_t>(p.count));
    std::uint32_t released = rt::RxLink::kNoSlot;
    offer(rt::ReceivedState{n, seq, p.send_time_s, p.x_hat, p.v_hat, static_cast<int>(p.count), p.slot, &released});
    if (released == p.slot) return false;
    if (released != rt::RxLink::kNoSlot) in.ep->release_rx(released);  // the packet it replaced
    return true;
  });
}

// What run tick kr does with each packet (rt::drive_tick's observer): with a recorder every packet
// handed to a link recorded with kr and its run index (the replay offers them again); the link
// counts what it does not use. The solve's trace stage starts after the last. RT-safe.
struct RunTickObserver {
  const TickInputs& in;
  TickCounters& cnt;
  std::int64_t kr;
  void offered(const rt::ReceivedState& p, std::int64_t index, rt::RxVerdict v) {
    (void)v;
    if (in.recorder) in.recorder->rt_packet(kr, p.link, index, p.send_time_s, p.x_hat, p.v_hat);
    ++cnt.rx_offered;
  }
  void stepping() { platform::trace::solve_begin(); }
};

// Largest node speed of the core's state (inf when not finite). RT-safe.
double max_node_speed(const TickInputs& in) {
  const auto& v = in.core->v();
  double vmax = 0;
  for (int p = 0; p < in.dofs / 3; ++p) vmax = std::max(vmax, v.segment<3>(3 * p).norm());
  return std::isfinite(vmax) ? vmax : INFINITY;
}

void record_trace(const TickInputs& in, TickRecords& rec, std::int64_t kr, const double* F, const rt::Vec3& q, double vmax, std::uint32_t flags,
                  const platform::TickInfo& info) {
  if (kr % in.trace_every != 0) return;
  const std::size_t slot = rec.trace_window.writer_slot();
  if (slot == RowWindow::kNone) {  // the writer fell behind: dropped, counted, reported after the run
    ++rec.trace_lost;
    return;
  }
  TraceRec& r = rec.trace[slot];
  const auto& e = in.core->energy();
  r.k = kr;
  const auto xn = in.core->x().segment<3>(3 * in.trace_node);
  const auto& y = in.core->vp_position_m();
  for (int a = 0; a < 3; ++a) {
    r.node[a] = xn[a];
    r.force[a] = F[a];
    r.vp[a] = y[a];
    r.device[a] = q[a];
  }
  r.port_J = e.port_J;
  r.ctrl_J = e.controller_J;
  r.vo_J = e.vo_J;
  r.max_speed = vmax;
  r.step_s = in.core->last_step_s();
  r.flags = flags;
  r.wake_latency_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.wake_latency_ns, INT32_MAX));
  r.contact = in.core->in_contact() ? 1 : 0;
  rec.trace_window.writer_commit();
  ++rec.trace_rows;
}

void record_state(const TickInputs& in, TickRecords& rec, std::int64_t kr) {
  if (kr % in.state_every != 0) return;
  const std::size_t slot = rec.state_window.writer_slot();
  if (slot == RowWindow::kNone) {
    ++rec.state_lost;
    return;
  }
  rec.state_k[slot] = kr;
  const double* x = in.core->x().data();
  std::copy(x, x + in.dofs, rec.state_x.data() + slot * static_cast<std::size_t>(in.dofs));
  rec.state_window.writer_commit();
  ++rec.state_rows;
}

void record_telemetry(const TickInputs& in, const double* F, const rt::Vec3& q, std::uint32_t flags, const platform::TickInfo& info) {
  if (in.telemetry == nullptr) return;
  StageScope stage(Stage::telemetry);
  const auto& e = in.core->energy();
  platform::TelemetryRecord tr;
  tr.tick = info.index;
  tr.scheduled_ns = info.scheduled_ns;
  tr.wake_latency_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.wake_latency_ns, INT32_MAX));
  tr.exec_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.prev_exec_ns, INT32_MAX));
  tr.overruns = static_cast<std::uint32_t>(info.overruns);
  tr.status = flags;
  for (int a = 0; a < 3; ++a) {
    tr.values[static_cast<std::size_t>(a)] = F[a];
    tr.values[static_cast<std::size_t>(3 + a)] = q[a];
  }
  tr.values[6] = e.port_J;
  tr.values[7] = e.controller_J;
  tr.values[8] = e.vo_J;
  tr.values[9] = in.core->in_contact() ? 1 : 0;
  tr.values[10] = static_cast<double>(in.core->edge_drop_events());
  in.telemetry->record(tr);
}

// Energy, speed, divergence and neighbour-presence bookkeeping. RT-safe.
double monitor(const TickInputs& in, TickCounters& cnt, std::int64_t kr, std::uint32_t flags, double force_N, const platform::TickInfo& info) {
  cnt.port_min_J = std::min(cnt.port_min_J, in.core->energy().port_J);
  const double vmax = max_node_speed(in);
  cnt.max_speed_m_per_s = std::max(cnt.max_speed_m_per_s, vmax);
  if (in.core->in_contact()) ++cnt.contact_ticks;
  cnt.device_force_max_N = std::max(cnt.device_force_max_N, force_N);
  if (in.core->neighbor_count() > 0) {  // solo (no neighbour): nothing to be out of bound
    const bool usable = any_neighbour_within_bound(*in.core, kr);
    if (!usable) ++cnt.no_neighbour_ticks;
    cnt.outages.on_tick(*in.core, kr, usable, info);
  }
  if ((flags & rt::kDiverged) && !cnt.diverged) {
    cnt.diverged = true;
    cnt.diverged_at_s = static_cast<double>(kr) * in.period_s;
    if (in.telemetry) in.telemetry->report_fault(platform::FaultKind::divergence, info.index);
  }
  return vmax;
}

}  // namespace

rt::Vec3 read_device(const TickInputs& in, TickCounters& cnt) {
  StageScope stage(Stage::device_read);
  drivers::DeviceSample ds{};
  rt::Vec3 q;
  if (in.device->read_newest(ds)) {
    if (in.map != nullptr) {
      bool clamped = false;
      q = in.map->to_object(ds.position_m, &clamped);
      if (clamped) ++cnt.outside_workspace_ticks;
    } else {
      q = rt::Vec3(ds.position_m[0], ds.position_m[1], ds.position_m[2]);
    }
  } else {
    q = rt::Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    ++cnt.device_fault_ticks;
  }
  platform::trace::device_read(0, ds.sequence);
  return q;
}

void device_force_out(const TickInputs& in, const TickCounters& cnt, const rt::Vec3& f, double out[3]) {
  const rt::Vec3 ramped = ramp_in_factor(cnt.ticks_run, in.ramp_ticks) * f;
  if (in.map != nullptr) {
    in.map->force_to_device(ramped, out);
  } else {
    for (int a = 0; a < 3; ++a) out[a] = ramped[a];
  }
}

void receive_packets(const TickInputs& in, TickCounters& cnt, std::int64_t kr) {
  RunTickObserver observer{in, cnt, kr};
  drain_rx(in, cnt, rt::offer_to(*in.core, in.run_k0, observer));
}

bool any_neighbour_within_bound(rt::StationCore& core, std::int64_t kr) {
  for (int n = 0; n < core.neighbor_count(); ++n)
    if (kr - core.rx(n).newest_sequence() <= core.neighbor(n).index_delay_bound_ticks) return true;
  return false;
}

std::uint32_t run_tick(const TickInputs& in, TickRecords& rec, TickCounters& cnt, std::int64_t k, std::int64_t kr, const platform::TickInfo& info) {
  if (in.gpio) in.gpio->tick_high();  // the loop already emitted tick_begin
  if (in.ep) in.ep->note_tick(k);      // the sequence ceiling of the I/O thread's decoder (solo: no endpoint)
  const rt::Vec3 q = read_device(in, cnt);
  if (in.recorder && cnt.ticks_run == 0) in.recorder->rt_initial_state(in.core->x().data(), in.core->v().data());
  // T_k: the measured wake-to-wake period (the first tick: the nominal one); the core clamps it to
  // station.period_min_s..period_max_s and counts it when outside (rt/README.md "Variable steps")
  // (a fixed-step configuration, period_min_s = period_max_s, integrates over the nominal period)
  const bool variable = in.core->config().t_max() > in.core->config().t_min();
  const double step_s = variable && cnt.ticks_run > 0 ? static_cast<double>(info.wake_ns - cnt.last_wake_ns) * 1e-9 : in.period_s;
  cnt.last_wake_ns = info.wake_ns;
  // RX drained into the receive links (sequence numbers become run indices, seq - run_k0), then
  // the coupled VO + VP step at run cycle kr
  const auto out = rt::drive_tick(*in.core, rt::TickDrive{kr, in.run_k0, q, step_s}, [&](auto&& offer) { drain_rx(in, cnt, offer); },
                                  RunTickObserver{in, cnt, kr});
  platform::trace::solve_end();
  if (in.edge_events) in.edge_events->after_tick(*in.core, kr);  // an isolation or a gate trip: logged by the non-RT side
  // The force the device is told, in the object frame (ramp-in applied): what the trace, the
  // telemetry and the checks on them see.
  const double ramp = ramp_in_factor(cnt.ticks_run, in.ramp_ticks);
  const double F[3] = {ramp * out.device_force_N[0], ramp * out.device_force_N[1], ramp * out.device_force_N[2]};
  {
    StageScope stage(Stage::publish);
    double F_dev[3];
    device_force_out(in, cnt, out.device_force_N, F_dev);  // ramp-in, object -> device frame
    in.device->command_force(F_dev);
    platform::trace::device_write(0, static_cast<std::uint64_t>(kr));
    if (in.simulated) in.simulated->service(static_cast<double>(kr) * in.period_s, in.period_s);
  }
  bool sent = false;
  {
    StageScope stage(Stage::tx);
    if (in.ep && (!in.tx_deadband || in.tx_deadband->should_send(kr, in.core->x_hat(), in.core->v_hat()))) {
      const OutgoingState lie = g_outgoing_rewrite ? g_outgoing_rewrite(*in.core, kr) : OutgoingState{};
      sent = in.ep->push_state(static_cast<std::uint64_t>(k), net::monotonic_s(), lie.x_hat ? lie.x_hat : in.core->x_hat(),
                               lie.v_hat ? lie.v_hat : in.core->v_hat(),
                               (out.flags & rt::kDiverged) != 0,  // safe state: the flag, never the state
                               in.core->vp_position_m().data());  // the proxy, for the neighbours' live views
      if (!sent) ++cnt.push_failures;
    }
  }
  {
    StageScope stage(Stage::monitor);
    const double vmax = monitor(in, cnt, kr, out.flags, std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]), info);
    record_trace(in, rec, kr, F, q, vmax, out.flags | (sent ? kTraceStateSent : 0u), info);
    record_state(in, rec, kr);
  }
  record_telemetry(in, F, q, out.flags, info);
  if (in.recorder) {
    TickRecord row = make_tick_record(*in.core, kr, q, out, step_s);  // the T_k handed to the core, for replay
    row.wake_latency_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.wake_latency_ns, INT32_MAX));
    row.exec_ns = static_cast<std::int32_t>(std::min<std::int64_t>(info.prev_exec_ns, INT32_MAX));
    in.recorder->rt_tick(row);
  }
  if (in.view) in.view->note_missed_cycles(info.missed_cycles);
  if (in.view) in.view->note_overruns(info.overruns);
  if (in.view) in.view->on_tick(*in.core, kr, in.period_s, q, out.device_force_N, out.flags, info.prev_exec_ns, info.wake_latency_ns);
  ++cnt.ticks_run;
  if (in.gpio) in.gpio->tick_low();
  return out.flags;
}

void set_outgoing_state_rewrite(OutgoingStateRewrite rewrite) { g_outgoing_rewrite = rewrite; }

}  // namespace haptic::firmware
