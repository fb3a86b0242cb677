#include "firmware/station/neighbours.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

namespace haptic::firmware {

namespace {
const net::PeerStats& peer_of(const StationPlan& plan, const net::EndpointStats& s, std::size_t n) {
  return s.peers[static_cast<std::size_t>(plan.peers.nbr_to_peer[n])];
}
std::string ms(double s) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f ms", s * 1e3);
  return b;
}
}  // namespace

std::string fingerprint_mismatches(const StationPlan& plan, const net::EndpointStats& stats) {
  std::string out;
  const auto& nbrs = plan.neighbours();
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = peer_of(plan, stats, n);
    if (!p.has_fingerprint) continue;
    const std::string d = net::fingerprint_difference(plan.fingerprint, p.fingerprint);
    if (d.empty()) continue;
    if (!out.empty()) out += "; ";
    out += "station " + std::to_string(nbrs[n] + 1) + ": " + d;
  }
  return out;
}

NeighbourGrid::NeighbourGrid(std::size_t neighbours)
    : epoch_own_clock_s(neighbours, std::numeric_limits<double>::infinity()), newest_seq(neighbours, -1.0) {}

void NeighbourGrid::add(int n, std::uint64_t seq, double send_time_s, double period_s) {
  if (n < 0 || static_cast<std::size_t>(n) >= epoch_own_clock_s.size()) return;
  const double e = send_time_s - static_cast<double>(seq) * period_s;
  auto& slot = epoch_own_clock_s[static_cast<std::size_t>(n)];
  if (e < slot) slot = e;
  auto& newest = newest_seq[static_cast<std::size_t>(n)];
  if (static_cast<double>(seq) > newest) newest = static_cast<double>(seq);
}

ClockCheck check_clock_offsets(const StationPlan& plan, const net::EndpointStats& stats, const NeighbourGrid& grid, std::int64_t epoch_ns) {
  ClockCheck c;
  const auto& nbrs = plan.neighbours();
  const double T = plan.built->spec.period_s;
  const double bound = plan.file.station.clock_offset_max_ms * 1e-3;
  const double epoch_s = static_cast<double>(epoch_ns) * 1e-9;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = peer_of(plan, stats, n);
    const double e = n < grid.epoch_own_clock_s.size() ? grid.epoch_own_clock_s[n] : INFINITY;
    if (p.clock_offset_samples == 0 || !std::isfinite(e)) {
      c.grid_offset_s.push_back(NAN);
      c.uncertainty_s.push_back(NAN);
      c.shift_ticks.push_back(0);
      continue;
    }
    const double offset = (e - p.clock_offset_s) - epoch_s;
    const double unc = p.clock_offset_rtt_s / 2.0 + T;
    c.grid_offset_s.push_back(offset);
    c.uncertainty_s.push_back(unc);
    // within the uncertainty the grids are one: no shift (a one-host session stays bit-for-bit as before)
    c.shift_ticks.push_back(std::abs(offset) > unc ? std::llround(offset / T) : 0);
    if (std::abs(offset) - unc > plan.file.station.clock_offset_limit_ms * 1e-3)
      c.refusal += (c.refusal.empty() ? "" : "; ") + std::string("station ") + std::to_string(nbrs[n] + 1) + "'s tick grid is " + ms(std::abs(offset)) +
                   " (+- " + ms(unc) + ") " + (offset > 0 ? "behind" : "ahead of") + " station " + std::to_string(plan.station_id) + "'s";
    if (std::abs(offset) - unc > bound) {
      c.exceeded = true;
      if (!c.message.empty()) c.message += "; ";
      c.message += "station " + std::to_string(nbrs[n] + 1) + " runs its ticks " + ms(std::abs(offset)) + " " + (offset > 0 ? "later" : "earlier") +
                   " than ours (+- " + ms(unc) + ")";
    }
  }
  if (!c.refusal.empty())
    c.refusal = "refusing to couple: clock offset beyond station.clock_offset_limit_ms = " + ms(plan.file.station.clock_offset_limit_ms * 1e-3) +
                ": " + c.refusal + " (their clocks, or start_at, differ: check NTP/PTP)";
  if (c.exceeded)
    c.message = "clock offset above station.clock_offset_max_ms = " + std::to_string(plan.file.station.clock_offset_max_ms) + ": " + c.message +
                " (start_clock = \"realtime\" with unsynchronised clocks? check NTP/PTP)";
  return c;
}

