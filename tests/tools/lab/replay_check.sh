#!/usr/bin/env bash
# A run folder replayed on one timeline (haptic-lab replay; tools/lab/README.md "Replay a run folder"):
#   1. a folder with no station-N.h5 is refused (exit 2) saying how to record them;
#   2. the four session logs of a recorded run (`sim --record`: every station's log in one folder, as a
#      lab run with station.record = true leaves them) are each replayed by `haptic-station replay
#      --view-port` and one page drives them: opened in headless Chromium at run time 2.0 s and at 3.0 s
#      (?t=S&pause), every station's view serves its frame at that run time (the page's table is each
#      station's frame as its view server sent it), not where its own timeline stood;
#   3. stopped (SIGTERM), it reports each station's replay: stations 1, 3, 4 bit-exact, station 2 (one
#      packet value changed in its last bit with h5py) differing at a tick: exit 4;
#   4. a log that cannot be replayed (not HDF5) makes it exit 4 naming the station.
# Exit 77 (skipped) without Debian's chromium or python3-h5py. Usage: replay_check.sh BUILD_BIN_DIR WORK_DIR (~40 s)
set -uo pipefail
bin="$1"; work="$2"
chrome=$(command -v chromium || true)
[ -n "$chrome" ] || { echo "SKIPPED: chromium is not installed (apt-get install chromium)"; exit 77; }
/usr/bin/python3 -c 'import h5py' 2>/dev/null || { echo "SKIPPED: python3-h5py missing (apt-get install python3-h5py)"; exit 77; }
rm -rf "$work"; mkdir -p "$work/empty"
fail() { echo "FAILED: $*"; exit 1; }
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done' EXIT
lab="$bin/haptic-lab"

out=$("$lab" replay "$work/empty" --for 5 2>&1); rc=$?
[ "$rc" = 2 ] && grep -q "no station-N.h5 session log (record them: \[station\] record = true" <<<"$out" || { echo "$out"; fail "an empty folder: exit $rc"; }
echo "ok: a folder without session logs is refused (exit 2) saying how to record them"

"$bin/haptic-station" sim --scenario paper-best --out "$work/run" --duration 4 --push-end 1 --release 2 --record --no-plots --quiet \
  > "$work/sim.log" 2>&1 || { cat "$work/sim.log"; fail "sim --record failed"; }
/usr/bin/python3 - "$work/run/station-2.h5" <<'PY' || fail "h5py could not change station 2's log"
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r+") as f:  # one packet value of station 2 changed in its last bit: its replay differs
    x = f["packets/x"]
    x[200, 7] = np.nextafter(x[200, 7], np.inf)
PY
"$lab" replay "$work/run" --for 200 > "$work/replay.log" 2>&1 &
pids+=($!)
url=""
for _ in $(seq 1 600); do
  url=$(sed -n 's/^haptic-lab replay: \(http:[^ ]*\) .*/\1/p' "$work/replay.log"); [ -n "$url" ] && break
  kill -0 "${pids[0]}" 2>/dev/null || break; sleep 0.1
done
[ -n "$url" ] || { cat "$work/replay.log"; fail "haptic-lab replay printed no URL"; }
times() {  # times S: each station's frame time (s) on the page opened at run time S, paused
  timeout 120 "$chrome" --headless=new --no-sandbox --disable-gpu --enable-unsafe-swiftshader --use-angle=swiftshader \
    --user-data-dir="$work/profile-$1" --virtual-time-budget=8000 --dump-dom "${url}?t=$1&pause=1" 2>"$work/chrome-$1.log" |
    sed 's/<tr /\n<tr /g' | sed -n 's/.*<tr class="station" id="station-\([0-9]*\)" data-t="\([0-9.]*\)".*/\1 \2/p'
}
for at in 2.0 3.0; do
  got=$(times "$at")
  [ "$(grep -c . <<<"$got")" = 4 ] || { echo "$got"; fail "the page at t = $at shows $(grep -c . <<<"$got") stations' frames, not 4"; }
  # each station's frame: the first kept frame at or after the run time (frames ~34 ms apart at 30 Hz)
  awk -v at="$at" '{ if ($2 < at || $2 - at > 0.1) { print "station " $1 " shows t = " $2; bad = 1 } } END { exit bad }' <<<"$got" ||
    fail "at t = $at not every station's view shows its frame at that run time"
  echo "ok: page opened at t = $at: stations' frames at $(awk '{printf "%s ", $2}' <<<"$got")s"
done
kill -TERM "${pids[0]}"; wait "${pids[0]}"; rc=$?; pids=()
[ "$rc" = 4 ] && [ "$(grep -c 'exit 0: replay of station [134] (sim log): .* bit-exact at every tick' "$work/replay.log")" = 3 ] &&
  grep -q "station 2: exit 3: .*state hash differs first at tick" "$work/replay.log" ||
  { cat "$work/replay.log"; fail "haptic-lab replay: exit $rc (not 4), or stations 1, 3, 4 not bit-exact, or station 2's changed packet not named"; }
echo "ok: stopped (SIGTERM): stations 1, 3, 4 replayed bit-exactly; station 2's changed packet named (exit 3): exit 4"

echo "not a session log" > "$work/run/station-5.h5"
out=$("$lab" replay "$work/run" --for 30 2>&1); rc=$?
[ "$rc" = 4 ] && grep -q "station 5: haptic-station replay .*station-5.h5 exited 2" <<<"$out" || { echo "$out"; fail "a bad log: exit $rc, or station 5 not named"; }
echo "ok: a log that cannot be replayed exits 4 naming station 5"
