#!/usr/bin/env bash
# A station the host stalls says so: four `haptic-station run` processes over UDP on loopback
# (tools/run4/run4.sh, paper-best star, 8 s run), the hub (station 1) stopped with SIGSTOP about 1.5 s
# into the run and continued 2.5 s later (~1,250 periods at 2 ms). The hub must exit 11 (missed
# cycles, firmware/station/phase.hpp) with "missed_cycles" in station-1.json's conditions,
# missed_cycles_total above station.max_missed_cycles (default 500) and a log line saying so.
# The leaves' exits are printed (they see the hub silent, typically exit 7) but not checked.
# Bounded: every wait has a limit, the stopped process is always continued (trap), run4.sh stops
# every station after its planned time + 20 s. No root (UDP on 127.0.0.1).
# Usage: missed_cycles_check.sh HAPTIC_STATION_BIN WORK_DIR
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
bin="$1"; work="$2"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$work"
rm -rf "$work"; mkdir -p "$work"
out="$work/run"
stopped=""
cleanup() { [ -n "$stopped" ] && kill -CONT "$stopped" 2>/dev/null || true; }
QUIET_HOST_CLEANUP=cleanup  # run by quiet_host.sh's EXIT trap
"$repo/tools/run4/run4.sh" --transport udp --bin "$bin" --out "$out" --duration 8 --push-end 2.5 --release 5 \
    --no-plots > "$work/run4.log" 2>&1 &
run4=$!
# the run phase starts when haptic-lab's progress line says "running" (bounded: 60 s)
for _ in $(seq 600); do
  grep -q "running," "$work/run4.log" 2>/dev/null && break
  kill -0 "$run4" 2>/dev/null || break
  sleep 0.1
done
grep -q "running," "$work/run4.log" || { echo "FAIL: the run never started"; cat "$work/run4.log"; wait "$run4" || true; exit 1; }
hub=$(head -n 1 "$out/station-pids.txt")
sleep 1.5
stopped="$hub"
kill -STOP "$hub"
t0=$(date +%s.%N)
sleep 2.5
kill -CONT "$hub"
t1=$(date +%s.%N)
stopped=""
echo "station 1 (pid $hub) stopped for $(awk "BEGIN { printf \"%.2f\", $t1 - $t0 }") s"
wait "$run4" || true  # the leaves fail (exit 7): run4.sh exits 1; station-1.json is what this checks
/usr/bin/python3 - "$out" "$out/station-1.log" <<'PY'
import glob, json, sys
out, log = sys.argv[1], sys.argv[2]
for f in sorted(glob.glob(out + "/station-[0-9].json")):
    d = json.load(open(f))
    print("%s: exit %s, missed_cycles_total %s, conditions %s" % (f.rsplit("/", 1)[1], d.get("exit_code"), d.get("missed_cycles_total"), d.get("conditions")))
hub = json.load(open(out + "/station-1.json"))
fail = []
if hub.get("exit_code") != 11:
    fail.append("the stopped hub exited %s, not 11 (missed cycles)" % hub.get("exit_code"))
if "missed_cycles" not in (hub.get("conditions") or []):
    fail.append("station-1.json's conditions do not name missed_cycles")
if not hub.get("missed_cycles_total", 0) > hub.get("max_missed_cycles", 500):
    fail.append("missed_cycles_total %s not above max_missed_cycles %s" % (hub.get("missed_cycles_total"), hub.get("max_missed_cycles")))
text = open(log).read()
if "missed" not in text or "station.max_missed_cycles" not in text:
    fail.append("station-1.log does not say it missed cycles")
for m in fail:
    print("FAIL: " + m)
if not fail:
    print("ok: the stopped hub exits 11 and names missed_cycles (%d missed cycles)" % hub["missed_cycles_total"])
sys.exit(1 if fail else 0)
PY
