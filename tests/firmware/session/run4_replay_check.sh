#!/usr/bin/env bash
# A recorded four-process run replays bit-exactly for every station: four
# `haptic-station run` processes over UDP on loopback with station.record = true, then
# `haptic-station replay` on each station's log must match the recorded state hash at every tick
# with no input lost (~10 s; multi-process: run it under /tmp/haptic-multiproc.lock).
set -uo pipefail
bin="$1"; out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
[ -x /usr/bin/python3 ] || { echo "SKIPPED: /usr/bin/python3 (Debian python3-numpy) missing for the merge"; exit 77; }
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$out"
rm -rf "$out"; mkdir -p "$out"
"$repo/tools/run4/run4.sh" --transport udp --bin "$bin" --out "$out" --duration 3 --push-end 1 --release 2 \
  --probe 1.0 --seed 2 --no-plots --station record=true > "$out/run4.log" 2>&1 \
  || { echo "FAILED: run4.sh"; tail -30 "$out/run4.log"; exit 1; }
fail=0
for i in 1 2 3 4; do
  log="$out/station-$i.h5"
  [ -f "$log" ] || { echo "FAILED: no $log"; fail=1; continue; }
  "$bin" replay "$log" > "$out/replay-$i.log" 2>&1; rc=$?
  if [ $rc -ne 0 ] || ! grep -q "bit-exact at every tick" "$out/replay-$i.log"; then
    echo "FAILED station $i (exit $rc): $(cat "$out/replay-$i.log")"; fail=1
  else
    echo "ok station $i: $(cat "$out/replay-$i.log")"
  fi
done
/usr/bin/python3 - "$out" <<'PY' || fail=1
import json, sys
for i in range(1, 5):
    r = json.load(open("%s/station-%d.json" % (sys.argv[1], i)))["recording"]
    print("station %d: %d ticks, %d packets recorded, %d dropped, %.1f MB" % (i, r["ticks"], r["packets"], r["dropped_records"], r["bytes"] / 1e6))
    if r["ticks"] < 1000 or r["packets"] < 500 or r["dropped_records"] != 0 or r["error"]:
        print("FAILED: station %d recording %s" % (i, r)); sys.exit(1)
PY
exit $fail
