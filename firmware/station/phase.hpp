#pragma once
// The statuses the phases of `haptic-station run` return (DESIGN.md, "The station process":
// plan -> probe -> build -> run -> report) and the process exit codes they map to.
#include <string>

namespace haptic::firmware {

// What a phase ended with. RT-safe to copy (an enum).
enum class PhaseStatus {
  kOk = 0,
  kConfigError,   // the configuration is wrong (plan): exit 2
  kNoNeighbour,   // probing: no neighbour answered at all
  kDeviceMissing, // open: the configured device could not be started (never replaced by a simulated user): exit 9
  kFailed,        // any other run-time failure (socket, device fault, a neighbour missing, core not ready)
  kStopped,       // SIGINT/SIGTERM before the phase finished
};

// Process exit codes of `haptic-station run` (also in --help and firmware/README.md). When
// several conditions hold, the code is the first of this list that holds:
//   2 configuration error, 9 device missing (device.kind names a device that could not be
//   started; a station never substitutes a simulated user), 4 diverged, 5 safe state latched, 6 passivity condition not met,
//   12 key compromise suspected (a neighbour's key in two live incarnations: net/ refused both for the rest of the run
//      and the station ran without it; before 11 and 7, which that loss of a neighbour may also cause: the theft is the
//      cause; the systemd unit does not restart it, so the station does not forget the suspicion: the operator revokes the key),
//   13 neighbour isolated (the neighbour state check, rt/edge_monitor.hpp, isolated an authenticated neighbour whose
//      reported states were inconsistent with its own velocities or far from this copy; before 11 and 7 for the same reason
//      as 12; not restarted by the systemd unit: a restart would forget the liar and let it drag the copies again),
//   11 missed cycles (the run loop skipped more than station.max_missed_cycles periods in all: the
//      host stalled the station; before 7, because a stalled station's neighbours see it silent and it may in turn
//      see them out of bound: the stall is the cause, and the stalled station is the one that must say so),
//   7 no neighbour (none answered probing, or none within its bound for more than
//     station.max_no_neighbour_fraction of the run), 3 other run-time failure,
//   8 the run ended before the scripted release,
//   10 held by the gate (the per-edge energy gate tripped: the run stayed bounded by the gate's
//      bound, not by eq. (18) alone; station-<id>.json's "gate" says how often and how much it
//      removed); 0 otherwise.
// A safety stop keeps its code: 10 is the last of the list and 11 comes after 6, so neither replaces 4, 5 or 6.
// 11 is not a safety stop: no safety check of the core acted (else 4, 5 or 6 would be the code), the stall came
// from the host, and a restarted station rejoins its session; the systemd unit restarts it like 3 and 7.
// The edge-drop rule (a packet over its index-delay bound) is named in the conditions
// ("edge_drop_rule_acted", counts in "gate") without a code of its own: it is eq. (18)'s own
// over-bound action, and a lab run may see a few drop events on an honest network.
enum ExitCode : int {
  kExitOk = 0,
  kExitConfigError = 2,
  kExitRunFailed = 3,
  kExitDiverged = 4,
  kExitSafeState = 5,
  kExitPassivityNotMet = 6,
  kExitNoNeighbour = 7,
  kExitBeforeRelease = 8,
  kExitDeviceMissing = 9,
  kExitHeldByGate = 10,
  kExitMissedCycles = 11,
  kExitKeyCompromise = 12,
  kExitNeighbourIsolated = 13,
};

// Safety stops: the exits after which force output stays off until the operator has looked (only
// the operator re-arms, drivers/README.md "Safe state"). The systemd unit lists them in
// RestartPreventExitStatus; tests/firmware/deploy/unit_check.sh reads this list and fails if the installed
// unit would restart any of them.
inline constexpr int kSafetyStopExitCodes[] = {kExitDiverged, kExitSafeState, kExitPassivityNotMet};

// One paragraph for --help and the README. Not RT-safe.
std::string exit_code_help();

}  // namespace haptic::firmware
