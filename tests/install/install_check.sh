#!/usr/bin/env bash
# Installed binaries find their scripts in the install tree, not in the source tree:
#   1. cmake --install BUILD --prefix <tmp> --component Unspecified (binaries + scripts; the deploy
#      component writes to /etc and is checked in step 4 under DESTDIR instead);
#   2. the installed haptic-station carries no path into the source tree's tools/;
#   3. run from an unrelated working directory with HAPTIC_TOOLS_DIR unset, a short `sim` draws
#      its PNG figures with <tmp>/share/haptic/tools/plots/plot_run.py (skipped, exit 77, when
#      /usr/bin/python3 cannot import matplotlib);
#   4. DESTDIR=<tmp2> cmake --install --prefix /opt/haptic-check --component deploy: the systemd
#      unit starts /opt/haptic-check/bin/haptic-station (the prefix given at install time).
# Usage: install_check.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build="$1"
src="$2"
work="$3"
rm -rf "$work"
mkdir -p "$work/elsewhere"
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" --component Unspecified >"$work/install.log"
bin="$prefix/bin/haptic-station"
script="$prefix/share/haptic/tools/plots/plot_run.py"
[ -x "$bin" ] || { echo "FAIL: $bin not installed"; exit 1; }
[ -f "$script" ] || { echo "FAIL: $script not installed"; exit 1; }
if grep -aq "$src/tools" "$bin"; then
  echo "FAIL: the installed binary names the source tree ($src/tools)"
  exit 1
fi
echo "ok: installed $bin and $script; the binary names no source path"

# Deploy unit (step 4) first: it does not need matplotlib.
dest="$work/destdir"
DESTDIR="$dest" cmake --install "$build" --prefix /opt/haptic-check --component deploy >"$work/install-deploy.log"
unit=$(find "$dest" -name 'haptic-station@.service' | head -1)
[ -n "$unit" ] || { echo "FAIL: no haptic-station@.service under DESTDIR"; exit 1; }
grep -q '^ExecStart=/opt/haptic-check/bin/haptic-station ' "$unit" ||
  { echo "FAIL: $unit does not start the binary of the install prefix:"; grep ExecStart "$unit"; exit 1; }
echo "ok: systemd unit starts /opt/haptic-check/bin/haptic-station"

if ! /usr/bin/python3 -c 'import matplotlib, numpy' 2>/dev/null; then
  echo "SKIPPED: /usr/bin/python3 cannot import matplotlib/numpy (apt-get install python3-matplotlib): figures not checked"
  exit 77
fi
out="$work/elsewhere/run"
(cd "$work/elsewhere" && env -u HAPTIC_TOOLS_DIR "$bin" sim --scenario paper-best --duration 4 --push-end 1 --release 2 \
   --trace-every 10 --quiet --out "$out") >"$work/sim.log" 2>&1 || { cat "$work/sim.log"; echo "FAIL: sim failed"; exit 1; }
if grep -q "no figures\|figure script failed" "$work/sim.log"; then
  cat "$work/sim.log"
  echo "FAIL: the installed binary drew no figures"
  exit 1
fi
pngs=$(find "$out" -name '*.png' | wc -l)
[ "$pngs" -gt 0 ] || { cat "$work/sim.log"; echo "FAIL: no PNG in $out"; exit 1; }
echo "ok: the installed haptic-station, run from $work/elsewhere, drew $pngs figures with the installed plot script"