PeerEventLog::PeerEventLog(const StationPlan& plan, std::int64_t run_epoch_ns, double quiet_s)
    : plan_(&plan),
      epoch_s_(static_cast<double>(run_epoch_ns) * 1e-9),
      quiet_until_s_(epoch_s_ + quiet_s),
      downs_(plan.neighbours().size(), 0),
      ups_(plan.neighbours().size(), 0),
      incarnation_changes_(plan.neighbours().size(), 0),
      refused_(plan.neighbours().size(), 0),
      compromised_(plan.neighbours().size(), false) {}

namespace {
std::string key_compromise_message(int station, const net::PeerStats& p) {
  const std::string what = p.key_compromise_conflict
                               ? "sent two different authentic datagrams with sequence " + std::to_string(p.key_compromise_seq) +
                                     ": refused for the rest of the run"
                               : "has two live incarnations (" + std::to_string(p.incarnation) + " and " +
                                     std::to_string(p.refused_incarnation) + "): both refused for the rest of the run";
  return "key compromise suspected: station " + std::to_string(station) + " " + what +
         " (net/README.md \"Incarnations and restarts\"); revoke its key (net.revoked_keys) "
         "and rotate the lab's keys (haptic-lab rotate-keys)";
}
}  // namespace

std::vector<std::string> key_compromise_messages(const StationPlan& plan, const net::EndpointStats& stats) {
  std::vector<std::string> lines;
  const auto& nbrs = plan.neighbours();
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = peer_of(plan, stats, n);
    if (p.key_compromise) lines.push_back(key_compromise_message(nbrs[n] + 1, p));
  }
  return lines;
}

std::vector<std::string> energy_bound_events(const StationPlan& plan, const rt::StationCore& core) {
  std::vector<std::string> lines;
  const auto& nbrs = plan.neighbours();
  const auto& gate = core.edge_gate();
  const auto& acc = core.edge_energy();
  for (std::size_t n = 0; n < nbrs.size() && static_cast<int>(n) < core.neighbor_count(); ++n) {
    const int j = static_cast<int>(n);
    if (gate.trips(j) == 0) continue;
    char b[300];
    std::snprintf(b, sizeof b,
                  "neighbour %d: energy bound %.4g J (station.edge_energy_bound_J) tripped %llu time(s); the edge acted as a damper for %llu "
                  "ticks (its account: peak %.4g J, now %.4g J, released at %.4g J)",
                  nbrs[n] + 1, gate.bound_J(j), static_cast<unsigned long long>(gate.trips(j)), static_cast<unsigned long long>(gate.gated_ticks(j)),
                  acc.peak_J(j), acc.edge_J(j), gate.release_J(j));
    lines.emplace_back(b);
  }
  return lines;
}

std::vector<std::string> return_ramp_events(const StationPlan& plan, const rt::StationCore& core) {
  std::vector<std::string> lines;
  const auto& nbrs = plan.neighbours();
  const auto& ramp = core.return_ramp();
  const auto& fade = core.drop_fade();
  for (std::size_t n = 0; n < nbrs.size() && static_cast<int>(n) < core.neighbor_count(); ++n) {
    const int j = static_cast<int>(n);
    char b[300];
    if (fade.fades(j) > 0) {
      std::snprintf(b, sizeof b, "neighbour %d: its data aged out %llu time(s); the edge was released over station.drop_fade_s = %.3g s",
                    nbrs[n] + 1, static_cast<unsigned long long>(fade.fades(j)), core.config().drop_fade_s);
      lines.emplace_back(b);
    }
    if (ramp.ramps(j) == 0) continue;
    std::snprintf(b, sizeof b,
                  "neighbour %d: its data returned after an outage %llu time(s); the copies were pulled together over station.return_ramp_s = "
                  "%.3g s (last offset %.3g mm)",
                  nbrs[n] + 1, static_cast<unsigned long long>(ramp.ramps(j)), core.config().return_ramp_s, ramp.last_offset_m(j) * 1e3);
    lines.emplace_back(b);
  }
  return lines;
}

