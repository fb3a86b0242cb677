#!/usr/bin/env bash
# The main job: the paper's 4-user experiment (Huang & Lee 2013, Section V) end to end.
#   1. build (Release)
#   2. topology choice from the delay matrix (eq. 27) with haptic-topology, when built
#   3. damping from eq. (18) and the paper-best, paper-worst and paper-unstable runs
#   4. a report (Markdown + PNG) with our numbers next to the paper's
# Output: build/paper-report/ (report.md, figures, one folder per run).
# Usage: tools/main-job.sh [--seed S] [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
SEED=1
OUT=build/paper-report
while [ $# -gt 0 ]; do
  case "$1" in
    --seed) SEED="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) echo "main-job.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"
mkdir -p "$OUT"
DELAYS="0,4,4,4;8,0,80,200;4,100,0,200;6,240,200,0"
if [ -x build/bin/haptic-topology ]; then
  echo "== topology ranking (eq. 27), 3 undirected links =="
  if build/bin/haptic-topology --help 2>/dev/null | grep -q -- "--json"; then
    build/bin/haptic-topology --links 3 --json "$OUT/topology.json" | tee "$OUT/topology.txt" || echo "haptic-topology failed; continuing with the paper's Fig. 7 topologies" >&2
  else
    build/bin/haptic-topology --links 3 | tee "$OUT/topology.txt" || true
  fi
else
  echo "haptic-topology not built: using the paper's Fig. 7 topologies" | tee "$OUT/topology.txt"
fi
for s in paper-best paper-worst paper-unstable; do
  echo "== $s =="
  build/bin/haptic-station sim --scenario "$s" --seed "$SEED" --delay-matrix "$DELAYS" --out "$OUT/$s" --trace-every 5
done
/usr/bin/python3 tools/report/make_report.py "$OUT"
echo "report: $OUT/report.md"
