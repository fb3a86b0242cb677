#!/usr/bin/env bash
# Memory soak: four `haptic-station run` processes on UDP loopback (tools/run4/run4.sh, paper-best,
# simulated users, nice'd), their resident memory read from /proc/PID/status (VmRSS, VmHWM, VmLck)
# every --interval seconds into a CSV, then a plot of RSS against run time. The acceptance figure:
# RSS at 1 minute and at the end of the run within 10 % (printed at the end, and exit 1 when not).
# Usage: soak_rss.sh [--duration S] [--interval S] [--bin PATH] [--out DIR] [--csv FILE] [--plot FILE]
#                    [--nice N] [--run4 ARG]...
#   --duration S  run time of the stations (default 3600; station.duration_s allows up to 3600)
#   --interval S  seconds between samples (default 60)
#   --bin PATH    the haptic-station binary (default build/bin/haptic-station)
#   --out DIR     run4's output directory (default a new /tmp/soak.XXXXXX; the CSV files it
#                 streams are ~0.25 MB/s for the four stations, ~0.9 GB an hour)
#   --csv FILE    the samples (default tools/bench/results/soak_rss_<duration>s.csv)
#   --plot FILE   the plot (default the CSV's name with .png; needs matplotlib: /usr/bin/python3)
#   --nice N      niceness of the run (default 10)
#   --run4 ARG    passed to run4.sh (repeatable), e.g. --run4 --nodes --run4 33
# A loaded shared host misses cycles: the run is started with station.max_missed_cycles and
# station.max_no_neighbour_fraction relaxed, so a soak measures memory, not the host's scheduling.
# Bounded: run4.sh ends every station after its planned time + 20 s. Only the PIDs this script
# started (run4.sh and the stations it lists in station-pids.txt) are read or signalled.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
duration=3600; interval=60; bin="$repo/build/bin/haptic-station"; out=""; csv=""; plot=""; niceness=10; run4_extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) duration="$2"; shift 2 ;;
    --interval) interval="$2"; shift 2 ;;
    --bin) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --csv) csv="$2"; shift 2 ;;
    --plot) plot="$2"; shift 2 ;;
    --nice) niceness="$2"; shift 2 ;;
    --run4) run4_extra+=("$2"); shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    *) echo "soak_rss.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$duration" =~ ^[0-9]+$ ]] && [ "$duration" -ge 70 ] || { echo "soak_rss.sh: --duration must be a whole number of seconds >= 70, got '$duration'" >&2; exit 2; }
[[ "$interval" =~ ^[0-9]+$ ]] && [ "$interval" -ge 1 ] || { echo "soak_rss.sh: --interval must be a whole number of seconds >= 1, got '$interval'" >&2; exit 2; }
[ -x "$bin" ] || { echo "soak_rss.sh: $bin not found (build haptic-station, or pass --bin)" >&2; exit 2; }
[ -n "$out" ] || out="$(mktemp -d /tmp/soak.XXXXXX)"
[ -n "$csv" ] || csv="$repo/tools/bench/results/soak_rss_${duration}s.csv"
[ -n "$plot" ] || plot="${csv%.csv}.png"
mkdir -p "$out" "$(dirname "$csv")"

nice -n "$niceness" "$repo/tools/run4/run4.sh" --bin "$bin" --out "$out" --duration "$duration" --no-plots \
  --station max_missed_cycles=1000000000 --station max_no_neighbour_fraction=0.5 ${run4_extra[@]+"${run4_extra[@]}"} > "$out/run4.out" 2>&1 &
run4_pid=$!
echo "soak_rss.sh: run4.sh pid $run4_pid, out $out, duration $duration s, samples every $interval s into $csv"

# the four station PIDs (haptic-lab writes them when it started them)
pids=()
for _ in $(seq 1 600); do
  if [ -f "$out/station-pids.txt" ] && [ "$(wc -l < "$out/station-pids.txt")" -ge 4 ]; then mapfile -t pids < "$out/station-pids.txt"; break; fi
  kill -0 "$run4_pid" 2>/dev/null || break
  sleep 0.5
done
[ "${#pids[@]}" -ge 4 ] || { echo "soak_rss.sh: the stations never started (see $out/run4.out)" >&2; wait "$run4_pid" || true; exit 1; }
t0=$(date +%s.%N)
echo "t_s,station,pid,vm_rss_kB,vm_hwm_kB,vm_lck_kB" > "$csv"
sample() {  # one row per station still alive
  local now t i pid st
  now=$(date +%s.%N); t=$(echo "$now - $t0" | bc)
  for i in 0 1 2 3; do
    pid=${pids[$i]}
    st="/proc/$pid/status"
    [ -r "$st" ] || continue
    awk -v t="$t" -v s=$((i + 1)) -v p="$pid" '/^VmRSS:/{r=$2} /^VmHWM:/{h=$2} /^VmLck:/{l=$2} END{if (r != "") printf "%.1f,%d,%d,%d,%d,%d\n", t, s, p, r, h, l}' "$st" >> "$csv" || true
  done
}
# every interval until the run ends (bounded: run4.sh ends the stations after duration + 20 s)
end_by=$(( $(date +%s) + duration + 120 ))
next=$(( $(date +%s) + interval ))
while kill -0 "$run4_pid" 2>/dev/null && [ "$(date +%s)" -lt "$end_by" ]; do
  if [ "$(date +%s)" -ge "$next" ]; then sample; next=$(( next + interval )); fi
  sleep 1
done
rc=0; wait "$run4_pid" || rc=$?
echo "soak_rss.sh: run4.sh exited $rc (see $out/run4.out; a station that failed is in its station-<id>.json)"
/usr/bin/python3 - "$csv" "$plot" "$duration" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
by = {}
for r in rows:
    by.setdefault(int(r["station"]), []).append((float(r["t_s"]), int(r["vm_rss_kB"]) / 1024, int(r["vm_hwm_kB"]) / 1024, int(r["vm_lck_kB"]) / 1024))
# every station sampled at least at 1 min and later, or the soak measured nothing
ok = len(by) == 4 and all(len(v) >= 2 and v[0][0] <= 90 for v in by.values())
if not ok:
    print("not every station was sampled at 1 min and later (%d stations sampled): no result" % len(by))
for s in sorted(by):
    v = by[s]
    first = min(v, key=lambda x: abs(x[0] - 60))
    last = v[-1]
    ratio = last[1] / first[1]
    ok &= abs(ratio - 1) <= 0.10
    print("station %d: VmRSS %.1f MiB at %.0f s, %.1f MiB at %.0f s (ratio %.3f); VmHWM at the end %.1f MiB; VmLck %.1f MiB"
          % (s, first[1], first[0], last[1], last[0], ratio, last[2], last[3]))
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    for s in sorted(by):
        ax.plot([x[0] / 60 for x in by[s]], [x[1] for x in by[s]], marker=".", label="station %d VmRSS" % s)
    ax.set_xlabel("time since the stations started (min)")
    ax.set_ylabel("MiB")
    ax.set_ylim(0, 1.25 * max([x[1] for v in by.values() for x in v] + [1]))
    ax.set_title("four-station loopback run, %s s planned" % sys.argv[3])
    if by:
        ax.legend()
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=100)
    print("plot: " + sys.argv[2])
except ImportError:
    print("no matplotlib: no plot")
print("RSS at 1 min and at the end within 10 %%: %s" % ("yes" if ok else "NO"))
sys.exit(0 if ok else 1)
PY
