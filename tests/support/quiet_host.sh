# Sourced by the tests that run several station processes on this host at once (four-station runs,
# a lab from one file, rejoin, replay, view): they need a host that keeps the stations' period.
#
#   quiet_host_or_skip BIN_DIR OUT_DIR
#
# measures this host's wake-up latency first (build/bin/haptic-jitter: the station's own periodic
# loop, at its period, 1 s, no workload, at SCHED_OTHER: the class these runs' I/O threads
# (station.io_priority = 0) and start-up run at; a SCHED_FIFO tick barely sees a load of ordinary
# processes, the I/O thread that sends its packets does) and, when the P99 is over
# the limit, exits 77 (CTest: skipped, SKIP_RETURN_CODE) printing
#   SKIPPED: host too loaded: wake-up P99 X ms (limit Y ms) ...
# a visible skip with its figure, never a silent pass. Otherwise it returns, and if the test then
# fails (any exit but 0 and 77) an EXIT trap measures the host again and prints, for each station
# file under OUT_DIR, the station's own verdict on its host during the run (station-<id>.json
# "host", the starving-host rule of platform::host_starving) and why it exited.
#
# The limit, from the period T and the index-delay guard N̄ the runs use: a neighbour's data is used
# while it is at most N̄ ticks old. On one host a packet's age at the receiving tick grows with how
# late the sending station's I/O thread sent it and how late the receiving one took it in, both
# starved by the same load, so each may be late by N̄ T / 2 before the packet misses the guard. A host whose wake-up P99 is over
# N̄ T / 2 loses the guard on 1 % of the ticks from scheduling alone: the run then measures the host,
# not the code. These runs: T = 2 ms and N̄ >= 10 ticks (a loopback link's probe-measured loss
# allowance alone is 8-12 ticks of the round trip, R = 20-26 ticks, N̄ = ceil(R/2) = 10-13), so the
# limit is 10 ms; a normally loaded machine wakes the tick at P99 0.3-0.5 ms (tools/trace/README.md).
# QUIET_HOST_PERIOD_MS and QUIET_HOST_NBAR change T and N̄ for a test that runs others;
# QUIET_HOST_LIMIT_MS replaces the limit (only the test of this script uses it).

quiet_host_measure() {  # BIN_DIR -> prints "P99_MS MAX_MS" (or nothing when the tool is missing)
  local jitter="$1/haptic-jitter" period_ms="${QUIET_HOST_PERIOD_MS:-2}" j
  [ -x "$jitter" ] || return 0
  j="$(mktemp)"
  if "$jitter" -i "$(awk -v t="$period_ms" 'BEGIN{printf "%d", t*1000}')" -w 0 -D 1 -q --sched-other --no-mlock --json "$j" >/dev/null 2>&1; then
    /usr/bin/python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["runs"][0]["latency_us"]; print("%.3f %.3f" % (r["p99"]/1e3, r["max"]/1e3))' "$j"
  fi
  rm -f "$j"
}

quiet_host_limit_ms() {
  if [ -n "${QUIET_HOST_LIMIT_MS:-}" ]; then echo "$QUIET_HOST_LIMIT_MS"; return; fi
  awk -v t="${QUIET_HOST_PERIOD_MS:-2}" -v n="${QUIET_HOST_NBAR:-10}" 'BEGIN{printf "%g", n*t/2}'
}

# The EXIT trap: the test's own clean-up first (QUIET_HOST_CLEANUP, a command: a test that needs
# one sets it instead of a trap of its own), then, after a failed run, the host now and each
# station's own figures and verdict during the run; the test's exit status is kept.
quiet_host_on_exit() {
  local rc=$?
  if [ -n "${QUIET_HOST_CLEANUP:-}" ]; then $QUIET_HOST_CLEANUP || true; fi
  quiet_host_after_failure "$rc" "$1" "$2" || true
  exit "$rc"
}

quiet_host_after_failure() {
  local rc="$1" bin_dir="$2" out="$3" m limit
  if [ "$rc" -eq 0 ] || [ "$rc" -eq 77 ]; then return 0; fi
  limit="$(quiet_host_limit_ms)"
  m="$(quiet_host_measure "$bin_dir")"
  echo "--- the test failed (exit $rc); was the host starving? ---"
  if [ -n "$m" ]; then
    set -- $m
    echo "host re-measured after the run: wake-up P99 $1 ms, max $2 ms (limit $limit ms): $(awk -v p="$1" -v l="$limit" 'BEGIN{print (p>l)?"TOO LOADED now":"quiet enough now"}')"
  fi
  find "$out" -name 'station-*.json' 2>/dev/null | sort | while read -r f; do
    /usr/bin/python3 - "$f" <<'PY' || true
import json, sys
s = json.load(open(sys.argv[1]))
h = s.get("host")
if not h:
    print("%s: exit %s, no host figures (no loop ran, or a station file without \"host\")" % (sys.argv[1], s.get("exit_code")))
else:
    fig = "wake-up P99 %s ms, max %s ms, %s overruns, %s skipped periods in %s ticks of the %s loop" % (
        h.get("wake_p99_ms"), h.get("wake_max_ms"), h.get("overruns"), h.get("missed_cycles"), h.get("ticks"), h.get("loop"))
    print("%s: exit %s, host during the run %s (%s)" % (sys.argv[1], s.get("exit_code"), "STARVING" if h.get("starving") else "kept its period", fig))
for line in (s.get("explanation") or {}).get("lines", []):
    print("  " + line)
PY
  done
}

quiet_host_or_skip() {
  local bin_dir="$1" out="$2" m limit
  limit="$(quiet_host_limit_ms)"
  m="$(quiet_host_measure "$bin_dir")"
  if [ -z "$m" ]; then
    echo "host check: $bin_dir/haptic-jitter missing or failed: not measured, running anyway"
  else
    set -- $m
    if awk -v p="$1" -v l="$limit" 'BEGIN{exit !(p>l)}'; then
      echo "SKIPPED: host too loaded: wake-up P99 $1 ms (limit $limit ms = N̄ T / 2 with T = ${QUIET_HOST_PERIOD_MS:-2} ms, N̄ = ${QUIET_HOST_NBAR:-10}); max $2 ms; load $(cut -d' ' -f1-3 /proc/loadavg)"
      exit 77
    fi
    echo "host check: wake-up P99 $1 ms, max $2 ms (limit $limit ms): running"
  fi
  trap "quiet_host_on_exit '$bin_dir' '$out'" EXIT
}
