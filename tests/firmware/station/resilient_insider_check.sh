#!/usr/bin/env bash
# An authenticated insider on a 3-robust topology with the resilient rule (rt/README.md "Resilient
# consensus" and "What bounds a consistent lie"): five `haptic-station run` processes over UDP on
# loopback (one haptic-lab lab file per case: paper-best's object and user script for five users, 10 ms
# mean delays with the paper impairment, 6 s run), on the graph `haptic-topology --users 5 --seed 1
# --robustness 3` ranks best (1-2 1-3 1-4 1-5 2-3 2-4 3-4 3-5 4-5: K_5 without 2-5, 3-robust), every
# station with station.resilient_f = 1. Station 1 is haptic-insider (a TEST-ONLY build of the station,
# insider_main.cpp) lying from run time 1 s: a constant 2 cm offset, a 1 cm oscillation at the lowest
# elastic mode, a 2 mm/s ramp, and a 4 mm/s ramp whose reported velocities say so ("consistent": the
# kinematic check cannot see it). Then the same without a lie, and the consistent lie with
# resilient_f = 0 (what the rule is worth). Checks:
#  - clean: nobody isolated, every station exits 0;
#  - offset / mode / ramp: stations 2-5 isolate station 1 as inconsistent with its velocities, name it
#    in their log (a line written when it happened, "isolated station 1 at run time") and json, exit 13;
#  - consistent, F = 1: no isolation (K cannot see it), each honest station left station 1 out on at
#    least 90 % of the ticks from 1.5 s (the resilient rule names it: resilient_excluded_ticks per link,
#    aggregated by haptic-station merge into summary.json);
#  - every lie with F = 1: the honest four reach consensus among themselves: the largest distance of
#    one node between two honest copies over the run's last 0.5 s (the measure of "consensus < 1 mm"
#    in summary.json) is below CONSENSUS_MM = 1 mm, and the honest copies' mean end position is
#    within DRAG_MM = 2 mm of the clean run's (the clean run's own figures are printed: the
#    run-to-run variation of real-time runs);
#  - the consistent lie with F = 0: its drag is printed for comparison (not checked: with F = 0 nothing
#    but the envelope and the energy gate bounds it); a station whose gate tripped exits 10 and logged the
#    trip when it happened ("energy gate tripped on station 1's edge");
#  - summary.json (haptic-station merge): resilient_excluded_ticks = the links' sum (absent with F = 0),
#    state_check isolations = the links' sum, one flag per isolating link.
# Bounded: haptic-lab stops every station after its planned time + 20 s. No root.
# Usage: resilient_insider_check.sh BIN_DIR WORK_DIR  (BIN_DIR holds haptic-station, haptic-insider, haptic-jitter)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
source "$here/insider_bin.sh"                  # the wrapper that makes station 1 the insider
source "$here/../../support/quiet_host.sh"     # a measured "host too loaded" skip, and the host after a failure
bindir="$(cd "$1" && pwd)"; work="$2"
insider_skip_unless_built "$bindir"
quiet_host_or_skip "$bindir" "$work"
repo="$(cd "$here/../../.." && pwd)"
rm -rf "$work"
insider_bin "$bindir" "$work"  # station 1 runs as haptic-insider when INSIDER_LIE is set
export HAPTIC_BIN_DIR="$work/bin"
lab="$repo/tools/lab/haptic-lab"
run_case() {  # NAME LIE AMPLITUDE F
  echo "--- $1 (resilient_f = $4)"
  cat > "$work/$1.toml" <<LAB
[lab]
users = 5
scenario = "paper-best"
nodes = 33
duration_s = 6
push_end_s = 2
release_s = 4
seed = 1
probe_s = 1.5
start_delay_s = 4.0
[network]
transport = "udp"
impairment = "paper"
[topology]
links = "1-2,1-3,1-4,1-5,2-3,2-4,3-4,3-5,4-5"
[rt]
priority = 80
lock_memory = true
[station]
state_every = 5
resilient_f = $4
LAB
  local rc=0
  { "$lab" plan "$work/$1.toml" --run-dir "$work/$1" && "$lab" check "$work/$1" && \
    INSIDER_LIE="$2" INSIDER_AMPLITUDE="$3" "$lab" start "$work/$1" --no-console; } > "$work/$1.log" 2>&1 || rc=$?  # a lie's honest stations exit 13
  "$lab" collect "$work/$1" --no-plots >> "$work/$1.log" 2>&1 || { echo "collect failed (start exit $rc):"; tail -n 30 "$work/$1.log"; exit 1; }
  tail -n 2 "$work/$1.log"
}
run_case clean "" 0 1
run_case offset offset 0.02 1
run_case mode mode 0.01 1
run_case ramp ramp 0.002 1
run_case consistent consistent 0.004 1
run_case consistent-f0 consistent 0.004 0
/usr/bin/python3 "$here/resilient_insider_check.py" "$work"
