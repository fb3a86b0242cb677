#!/usr/bin/env bash
# The lab console (haptic-lab start's one page for the whole lab) in headless Chromium, for a loopback
# lab of USERS stations (4: a ring; 16: tools/lab/examples/loopback-16.toml, the optimizer's topology):
#   1. `haptic-lab start` serves the console and prints its URL and every station's view URL;
#   2. once /lab.json says every station runs (its live view's /status.json), a screenshot of the page
#      (console-USERS.png, not blank) and its DOM (--dump-dom): every station's row shows its state
#      (running, t, tick, N / N-bar per neighbour, overruns); a missing or stale station fails, named;
#   3. a station stopped with SIGSTOP turns "stale" and red (lab.json and the page);
#   4. the page's stop-all (POST /stop with its token) ends every station (SIGTERM): `start` returns
#      and every station wrote station-N.json;
#   5. `haptic-lab console RUN` alone shows every station "done" with the exit code of its station-N.json.
# Multi-process (run serially): a measured "host too loaded" skip (tests/support/quiet_host.sh); exit 77
# without Debian's chromium.
# Usage: console_check.sh BUILD_BIN_DIR SOURCE_DIR WORK_DIR USERS
set -uo pipefail
bin="$1"; src="$2"; work="$3"; users="$4"
here="$(cd "$(dirname "$0")" && pwd)"
chrome=$(command -v chromium || true)
[ -n "$chrome" ] || { echo "SKIPPED: chromium is not installed (apt-get install chromium)"; exit 77; }
rm -rf "$work"; mkdir -p "$work"
pids=()
spid=""
cleanup() { [ -z "$spid" ] || kill -CONT "$spid" 2>/dev/null; for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; }  # a stopped station continued, then SIGTERM to start (it ends its stations)
source "$here/../../support/quiet_host.sh"
QUIET_HOST_CLEANUP=cleanup
quiet_host_or_skip "$bin" "$work"
lab="$bin/haptic-lab"
fail() { echo "FAILED: $*"; exit 1; }
base=$(( 23100 + ($$ % 40) * 20 ))  # station i's live view on base + i - 1 (below the ephemeral ports, 32768+)
stations='view_rate_hz = 5                  # the console polls 2/s: a slow view keeps 16 stations light
max_no_neighbour_fraction = 1.0   # this checks the console, not host timing (a loaded VM stalls)
loss_allowance_ticks = 1'
if [ "$users" = 16 ]; then
  # a later epoch than the example's 3 s: sixteen stations start up on a loaded 2-core host in time
  sed -e 's/^duration_s = .*/duration_s = 100.0/' -e 's/^start_delay_s = .*/start_delay_s = 8.0/' \
      -e 's/^max_evaluations = .*/max_evaluations = 50/' -e "s/^\[lab\]$/[lab]\nview_port_base = $base/" \
      "$src/tools/lab/examples/loopback-16.toml" > "$work/lab.toml"
  printf '[station]\n%s\n' "$stations" >> "$work/lab.toml"
else
  cat > "$work/lab.toml" <<EOT
[lab]
users = $users
duration_s = 100.0
push_end_s = 1.0
release_s = 2.0
probe_s = 1.0
start_delay_s = 4.0
view_port_base = $base
[network]
transport = "udp"
[topology]
links = "$(seq -s, 1 "$users" | awk -F, '{for(i=1;i<NF;i++) printf "%d-%d,", $i, $(i+1); printf "%d-1", NF}')"
[station]
$stations
EOT
fi
run=$("$lab" plan "$work/lab.toml" --runs-dir "$work/runs" 2>"$work/plan.err" | tail -1)
[ -f "$run/plan.json" ] || { cat "$work/plan.err"; fail "haptic-lab plan failed"; }
"$lab" start "$run" --timeout 120 > "$work/start.log" 2>&1 &
start_pid=$!; pids+=("$start_pid")
url=""
for _ in $(seq 1 300); do
  url=$(sed -n 's/^haptic-lab console: \(http:[^ ]*\) .*/\1/p' "$work/start.log" | head -1)
  [ -n "$url" ] && break; sleep 0.1
