#!/usr/bin/env bash
# A short simulated run traced at node 2 (rest x != 0, so a position plotted as a displacement
# would show), then tools/plots/check_figures.py on its folder; then a 10-user run, whose snapshot
# figure shows 8 of the copies and must say which; then `sim` drawing its own figures (the script
# started before the run). Exit 77 (skipped) without matplotlib.
set -euo pipefail
bin="$1"; out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
/usr/bin/python3 -c 'import matplotlib, numpy' 2>/dev/null || { echo "SKIPPED: python3-matplotlib / python3-numpy missing"; exit 77; }
rm -rf "$out"; mkdir -p "$out"
"$bin" sim --scenario paper-best --out "$out/sim" --duration 3 --push-end 1 --release 2 --trace-node 2 --trace-every 5 --no-plots --quiet
/usr/bin/python3 "$repo/tools/plots/check_figures.py" "$out/sim"
"$bin" sim --scenario paper-best --users 10 --out "$out/sim10" --duration 1.5 --push-end 0.8 --release 1.2 --no-plots --quiet
/usr/bin/python3 "$repo/tools/plots/check_figures.py" "$out/sim10"
# `sim` itself draws them: the figure script started before the run, told "go" once the files are written.
"$bin" sim --scenario paper-best --out "$out/drawn" --duration 1.5 --push-end 0.8 --release 1.2 --quiet > "$out/drawn.log"
grep -q "wrote $out/drawn/\*.png" "$out/drawn.log" || { echo "FAILED: sim did not say it wrote the figures:"; cat "$out/drawn.log"; exit 1; }
for f in fig_node_position fig_device_force fig_energy fig_consensus fig_snapshots; do
  [ "$out/drawn/$f.png" -nt "$out/drawn/summary.json" ] || { echo "FAILED: sim did not draw $f.png after writing summary.json"; exit 1; }
done
echo "sim drew its five figures"
