#pragma once
// The link-impairment set-up of a scenario, one for the simulator's channels and the station's
// send-side emulator: the directed link sender -> receiver gets the scenario's mean delay
// delay_ms(receiver, sender) under the named preset (net/impairment.hpp; for "paper" the
// scenario's jitter, loss and duplication), and the seed net::link_seed(run seed, receiver,
// sender). Start-up only (not RT-safe); throws std::invalid_argument naming the key.
#include <cstdint>
#include <string>

#include "firmware/scenario.hpp"
#include "firmware/station/config.hpp"
#include "net/config.hpp"
#include "net/endpoint.hpp"
#include "net/impairment.hpp"

namespace haptic::firmware {

struct LinkSetup {
  net::LinkImpairment model;
  std::uint64_t seed = 1;
};
// Users 0-based; row `receiver` of spec.delay_ms receives from column `sender`.
LinkSetup scenario_link(const ScenarioSpec& spec, int receiver, int sender, std::uint64_t run_seed, const std::string& preset = "paper");

// The station's send-side emulator set-up from its file (start-up; the station's plan):
// every impaired peer link (wire id = user number) takes scenario_link(spec, peer, me, run seed,
// [net.impairment] preset) with run seed = [net.impairment] seed when given, else station.seed;
// a peer's own mean_delay_ms, a trace file and a blackout from the file are kept.
void apply_station_impairments(const StationFile& file, const ScenarioSpec& spec, net::NetConfig& nc);

}  // namespace haptic::firmware
