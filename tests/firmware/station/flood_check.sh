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
set -euo pipefail
bin="$1"; out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
[ -x /usr/bin/python3 ] || { echo "SKIPPED: /usr/bin/python3 missing"; exit 77; }
bin_dir="$(cd "$(dirname "$bin")" && pwd)"
[ -x "$bin_dir/haptic-flood" ] || { echo "FAILED: $bin_dir/haptic-flood not built"; exit 1; }
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$bin_dir" "$out"
rm -rf "$out"
/usr/bin/python3 "$repo/tools/flood/flood_run.py" --out "$out" --bin-dir "$bin_dir" --clean-runs 1 --damping 400 \
  --rate 4000 --max-datagrams 2000000
if [ "$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["physics_binding"])' "$out/flood-report.json")" != True ]; then
  echo "SKIPPED (in part): the clean run's host was starving: consensus, hold force and deformation were not compared; exit codes, energy trips and genuine packets were, and passed"
  exit 77
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIPPED (in part): not root: the spoofed, sniffed-replay, cross-run-replay and stolen-key classes did not run; the unprivileged classes passed"
  exit 77
fi
