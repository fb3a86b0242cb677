#include "firmware/station/link_impairment.hpp"

namespace haptic::firmware {

LinkSetup scenario_link(const ScenarioSpec& spec, int receiver, int sender, std::uint64_t run_seed, const std::string& preset) {
  LinkSetup s;
  s.model = net::LinkImpairment::preset(preset, spec.delay_ms(receiver, sender) * 1e-3, "net.impairment.preset");
  if (preset == "paper") {
    s.model.jitter_fraction = spec.jitter_fraction;
    s.model.loss_probability = spec.loss_probability;
    s.model.duplicate_probability = spec.duplicate_probability;
    s.model.burst_enter_probability = spec.burst_enter_probability;
    s.model.burst_exit_probability = 1.0 / spec.burst_mean_packets;
    s.model.burst_loss_probability = spec.burst_loss_probability;
  }
  s.model.delay_correlation = spec.delay_correlation;  // the one delay model, i.i.d. or time-correlated
  s.model.delay_trace = spec.delay_trace;              // or a recorded trace, replayed
  s.seed = net::link_seed(run_seed, receiver, sender);
  return s;
}

void apply_station_impairments(const StationFile& file, const ScenarioSpec& spec, net::NetConfig& nc) {
  const int me = file.station.id - 1;
  const std::uint64_t run_seed = file.impairment_seed_set ? nc.impairment_seed : file.station.seed;
  for (auto& l : nc.endpoint.peers) {
    if (!l.impaired) continue;
    const int peer = l.station_id - 1;
    bool mean_given = false;
    for (const auto& [id, given] : file.peer_mean_delay_set)
      if (id == l.station_id) mean_given = given;
    const net::LinkImpairment from_file = l.impairment;
    const LinkSetup s = scenario_link(spec, peer, me, run_seed, file.impairment_preset);
    l.impairment = s.model;
    if (mean_given) l.impairment.mean_delay_s = from_file.mean_delay_s;
    l.impairment.delay_trace = from_file.delay_trace;
    l.impairment.blackout_start_s = from_file.blackout_start_s;
    l.impairment.blackout_length_s = from_file.blackout_length_s;
    l.seed = s.seed;
  }
}

}  // namespace haptic::firmware
