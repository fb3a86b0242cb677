#include "firmware/view/frame.hpp"

#include "platform/periodic_loop.hpp"

#include <algorithm>
#include <cmath>

#include "firmware/model/metrics.hpp"

namespace haptic::firmware {

namespace {
nlohmann::json micrometres(const float* x, int values) {
  std::vector<long> v(static_cast<std::size_t>(values));
  for (int i = 0; i < values; ++i) v[static_cast<std::size_t>(i)] = std::lround(static_cast<double>(x[i]) * 1e6);
  return v;
}
}  // namespace

void ViewPublisher::on_tick(const rt::StationCore& core, std::int64_t kr, double period_s, const rt::Vec3& q, const rt::Vec3& force,
                            std::uint32_t flags, std::int64_t exec_ns, std::int64_t wake_ns) {
  exec_max_ = std::max<std::int32_t>(exec_max_, static_cast<std::int32_t>(std::min<std::int64_t>(exec_ns, INT32_MAX)));
  wake_max_ = std::max<std::int32_t>(wake_max_, static_cast<std::int32_t>(std::min<std::int64_t>(wake_ns, INT32_MAX)));
  flags_ |= flags;
  port_min_J_ = std::min(port_min_J_, core.energy().port_J);
  ++ticks_;
  if (kr % every_ != 0) return;
  ViewFrame& f = box_.writer_slot();
  const int n = static_cast<int>(core.x().size() / 3);
  f.seq = ++seq_;
  f.k = kr;
  f.t_s = static_cast<double>(kr + 1) * period_s;
  f.nodes = std::min(n, kViewMaxNodes);
  const double* x = core.x().data();
  for (int i = 0; i < 3 * f.nodes; ++i) f.x[i] = static_cast<float>(x[i]);
  f.neighbours = core.neighbor_count();
  f.copies = n <= kViewCopyNodes ? std::min(f.neighbours, kViewMaxCopies) : 0;
  f.received_copy_distance_m = 0;
  for (int j = 0; j < f.neighbours; ++j) {
    const rt::RxLink& rx = core.rx(j);
    f.peer[j] = core.neighbor(j).peer_id;
    f.index_delay[j] = kr - rx.newest_sequence();
    f.bound[j] = core.neighbor(j).index_delay_bound_ticks;
    f.received_copy_distance_m = std::max(f.received_copy_distance_m, model::max_node_distance_m(x, rx.newest_x_hat(), n));
    if (j < f.copies)
      for (int i = 0; i < 3 * n; ++i) f.copy_x[j][i] = static_cast<float>(rx.newest_x_hat()[i]);
  }
  const auto& y = core.vp_position_m();
  for (int a = 0; a < 3; ++a) f.vp[a] = y[a], f.device[a] = q[a], f.force[a] = force[a];
  const auto& e = core.energy();
  f.port_J = e.port_J, f.controller_J = e.controller_J, f.vo_J = e.vo_J;
  f.exec_max_ns = exec_max_, f.wake_max_ns = wake_max_, f.flags = flags_;
  f.window_ticks = ticks_, f.window_missed_cycles = missed_;
  f.period_ns = static_cast<std::int64_t>(period_s * 1e9 + 0.5);
  f.overruns = overruns_total_, f.missed_cycles = missed_total_;
  f.gate_trips = core.edge_gate().trips(), f.gate_removed_J = core.edge_gate().removed_J();
  f.edge_drops = core.edge_drop_events(), f.port_min_J = port_min_J_;
  f.in_contact = core.in_contact();
  box_.writer_publish_slot();
  exec_max_ = wake_max_ = 0;
  flags_ = 0;
  ticks_ = missed_ = 0;
}

nlohmann::json view_scene_json(const rt::StationCore& core, int station_id, const std::string& mode) {
  const rt::Scene& s = *core.config().scene;
  const int n = std::min(s.nodes, kViewMaxNodes);
  std::vector<int> tri;
  for (const auto& t : s.mesh.surface)
    if (t[0] < n && t[1] < n && t[2] < n) tri.insert(tri.end(), {t[0], t[1], t[2]});
  std::vector<float> xd(static_cast<std::size_t>(3 * n));
  for (int i = 0; i < 3 * n; ++i) xd[static_cast<std::size_t>(i)] = static_cast<float>(s.x_d[i]);
  std::vector<int> peers;
  for (int j = 0; j < core.neighbor_count(); ++j) peers.push_back(core.neighbor(j).peer_id + 1);
  return {{"type", "scene"},     {"mode", mode},          {"station", station_id},
          {"nodes", n},          {"rest_um", micrometres(xd.data(), 3 * n)},
          {"triangles", tri},    {"contact", core.config().contact_nodes},
          {"neighbours", peers}, {"users", core.config().users},   {"period_s", core.config().period_s},
          {"damping_Ns_per_m", core.config().damping_Ns_per_m}};
}

nlohmann::json view_frame_json(const ViewFrame& f) {
  nlohmann::json j = {{"type", "frame"},
                      {"seq", f.seq},
                      {"k", f.k},
                      {"t", f.t_s},
                      {"x_um", micrometres(f.x, 3 * f.nodes)},
                      {"vp", {f.vp[0], f.vp[1], f.vp[2]}},
                      {"device", {f.device[0], f.device[1], f.device[2]}},
                      {"force", {f.force[0], f.force[1], f.force[2]}},
                      {"port_J", f.port_J},
                      {"controller_J", f.controller_J},
                      {"vo_J", f.vo_J},
                      {"received_copy_distance_m", f.received_copy_distance_m},
                      {"exec_max_us", f.exec_max_ns * 1e-3},
                      {"wake_max_us", f.wake_max_ns * 1e-3},
                      {"flags", f.flags},
                      {"safe_state", (f.flags & rt::kSafeState) != 0},
                      {"contact", f.in_contact}};
  nlohmann::json links = nlohmann::json::array(), copies = nlohmann::json::array();
  for (int n = 0; n < f.neighbours; ++n)
    links.push_back({{"peer", f.peer[n] + 1}, {"index_delay", f.index_delay[n]}, {"bound", f.bound[n]}, {"within", f.index_delay[n] <= f.bound[n]},
                     {"over_nbar", f.index_delay[n] > f.bound[n]}});
  for (int c = 0; c < f.copies; ++c) copies.push_back(micrometres(f.copy_x[c], 3 * f.nodes));
  j["links"] = links;
  j["copies_um"] = copies;
  // this host since the previous frame, by the one starving-host rule (the largest wake-up as the
  // P99 of a window this short); the replay and the simulator report no skipped periods
  j["host"] = {{"starving", platform::host_starving(f.window_ticks, f.window_missed_cycles, f.wake_max_ns, f.period_ns)},
               {"wake_max_ms", f.wake_max_ns * 1e-6}, {"skipped_periods", f.window_missed_cycles}, {"ticks", f.window_ticks},
               {"period_ms", static_cast<double>(f.period_ns) * 1e-6}};
  j["loop"] = {{"overruns", f.overruns}, {"missed_cycles", f.missed_cycles}};  // totals since the loop started
  j["gate"] = {{"trips", f.gate_trips}, {"removed_J", f.gate_removed_J}, {"edge_drops", f.edge_drops}, {"port_min_J", f.port_min_J},
               {"held", f.gate_trips > 0}};
  return j;
}

void LinkSince::annotate(nlohmann::json& frame) {
  const double t = frame.value("t", 0.0);
  for (auto& l : frame["links"]) {
    const bool up = l.contains("up") ? l["up"].get<bool>() : l.value("within", false);
    const auto [it, first] = state_.try_emplace(l.value("peer", 0), up, t);
    if (!first && it->second.first != up) it->second = {up, t};
    l["since_s"] = it->second.second;
  }
}

}  // namespace haptic::firmware
