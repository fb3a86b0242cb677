#!/usr/bin/env bash
# A short four-station run (tools/run4/run4.sh, UDP on loopback) recorded with LTTng
# (tools/trace/record.sh) and analysed (tools/trace/analyze.py). Per station, the trace must
# agree with the station's own loop counters (station-N.json "loop": ticks, overruns, missed
# cycles), and the tick's per-stage breakdown must hold every stage the station emits
# (device_read, rx_drain, solve, publish, tx, monitor) with stage time <= tick execution time.
# Fails with the reason when tracing is impossible here (LTTng compiled out or lttng missing).
# Counts only its own four processes (their PIDs from run4.sh's station-pids.txt). The lab
# configurations' options (firmware/deploy/lab-4-stations: net.tx_direct = true, net.io_cpu = 0). Under run4.sh's emulated impairment the pushes take the I/O
# thread's path (direct TX declines an impaired link: io_thread.tx_direct_declined); the shipped lab
# run, station_device_documented_lab, has the tick send every push itself.
set -euo pipefail
bin="$1"; out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
[ -x /usr/bin/python3 ] || { echo "FAILED: /usr/bin/python3 (python3-bt2, numpy) missing"; exit 1; }
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$out"
rm -rf "$out"; mkdir -p "$out"
set +e
"$repo/tools/trace/record.sh" -o "$out/trace" -- "$repo/tools/run4/run4.sh" --transport udp --bin "$bin" --out "$out/run" \
  --duration 3 --push-end 1.0 --release 2.0 --probe 1.0 --seed 2 --no-plots --net tx_direct=true --net io_cpu=0 > "$out/record.log" 2>&1
rc=$?
set -e
if [ $rc -ne 0 ]; then cat "$out/record.log"; echo "FAILED: record.sh around run4.sh exited $rc (3 = tracing impossible here)"; exit 1; fi
# Only this run's own station processes (the PIDs run4.sh started), not other haptic-station
# processes traced meanwhile on a shared machine.
[ -s "$out/run/station-pids.txt" ] || { echo "FAILED: run4.sh wrote no station-pids.txt"; exit 1; }
/usr/bin/python3 "$repo/tools/trace/analyze.py" "$out/trace" --procname haptic-station --vpids "@$out/run/station-pids.txt" --json "$out/analysis.json" > "$out/analyze.log" 2>&1 \
  || { cat "$out/analyze.log"; echo "FAILED: analyze.py"; exit 1; }
/usr/bin/python3 - "$out" <<'PY'
import json, sys, os
out = sys.argv[1]
a = json.load(open(os.path.join(out, "analysis.json")))
stations = [json.load(open(os.path.join(out, "run", "station-%d.json" % i))) for i in range(1, 5)]
blocks = a["stations"] if isinstance(a, dict) and "stations" in a else a
fail = []
if isinstance(a, dict) and a.get("discarded_events", 0):
    fail.append("the tracer discarded %d events" % a["discarded_events"])
if len(blocks) != 4:
    fail.append("%d traced stations, expected 4" % len(blocks))
need = ["device_read", "rx_drain", "solve", "publish", "tx", "monitor"]
used = set()
for i, s in enumerate(stations, 1):
    # The process traces its one loop over its whole life (probe, set-up gap, run): station_loop.
    loop = {k: s["station_loop"][k] for k in ("ticks", "overruns", "missed_cycles")}
    match = [j for j, b in enumerate(blocks) if j not in used and b["ticks"] == loop["ticks"] and b["overruns"] == loop["overruns"]
             and b["missed_cycles"] == loop["missed_cycles"]]
    if not match:
        fail.append("station %d: loop counters %s match no traced station %s" % (
            i, loop, [(b["ticks"], b["overruns"], b["missed_cycles"]) for b in blocks]))
        continue
    b = blocks[match[0]]
    used.add(match[0])
    missing = [n for n in need if n not in b["stages"]]
    if missing:
        fail.append("station %d: stages %s missing from the breakdown %s" % (i, missing, sorted(b["stages"])))
    share = sum(b["stage_share_of_exec"].get(n, 0.0) for n in need)
    if not share <= 1.0 + 1e-6:
        fail.append("station %d: stages add up to %.2f of the tick execution time" % (i, share))
    print("station %d: %d ticks, %d overruns, %d missed cycles; stage share of the tick: %s" % (
        i, b["ticks"], b["overruns"], b["missed_cycles"],
        ", ".join("%s %.0f%%" % (n, 100 * b["stage_share_of_exec"].get(n, 0.0)) for n in need)))
if fail:
    print("FAILED: " + "; ".join(fail)); sys.exit(1)
PY