std::vector<std::string> round_trip_over_bound_events(const StationPlan& plan, const net::EndpointStats& stats,
                                                      const std::vector<int>& bound_ticks) {
  std::vector<std::string> lines;
  const auto& nbrs = plan.neighbours();
  const double T = plan.built->spec.period_s;
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = peer_of(plan, stats, n);
    if (p.rtt_over_bound_events == 0) continue;
    const double bound_s = n < bound_ticks.size() ? static_cast<double>(bound_ticks[n]) * T : p.rtt_probe_bound_s;
    lines.push_back("neighbour " + std::to_string(nbrs[n] + 1) + ": " + std::to_string(p.rtt_over_bound_events) +
                    " round trip(s) above the probing bound " + ms(p.rtt_probe_bound_s) + " (largest " + ms(p.rtt_max_s) + "; R_ij = " + ms(bound_s) +
                    " with the loss allowance, which B_i and the age guard use): B_i was not re-derived; data older than the age guard's "
                    "bound is refused (that edge dropped while late) (net/README.md, \"Policy for a measured round trip above the bound\")");
  }
  return lines;
}

std::vector<std::string> PeerEventLog::poll(const net::EndpointStats& stats) {
  std::vector<std::string> lines;
  const auto& nbrs = plan_->neighbours();
  for (std::size_t n = 0; n < nbrs.size(); ++n) {
    const net::PeerStats& p = peer_of(*plan_, stats, n);
    const std::string who = "neighbour " + std::to_string(nbrs[n] + 1);
    auto at = [&](double t_s) {
      char b[48];
      std::snprintf(b, sizeof b, "run time %.3f s", t_s - epoch_s_);
      return std::string(b);
    };
    if (p.down_events > downs_[n]) {
      downs_[n] = p.down_events;
      if (p.last_down_s >= quiet_until_s_) {
        ++events_;
        lines.push_back(who + " went silent at " + at(p.last_down_s) + " (no packet for net.peer_silence_s)");
      }
    }
    const bool restarted = p.incarnation_changes > incarnation_changes_[n];
    incarnation_changes_[n] = p.incarnation_changes;
    const std::string new_incarnation = "restarted: new incarnation " + std::to_string(p.incarnation);
    if (p.up_events > ups_[n]) {
      ups_[n] = p.up_events;
      if (p.last_up_s >= quiet_until_s_) {
        ++events_;
        lines.push_back(who + " is back at " + at(p.last_up_s) + (restarted ? " (" + new_incarnation + ")" : ""));
      }
    } else if (restarted && p.last_receive_s >= quiet_until_s_) {  // replaced without a silence the periodic check saw
      ++events_;
      lines.push_back(who + " " + new_incarnation + " at " + at(p.last_receive_s));
    }
    if (p.refused_incarnation != 0 && p.refused_incarnation != refused_[n] && !p.key_compromise) {
      refused_[n] = p.refused_incarnation;
      ++events_;
      lines.push_back(who + " announced a new incarnation " + std::to_string(p.refused_incarnation) + " while its current one " +
                      std::to_string(p.incarnation) + " still spoke: refused until the current one has been silent for net.peer_silence_s");
    }
    if (p.key_compromise && !compromised_[n]) {
      compromised_[n] = true;
      ++events_;
      lines.push_back(key_compromise_message(nbrs[n] + 1, p) + " (found at " + at(p.key_compromise_s) + ")");
    }
  }
  return lines;
}

}  // namespace haptic::firmware
