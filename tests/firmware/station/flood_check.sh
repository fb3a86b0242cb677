#!/usr/bin/env bash
# The four-process flood run, short (tools/flood/flood_run.py, ~20 s): four stations on loopback
# planned once, run clean and then under a bounded flood of every attack class from haptic-flood at
# 4,000 datagrams/s (the tool's default is as fast as the machine sends, 14,000-32,000/s here: at
# load 8 on this 2-vCPU VM that starved the stations' SCHED_OTHER I/O threads of CPU, so the test
# uses a rate a loaded CI machine also absorbs; tools/flood/README.md has the full-rate figures); consensus time,
# hold-force balance, energies, exit codes, energy-bound trips and per-link genuine packets must be
# unchanged within flood_run.py's tolerances. B_i is fixed (station.damping_Ns_per_m = 400, above
# eq. 18 for this machine's bounds in both runs) so that the check is about what gets through, not
# about how the flood's CPU cost moves the measured round trips (that is measured by the tool's
# default run, tools/flood/README.md). Not root: the unprivileged classes run and are checked, then the
# test exits 77 (SKIPPED) because the on-path classes (spoofed source, sniffed live and cross-run
# replay, stolen key) could not run. Likewise when the clean run's stations could not keep their
# period (host starving during the run): the physics rows were not binding, the security rows were.
# When the flood run's stations starved and only rows a starving host moves changed (physics, exit 11),
# the pair runs once more: a second such result is the flood's doing (failed); otherwise the second
# pair is the result.
set -euo pipefail
bin="$1"; out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
[ -x /usr/bin/python3 ] || { echo "SKIPPED: /usr/bin/python3 missing"; exit 77; }
bin_dir="$(cd "$(dirname "$bin")" && pwd)"
[ -x "$bin_dir/haptic-flood" ] || { echo "FAILED: $bin_dir/haptic-flood not built"; exit 1; }
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$bin_dir" "$out"
flood_pair() {
  rm -rf "$1"
  /usr/bin/python3 "$repo/tools/flood/flood_run.py" --out "$1" --bin-dir "$bin_dir" --clean-runs 1 --damping 400 \
    --rate 4000 --max-datagrams 2000000
}
# Whether the flood run's stations starved and every binding row that changed is one a starving host
# moves (physics rows, a station's exit 11: missed cycles over the limit); prints the starving
# stations. The flood's CPU cost on this shared host, or the other tests' load (or the VM's stalls)?
flood_alone_starved() {
  /usr/bin/python3 - "$1" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
flood = r["runs"]["flood"]["starving_stations"]
bad = [c for c in r["comparisons"]["flood"] if c["binding"] and not c["ok"]]
host_moved = lambda c: c["what"] in r["tolerances"] or (c["what"].endswith(" exit_code") and c["run"] == 11)
if flood and bad and all(host_moved(c) for c in bad):
    print(", ".join(map(str, flood)))
    sys.exit(0)
sys.exit(1)
PY
}
rc=0
flood_pair "$out" || rc=$?
if [ "$rc" -eq 1 ] && who="$(flood_alone_starved "$out/flood-report.json")"; then
  # A flood that starves its host reproduces; the other tests' load on a 2-core CI host rarely
  # lands on the same run twice. The first attempt stays in $out for the record.
  echo "flood_check: only rows a starving host moves changed, and the flood run's station(s) $who starved: the pair once more"
  rc=0
  flood_pair "$out-again" || rc=$?
  if [ "$rc" -eq 1 ] && flood_alone_starved "$out-again/flood-report.json" >/dev/null; then
    echo "FAILED: the flood run starved its stations in both attempts and moved what a starving host moves: the flood's doing"; exit 1
  fi
  [ "$rc" -eq 0 ] || exit "$rc"
  out="$out-again"
elif [ "$rc" -ne 0 ]; then
  exit "$rc"
fi
if [ "$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["physics_binding"])' "$out/flood-report.json")" != True ]; then
  echo "SKIPPED (in part): the clean run's host was starving: consensus, hold force and deformation were not compared; exit codes, energy trips and genuine packets were, and passed"
  exit 77
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIPPED (in part): not root: the spoofed, sniffed-replay, cross-run-replay and stolen-key classes did not run; the unprivileged classes passed"
  exit 77
fi
