#pragma once
// `haptic-station merge DIR`: the outputs of N `haptic-station run` processes (DIR/station-<i>.json,
// -trace.csv, -state.csv, i = 1..N) merged into the simulator's contract (firmware/run/summary.hpp):
// DIR/summary.json, trace.csv and series.csv on the run's common tick index, the metrics taken by
// the simulator's code (firmware/run/metrics.hpp). Quantities that need every copy at once
// (consensus error, deformation, consensus times) use the ticks where all stations recorded their
// state (station.state_every); forces and energies the ticks all stations traced. Per link it adds
// what the stations measured (delay, loss, round trips) and whether the round-trip bounds enforced
// at both ends stay within what each end assumed in eq. (18). The stations' CSV files (in tick
// order) are read a row at a time, a few passes: the merge's memory does not grow with the run's
// length. Not RT-safe.
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace haptic::firmware {

// A directory that cannot be merged (missing or inconsistent station files, a station that
// reported an error, no common tick); what() says which file and why.
struct MergeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Merges DIR and writes DIR/summary.json, trace.csv, series.csv; returns the summary written.
// Throws MergeError.
nlohmann::json merge_run(const std::string& dir);

// One line for the operator: outcome, consensus times, hold balance, port energy, packets.
std::string merge_result_line(const nlohmann::json& summary);

}  // namespace haptic::firmware
