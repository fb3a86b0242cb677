#!/usr/bin/env bash
# A short simulated run traced at node 2 (rest x != 0, so a position plotted as a displacement
# would show), then tools/plots/check_figures.py on its folder; then a 10-user run, whose snapshot
# figure shows 8 of the copies and must say which. Exit 77 (skipped) without matplotlib.
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
