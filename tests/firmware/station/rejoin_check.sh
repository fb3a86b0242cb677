#!/usr/bin/env bash
# Rejoin after SIGKILL: four `haptic-station run` processes over UDP on
# loopback (tools/run4/run4.sh), paper-best star; a leaf (station 2), then the hub (station 1), is
# SIGKILLed at run time 5 s, during the hold, and restarted at 8 s with the same configuration.
# tools/run4/rejoin_check.py checks each run: rejoined (coupled) within 2 s of its restart, the copies
# in consensus (< 1 mm) at the end, no station's device force changing by more than the hold force
# from just before the kill to the release (tick to tick, within any 100 ms, and for the others away
# from its value at the restart). The lab configurations' options (net.tx_direct = true, net.io_cpu = 0; under
# the emulated impairment the pushes take the I/O thread's path, as run4_check.sh says) and a real
# device's default force ramp-in (device.ramp_in_s = 1; a simulated user's default is none, and
# without it the restarted station's own force rises from 0 to its hold force within 100 ms).
# Bounded: run4.sh stops every process after its planned time + 15 s.
# Third case: leaf 2 restarted WITHOUT the session's --start-at, so it plans a fresh future epoch
# (station.start_delay_s) and must see from its neighbours' run packets that the session runs.
# Usage: rejoin_check.sh HAPTIC_STATION_BIN WORK_DIR. No root needed (UDP on 127.0.0.1).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
bin="$1"; work="$2"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$work"
rm -rf "$work"; mkdir -p "$work"
rc=0
skipped=()
for case in 2 1 2-fresh; do
  who="${case%%-*}"; extra=(); [ "$case" = 2-fresh ] && extra=(--restart-fresh-epoch)
  out="$work/kill-$case"
  if ! "$repo/tools/run4/run4.sh" --transport udp --bin "$bin" --out "$out" --duration 14 --release 10 \
       --kill "$who:5:8" "${extra[@]}" --no-plots --state-every 1 --station max_no_neighbour_fraction=0.5 \
       --net tx_direct=true --net io_cpu=0 --device ramp_in_s=1 > "$work/run4-kill-$case.log" 2>&1; then
    # A station whose per-edge energy gate acted exits 10 (held by the gate) and says so: a reported
    # safeguard, not a failed rejoin; it is printed with the gate's figures and the worst port energy.
    # (A restarted station's eq. (13) account starts at 0 with the adopted, deformed state, whose stored
    # energy is not counted as d^2, so its port energy can go below 0 without any energy generated.)
    # A station that stopped for missed cycles (exit 11) on a host its own report calls starving is
    # the host's truthful stop, not the rejoin's: that case is a visible skip (77 at the end, if
    # nothing failed). Any other non-zero exit fails.
    judge=0
    /usr/bin/python3 - "$out" <<'PY' || judge=$?
import glob, json, sys
ok, starved = True, False
for f in sorted(glob.glob(sys.argv[1] + "/station-[0-9]*.json")):
    d = json.load(open(f))
    code, g = d.get("exit_code"), d.get("gate", {})
    if code == 0:
        continue
    if code == 10 and g.get("held_by_gate"):
        print("gate acted (reported, exit 10): %s: %d trip(s), %.4f J removed, worst port energy %.3g J"
              % (f.rsplit("/", 1)[1], g["energy_gate_trips"], g["energy_gate_removed_J"], g["port_energy_min_J"]))
        continue
    if code == 11 and (d.get("host") or {}).get("starving"):
        print("host starving (exit 11, %d skipped periods): %s" % (d.get("missed_cycles_total", -1), f.rsplit("/", 1)[1]))
        starved = True
        continue
    print("%s: exit %s" % (f, code))
    ok = False
sys.exit(1 if not ok else 3 if starved else 0)
PY
    if [ "$judge" -eq 3 ]; then
      echo "rejoin_check.sh: the run with station $who killed ($case): stations stopped for missed cycles on a starving host: not judged"
      skipped+=("$case"); continue
    elif [ "$judge" -ne 0 ]; then
      echo "rejoin_check.sh: the run with station $who killed ($case) failed:" >&2; tail -n 30 "$work/run4-kill-$case.log" >&2; rc=1; continue
    fi
  fi
  echo "--- station $who SIGKILLed at 5 s, restarted at 8 s${extra[*]:+ with a fresh epoch (no --start-at)}"
  /usr/bin/python3 "$repo/tools/run4/rejoin_check.py" --station "$bin" "$out" || rc=1
done
if [ "$rc" -eq 0 ] && [ "${#skipped[@]}" -gt 0 ]; then
  echo "SKIPPED (in part): case(s) ${skipped[*]}: stations stopped for missed cycles (exit 11) on a host they report starving; the other cases passed"
  exit 77
fi
exit $rc
