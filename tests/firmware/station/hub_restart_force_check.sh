#!/usr/bin/env bash
# A hub killed and restarted is not felt at the neighbours: four `haptic-station run` processes over
# UDP on loopback (tools/run4/run4.sh, paper-best star, paper impairment), the hub (station 1)
# SIGKILLed at run time 5 s, during the hold, and restarted at 8 s with the same configuration (the
# lab options of station_run4_rejoin: net.tx_direct, net.io_cpu = 0, device.ramp_in_s = 1). It must
# rejoin and bring the copies to consensus again (tools/run4/rejoin_check.py), and no neighbour's
# user force may change by more than 0.1 N within any 100 ms from 0.1 s before the kill until the
# release (tools/run4/rejoin_jolt.py --max-N 0.1, window `whole`): at the kill the hub's data age
# out and its edge is released over station.drop_fade_s (rt/drop_fade.hpp); at the restart the
# copies, drifted apart while the hub was away, are pulled together again (rt/return_ramp.hpp).
# Printed, not checked: the kill and rejoin parts, and the undisturbed hold before the kill. Every
# station must exit 0 (an energy gate that acted fails; the figures are printed all the same).
# Bounded: run4.sh stops every process after its planned time + 20 s. No root (UDP on 127.0.0.1).
# Usage: hub_restart_force_check.sh HAPTIC_STATION_BIN WORK_DIR
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
bin="$1"; work="$2"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$work"
rm -rf "$work"; mkdir -p "$work"
out="$work/kill-1"
rc=0
if ! "$repo/tools/run4/run4.sh" --transport udp --bin "$bin" --out "$out" --duration 16 --release 13 --kill 1:5:8 \
     --no-plots --state-every 1 --station max_no_neighbour_fraction=0.5 --net tx_direct=true --net io_cpu=0 --device ramp_in_s=1 \
     > "$work/run4.log" 2>&1; then
  echo "hub_restart_force_check.sh: a station of the run with the hub killed and restarted failed (their error lines):" >&2
  grep -h "FAILED\|error:" "$out"/station-*.log >&2 || tail -n 30 "$work/run4.log" >&2
  rc=1
  [ -f "$out/restart.json" ] || exit 1  # no restart: nothing to measure
fi
/usr/bin/python3 "$repo/tools/run4/rejoin_check.py" --station "$bin" "$out" || rc=1
/usr/bin/python3 "$repo/tools/run4/rejoin_jolt.py" "$out" --max-N 0.1 --json "$work/jolt.json" || rc=1
exit $rc
