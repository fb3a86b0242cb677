#include "firmware/session/replay.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "rt/tick_driver.hpp"

namespace haptic::firmware {

namespace {

using h5::Type;

// The packets of a log, read in blocks of rows (the values can be large).
class PacketCursor {
 public:
  PacketCursor(hid_t packets, int dofs) : g_(packets), dofs_(static_cast<std::size_t>(dofs)) {
    tick_ = h5::read_i64(g_, "tick");
    seq_ = h5::read_i64(g_, "seq");
    nbr_ = h5::read_i64(g_, "neighbour");
    send_ = h5::read_f64(g_, "send_time_s");
  }
  std::size_t size() const { return tick_.size(); }
  std::int64_t tick(std::size_t i) const { return tick_[i]; }
  std::int64_t seq(std::size_t i) const { return seq_[i]; }
  int neighbour(std::size_t i) const { return static_cast<int>(nbr_[i]); }
  double send_time(std::size_t i) const { return send_[i]; }
  const double* x(std::size_t i) { return load(i), x_.data() + (i - block0_) * dofs_; }
  const double* v(std::size_t i) { return load(i), v_.data() + (i - block0_) * dofs_; }

 private:
  void load(std::size_t i) {
    if (i >= block0_ && i < block0_ + block_n_) return;
    block0_ = i;
    block_n_ = std::min<std::size_t>(kBlock, size() - i);
    x_.resize(block_n_ * dofs_);
    v_.resize(block_n_ * dofs_);
    h5::read_rows(g_, "x", Type::kF64, x_.data(), block0_, block_n_);
    h5::read_rows(g_, "v", Type::kF64, v_.data(), block0_, block_n_);
  }
  static constexpr std::size_t kBlock = 512;
  hid_t g_;
  std::size_t dofs_;
  std::vector<std::int64_t> tick_, seq_, nbr_;
  std::vector<double> send_, x_, v_;
  std::size_t block0_ = 0, block_n_ = 0;
};

void scale(rt::SpatialMatrix& m, double s) {
  for (Eigen::Index i = 0; i < m.S.nonZeros(); ++i) m.S.valuePtr()[i] *= s;
}

// First tick whose inputs the log does not hold completely (-1: none).
std::int64_t inputs_end(hid_t file, const std::vector<TickRecord>& ticks) {
  std::int64_t end = h5::has_attr(file, "truncated_at_tick") ? h5::attr_i64(file, "truncated_at_tick") : -1;
  for (const auto& r : ticks)
    if (r.dropped > 0 && (end < 0 || r.k < end)) return r.k;
  return end;
}

FILE* open_trace(const std::string& path) {
  if (path.empty()) return nullptr;
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  std::fprintf(f, "t_s,k,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,port_energy_J,controller_energy_J,vo_energy_J,"
                  "recorded_force_x_N,recorded_force_y_N,recorded_force_z_N,hash_match\n");
  return f;
}

// One line per tick for stepping through (--from/--to): what the core did and whether it matched.
void print_step(std::FILE* out, const rt::StationCore& core, const TickRecord& r, const rt::StationCore::TickOutput& o, double t_s, std::uint64_t hash) {
  const auto& e = core.energy();
  const auto& y = core.vp_position_m();
  std::fprintf(out, "tick %lld t=%.4f s q=(%.6g %.6g %.6g) m F=(%.6g %.6g %.6g) N vp=(%.6g %.6g %.6g) m port=%.6g controller=%.6g vo=%.6g J "
                    "flags=0x%x contact=%d hash=%016llx recorded=%016llx %s\n",
               static_cast<long long>(r.k), t_s, r.q[0], r.q[1], r.q[2], o.device_force_N[0], o.device_force_N[1], o.device_force_N[2], y[0], y[1], y[2],
               e.port_J, e.controller_J, e.vo_J, o.flags, core.in_contact() ? 1 : 0, static_cast<unsigned long long>(hash),
               static_cast<unsigned long long>(r.hash), hash == r.hash ? "match" : "DIFFERS");
}

// The core's state after tick k as JSON (--state-json): x, v (m, m/s), VP, energies, each link's newest sequence.
void write_state_json(const std::string& path, const rt::StationCore& core, std::int64_t k, double t_s) {
  nlohmann::json links = nlohmann::json::array();
  for (int j = 0; j < core.neighbor_count(); ++j)
    links.push_back({{"peer", core.neighbor(j).peer_id + 1}, {"newest_sequence", core.rx(j).newest_sequence()},
                     {"index_delay", k - core.rx(j).newest_sequence()}, {"bound", core.neighbor(j).index_delay_bound_ticks}});
  const auto& e = core.energy();
  const auto& y = core.vp_position_m();
  const nlohmann::json j = {{"tick", k},
                            {"t_s", t_s},
                            {"x_m", std::vector<double>(core.x().data(), core.x().data() + core.x().size())},
                            {"v_m_per_s", std::vector<double>(core.v().data(), core.v().data() + core.v().size())},
                            {"vp_m", {y[0], y[1], y[2]}},
                            {"in_contact", core.in_contact()},
                            {"energy_J", {{"port", e.port_J}, {"controller", e.controller_J}, {"vo", e.vo_J}}},
                            {"links", links}};
  std::ofstream f(path);
  f << j.dump(1) << "\n";
  if (!f) throw std::runtime_error("cannot write " + path);
}

}  // namespace

std::vector<TickRecord> read_tick_records(hid_t file) {
  h5::Id g = h5::open_group(file, "ticks");
  const auto k = h5::read_i64(g.get(), "k");
  const auto q = h5::read_f64(g.get(), "q"), f = h5::read_f64(g.get(), "force"), y = h5::read_f64(g.get(), "vp");
  const auto port = h5::read_f64(g.get(), "port_J"), ctrl = h5::read_f64(g.get(), "controller_J"), vo = h5::read_f64(g.get(), "vo_J");
  const auto n = k.size();
  std::vector<std::uint64_t> hash(n);
  std::vector<std::uint32_t> flags(n), dropped(n);
  std::vector<std::uint8_t> contact(n);
  std::vector<std::int32_t> wake(n), exec(n);
  h5::read_rows(g.get(), "hash", Type::kU64, hash.data(), 0, n);
  h5::read_rows(g.get(), "flags", Type::kU32, flags.data(), 0, n);
  h5::read_rows(g.get(), "dropped", Type::kU32, dropped.data(), 0, n);
  h5::read_rows(g.get(), "contact", Type::kU8, contact.data(), 0, n);
  h5::read_rows(g.get(), "wake_latency_ns", Type::kI32, wake.data(), 0, n);
  h5::read_rows(g.get(), "exec_ns", Type::kI32, exec.data(), 0, n);
  std::vector<double> step(n, 0.0);  // version 1 logs: nominal steps
  if (h5::exists(g.get(), "step_s")) h5::read_rows(g.get(), "step_s", Type::kF64, step.data(), 0, n);
  std::vector<TickRecord> rows(n);
  for (std::size_t i = 0; i < n; ++i) {
    TickRecord& r = rows[i];
    r.k = k[i];
    for (int a = 0; a < 3; ++a) r.q[a] = q[3 * i + a], r.force[a] = f[3 * i + a], r.vp[a] = y[3 * i + a];
    r.port_J = port[i], r.controller_J = ctrl[i], r.vo_J = vo[i], r.hash = hash[i], r.flags = flags[i];
    r.dropped = dropped[i], r.contact = contact[i], r.wake_latency_ns = wake[i], r.exec_ns = exec[i], r.step_s = step[i];
  }
  return rows;
}

std::string ReplayResult::summary() const {
  std::ostringstream os;
  os << "replay of station " << station_id << " (" << source << " log): " << ticks << " ticks";
  if (gains_changed) {
    os << " re-run with changed gains; max |F - F_recorded| = " << max_force_difference_N << " N"
       << " (open loop: the neighbours' recorded states are replayed as they were, they do not react to the changed gains)";
  } else if (bit_exact()) {
    os << ", bit-exact at every tick (state hash)";
  } else if (first_mismatch >= 0) {
    os << ", state hash differs first at tick " << first_mismatch << " (" << matched << " ticks matched before)";
    if (recorded_build_id != replay_build_id)
      os << "; the log was written by another build (" << (recorded_build_id.empty() ? "unknown" : recorded_build_id.substr(0, 12)) << ", this one "
         << replay_build_id.substr(0, 12) << "): a change in the core's arithmetic since then also makes every tick differ";
  } else {
    os << ", " << matched << " matched";
  }
  if (stopped_at_to) os << " (stopped at tick " << last_tick << ", --to)";
  if (!inputs_complete()) os << "; the log's inputs are incomplete from tick " << inputs_end << " (dropped or truncated): replayed up to there";
  return os.str();
}

ReplayResult replay_session(const std::string& path, const ReplayOptions& opt, const ReplayObserver& observer) {
  h5::Id file = h5::open_file_read(path);
  auto setup = read_core_setup(file.get());
  // A ring that wrapped starts after its first tick's core state; a whole-run log may start late (a
  // station whose loop began after the run's first tick) and holds its initial state there.
  if (h5::has_attr(file.get(), "ring_ticks") && h5::attr_i64(file.get(), "ring_ticks") > 0 && h5::has_attr(file.get(), "first_tick") &&
      h5::attr_i64(file.get(), "first_tick") > 0)
    throw NotReplayable("a ring of the last " + std::to_string(h5::attr_i64(file.get(), "ring_ticks")) + " ticks (station.record_ring_s) that starts at tick " +
                        std::to_string(h5::attr_i64(file.get(), "first_tick")) +
                        ": it holds no core state there, so it is for inspection (h5py; rows in ring order, see ring_next_row), not replay;"
                        " record the whole run (record_ring_s = 0) to replay");
  ReplayResult res;
  res.station_id = static_cast<int>(h5::attr_i64(file.get(), "station_id"));
  res.source = h5::attr_str(file.get(), "source");
  if (h5::has_attr(file.get(), "build_id")) res.recorded_build_id = h5::attr_str(file.get(), "build_id");
  res.replay_build_id = program_build_id();
  res.gains_changed = opt.gains_changed();
  if (opt.damping_Ns_per_m >= 0) setup->config.damping_Ns_per_m = opt.damping_Ns_per_m;
  for (auto& g : setup->gains) scale(g.P, opt.p_scale), scale(g.D, opt.d_scale);
  rt::StationCore core(setup->config);
  if (h5::exists(file.get(), "initial_state")) {
    h5::Id g = h5::open_group(file.get(), "initial_state");
    const auto x = h5::read_f64(g.get(), "x"), v = h5::read_f64(g.get(), "v");
    core.set_state(Eigen::Map<const Eigen::VectorXd>(x.data(), static_cast<Eigen::Index>(x.size())),
                   Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size())));
  }
  const std::vector<TickRecord> ticks = read_tick_records(file.get());
  res.inputs_end = inputs_end(file.get(), ticks);
  h5::Id pg = h5::open_group(file.get(), "packets");
  PacketCursor pk(pg.get(), setup->scene.dofs);
  std::unique_ptr<FILE, int (*)(FILE*)> trace(open_trace(opt.trace_csv), [](FILE* f) { return f ? std::fclose(f) : 0; });
  const int dofs = setup->scene.dofs;
  // the trace's time: the first tick's nominal start plus the steps the core took (T_k)
  double t_s = ticks.empty() ? 0.0 : static_cast<double>(ticks.front().k) * setup->config.period_s;
  std::size_t p = 0;
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    const TickRecord& r = ticks[i];
    if (res.inputs_end >= 0 && r.k >= res.inputs_end) break;
    if (opt.to_tick >= 0 && r.k > opt.to_tick) {
      res.stopped_at_to = true;
      break;
    }
    // the recorded packets of tick r.k re-offered (their sequence numbers are recorded as the
    // core's indices), the recorded device sample and step T_k, as the station or the simulator
    // handed it to the core (0: the nominal one)
    const rt::TickDrive drive{r.k, 0, rt::Vec3(r.q[0], r.q[1], r.q[2]), r.step_s > 0 ? r.step_s : core.config().period_s};
    const auto out = rt::drive_tick(core, drive, [&](auto&& offer) {
      for (; p < pk.size() && pk.tick(p) <= r.k; ++p) {
        const int n = pk.neighbour(p);
        if (n < 0 || n >= core.neighbor_count()) throw std::runtime_error("log: packet " + std::to_string(p) + " names neighbour " + std::to_string(n));
        offer(rt::ReceivedState{n, pk.seq(p), pk.send_time(p), pk.x(p), pk.v(p), dofs});
      }
    });
    t_s += core.last_step_s();
    const std::uint64_t hash = state_hash(core, out);
    const bool match = hash == r.hash;
    ++res.ticks;
    res.last_tick = r.k;
    if (opt.from_tick >= 0 && r.k >= opt.from_tick) print_step(stdout, core, r, out, t_s, hash);
    if (match && res.first_mismatch < 0) ++res.matched;
    if (!match && res.first_mismatch < 0) res.first_mismatch = r.k;
    for (int a = 0; a < 3; ++a) res.max_force_difference_N = std::max(res.max_force_difference_N, std::abs(out.device_force_N[a] - r.force[a]));
    if (trace) {
      const auto& e = core.energy();
      const auto& y = core.vp_position_m();
      const auto& F = out.device_force_N;
      std::fprintf(trace.get(), "%.4f,%lld,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%d\n", t_s,
                   static_cast<long long>(r.k), F[0], F[1], F[2], y[0], y[1], y[2], e.port_J, e.controller_J, e.vo_J, r.force[0], r.force[1],
                   r.force[2], match ? 1 : 0);
    }
    if (observer) observer(core, r, static_cast<std::int64_t>(i));
  }
  if (opt.to_tick >= 0 && res.last_tick == opt.to_tick) res.stopped_at_to = true;
  if (!opt.state_json.empty() && res.ticks > 0) write_state_json(opt.state_json, core, res.last_tick, t_s);
  return res;
}

}  // namespace haptic::firmware