done
[ -n "$url" ] || { cat "$work/start.log"; fail "haptic-lab start printed no console URL"; }
[ "$(grep -cE "^  station [0-9]+ \(127\.0\.0\.1\): live view http://127\.0\.0\.1:[0-9]+/$" "$work/start.log")" = "$users" ] ||
  { cat "$work/start.log"; fail "haptic-lab start did not print each of the $users stations' view URL"; }
grep -q "^  station $users (127.0.0.1): live view http://127.0.0.1:$(( base + users - 1 ))/$" "$work/start.log" ||
  fail "station $users's view URL is not on port base + $users - 1"
echo "ok: console at $url, $users station view URLs printed"
# wait (bounded) until the console says every station runs; the page is checked whatever it says then
/usr/bin/python3 - "$url" "$users" <<'PY'
import json, sys, time, urllib.request
o = urllib.request.build_opener(urllib.request.ProxyHandler({}))
t0, states = time.monotonic(), {}
while time.monotonic() - t0 < 45:
    try:
        states = {r["station"]: r["state"] for r in json.loads(o.open(sys.argv[1] + "lab.json", timeout=2).read())["stations"]}
    except OSError:
        pass
    if len(states) == int(sys.argv[2]) and all(s == "running" for s in states.values()):
        break
    if states and all(s in ("done", "exited") for s in states.values()):
        break  # they all ended: the page is checked now and says so
    time.sleep(0.5)
print("console after %.1f s: %s" % (time.monotonic() - t0, " ".join("%s:%s" % kv for kv in sorted(states.items()))))
PY
kill -0 "$start_pid" 2>/dev/null || { cat "$work/start.log"; fail "the stations ended before the console page could be taken (station-N.log)"; }
shot_h=$(( 360 + 34 * users ))
# one chromium for both (a 2-core host loaded by the stations' real-time loops starts it slowly)
timeout 80 nice -n -10 "$chrome" --headless=new --no-sandbox --disable-gpu --hide-scrollbars --no-first-run --disable-extensions \
  --disable-background-networking --disable-component-update --disable-sync --user-data-dir="$work/profile-a" \
  --window-size=1500,$shot_h --screenshot="$work/console-$users.png" --dump-dom "$url" > "$work/dom-running.html" 2> "$work/chrome-shot.log"
[ -s "$work/console-$users.png" ] || { grep -v dbus "$work/chrome-shot.log" | tail -5; fail "chromium wrote no screenshot (in 80 s; load $(cut -d' ' -f1-3 /proc/loadavg))"; }
/usr/bin/python3 -c 'import sys, matplotlib.image as m, numpy as n; a = m.imread(sys.argv[1])[:, :, :3]
sys.exit(0 if n.mean(n.any(a < 0.9, axis=2)) > 0.01 else 1)' "$work/console-$users.png" || fail "the screenshot console-$users.png is blank"
/usr/bin/python3 "$here/console_dom.py" "$work/dom-running.html" "$users" running "$run" "$work/token" ||
  { tail -5 "$work/start.log"; fail "the console page does not show every station's state (screenshot $work/console-$users.png)"; }
# a station that stops moving (SIGSTOP: its loop and its view frozen) turns "stale" and red within a few
# seconds, the others still run; SIGCONT gives it back
spid=$(sed -n 2p "$run/station-pids.txt")
kill -STOP "$spid" || fail "cannot SIGSTOP station 2 (pid $spid)"
/usr/bin/python3 - "$url" <<'PY'; stale_rc=$?
import json, re, sys, time, urllib.request
o = urllib.request.build_opener(urllib.request.ProxyHandler({}))
t0 = time.monotonic()
while time.monotonic() - t0 < 20:
    rows = {r["station"]: r["state"] for r in json.loads(o.open(sys.argv[1] + "lab.json", timeout=5).read())["stations"]}
    page = o.open(sys.argv[1], timeout=5).read().decode()
    if rows[2] == "stale" and re.search(r'<tr class="station bad" id="station-2" data-station="2" data-state="stale">', page):
        print("ok: station 2 stopped: 'stale' and red on the page after %.1f s (others: %s)" % (time.monotonic() - t0, sorted(set(v for k, v in rows.items() if k != 2))))
        sys.exit(0)
    time.sleep(0.5)
sys.exit("FAILED: station 2 stopped, but the console still says %r" % rows[2])
PY
kill -CONT "$spid"
[ "$stale_rc" -eq 0 ] || fail "a stopped station is not flagged stale"
# stop-all: the page's form, with its token
/usr/bin/python3 - "$url" "$(cat "$work/token")" <<'PY' || fail "POST /stop was refused"
import sys, urllib.parse, urllib.request
o = urllib.request.build_opener(urllib.request.ProxyHandler({}))
class NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *a): return None
o.add_handler(NoRedirect())
try:
    o.open(sys.argv[1] + "stop", data=urllib.parse.urlencode({"token": "not-the-token"}).encode(), timeout=5)
    sys.exit("a stop without the page's token was accepted")
except urllib.error.HTTPError as e:
    assert e.code == 403, e.code
try:
    o.open(sys.argv[1] + "stop", data=urllib.parse.urlencode({"token": sys.argv[2]}).encode(), timeout=5)
except urllib.error.HTTPError as e:
    assert e.code == 303, e.code
PY
for _ in $(seq 1 300); do kill -0 "$start_pid" 2>/dev/null || break; sleep 0.1; done
kill -0 "$start_pid" 2>/dev/null && fail "haptic-lab start still runs 30 s after stop-all"
wait "$start_pid"; rc=$?; pids=()
grep -q "stop-all from the console: SIGTERM" "$work/start.log" || { cat "$work/start.log"; fail "start does not say the stop came from the console"; }
for i in $(seq 1 "$users"); do [ -s "$run/station-$i.json" ] || { cat "$work/start.log"; fail "station $i wrote no station-$i.json after stop-all"; }; done
echo "ok: stop-all from the page ended all $users stations (start exit $rc), each wrote station-N.json"
# the console alone, after the run: every station done, with its exit code
"$lab" console "$run" --for 60 > "$work/console.log" 2>&1 &
cpid=$!; pids+=("$cpid")
url2=""
for _ in $(seq 1 100); do url2=$(sed -n 's/^haptic-lab console: \(http:[^ ]*\) .*/\1/p' "$work/console.log" | head -1); [ -n "$url2" ] && break; sleep 0.1; done
[ -n "$url2" ] || { cat "$work/console.log"; fail "haptic-lab console printed no URL"; }
timeout 60 "$chrome" --headless=new --no-sandbox --disable-gpu --no-first-run --disable-extensions --disable-background-networking \
  --disable-component-update --disable-sync --user-data-dir="$work/profile-c" --dump-dom "$url2" \
  > "$work/dom-done.html" 2>> "$work/chrome-dom.log"
kill "$cpid"; wait "$cpid"; pids=()
/usr/bin/python3 "$here/console_dom.py" "$work/dom-done.html" "$users" done "$run" || fail "haptic-lab console does not show every station done with its exit code"
echo "ok: screenshot $work/console-$users.png"
