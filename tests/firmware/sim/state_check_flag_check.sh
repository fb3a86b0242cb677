#!/usr/bin/env bash
# `sim --state-check-kinematic-m M`: the simulator runs every station's neighbour state check (off by
# default: the paper outputs unchanged). Checks: without the flag summary.json has no "state_check" and
# no link "state_check_isolations"; with it summary.json names the threshold and the paper-best run (honest
# stations, no liar: liars are test code) isolates no one; trace.csv is the same bytes either way.
# Usage: state_check_flag_check.sh HAPTIC_STATION WORK_DIR
set -euo pipefail
bin="$1"; work="$2"
rm -rf "$work"; mkdir -p "$work"
"$bin" sim --scenario paper-best --duration 1.5 --out "$work/off" --no-plots > "$work/off.log" 2>&1
"$bin" sim --scenario paper-best --duration 1.5 --state-check-kinematic-m 2e-4 --out "$work/on" --no-plots > "$work/on.log" 2>&1
cmp "$work/off/trace.csv" "$work/on/trace.csv"
/usr/bin/python3 - "$work" <<'PY'
import json, sys
off = json.load(open(sys.argv[1] + "/off/summary.json"))
on = json.load(open(sys.argv[1] + "/on/summary.json"))
fail = []
if "state_check" in off or any("state_check_isolations" in l for l in off["link_stats"]):
    fail.append("the check off: summary.json names it")
if on.get("state_check", {}).get("kinematic_m") != 2e-4:
    fail.append("the check on: summary.json state_check %s" % on.get("state_check"))
iso = [l.get("state_check_isolations") for l in on["link_stats"]]
if iso != [0] * len(on["link_stats"]):
    fail.append("the check on: isolations per link %s (an honest paper-best run isolates no one)" % iso)
print("state_check %s, isolations per link %s" % (on.get("state_check"), iso))
for m in fail: print("FAIL: " + m)
sys.exit(1 if fail else 0)
PY
