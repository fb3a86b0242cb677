#pragma once
// What the neighbour state check (rt/edge_monitor.hpp) did in a run, for the log and
// station-<id>.json: each neighbour it isolated, named by station, with the reason, the run time,
// the node and value that tripped it, its re-admissions and the ticks this station ran without it.
// After the run only (reads the core; not RT-safe: allocates and formats strings).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/station/plan.hpp"
#include "rt/station.hpp"

namespace haptic::firmware {

// One line per neighbour the check isolated at least once ("" lines: none). When every neighbour
// of this station was isolated at the end of the run, one more line says it held its own copy alone.
std::vector<std::string> state_check_messages(const StationPlan& plan, const rt::StationCore& core);

// station-<id>.json "state_check": the thresholds and, per neighbour, what the check saw and did.
nlohmann::json state_check_json(const StationPlan& plan, const rt::StationCore& core);

}  // namespace haptic::firmware
