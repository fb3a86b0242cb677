#!/usr/bin/env bash
# The main job: the paper's 4-user experiment (Huang & Lee 2013, Section V) end to end.
#   1. build (Release) only what it runs: haptic-station and haptic-topology (no tests, no benchmarks)
#   2. topology choice from the delay matrix (eq. 27) with haptic-topology: best and worst
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
BUILD=${HAPTIC_BUILD_DIR:-build}  # build directory (default build/)
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD" -j"$(nproc)" --target haptic-station haptic-topology
mkdir -p "$OUT"
DELAYS="0,4,4,4;8,0,80,200;4,100,0,200;6,240,200,0"
# Topology choice (eq. 27) over all connected 3-link graphs of the paper's delay matrix.
BEST="" ; WORST=""
echo "== topology ranking (eq. 27), 3 undirected links =="
"$BUILD"/bin/haptic-topology --paper --paper-scene --loss-allowance 1 --json "$OUT/topology.json" | tee "$OUT/topology.txt"
BEST=$(/usr/bin/python3 -c "import json,sys; r=json.load(open(sys.argv[1]))['ranked']; print(','.join('%d-%d'%tuple(e) for e in r[0]['edges']))" "$OUT/topology.json")
WORST=$(/usr/bin/python3 -c "import json,sys; r=json.load(open(sys.argv[1]))['ranked']; print(','.join('%d-%d'%tuple(e) for e in r[-1]['edges']))" "$OUT/topology.json")
echo "best topology: $BEST   worst topology: $WORST"
for s in paper-best paper-worst paper-unstable; do
  echo "== $s =="
  case "$s" in
    paper-worst) TOPO="$WORST" ;;
    *) TOPO="$BEST" ;;  # paper-unstable: the best topology with Fig. 10's damping
  esac
  "$BUILD"/bin/haptic-station sim --scenario "$s" --topology "$TOPO" --seed "$SEED" --delay-matrix "$DELAYS" \
    --out "$OUT/$s" --trace-every 5
done
# Beyond the paper: the same best topology with no local damping and weak D-coupling, where the
# consensus loop does lose passivity and stability (paper-unstable with Fig. 10's damping did not).
echo "== no-damping (B_i = 0, D_ij = 1 I) =="
"$BUILD"/bin/haptic-station sim --scenario paper-unstable --topology "$BEST" --damping 0,0,0,0 --d-gain 1 \
  --seed "$SEED" --delay-matrix "$DELAYS" --out "$OUT/no-damping" --trace-every 5
# The same with the per-edge energy gate off: what the consensus law does alone (the report says
# whether the run above was held by the gate).
"$BUILD"/bin/haptic-station sim --scenario paper-unstable --topology "$BEST" --damping 0,0,0,0 --d-gain 1 \
  --seed "$SEED" --delay-matrix "$DELAYS" --edge-energy-bound 0 --out "$OUT/no-damping-gate-off" --trace-every 5 --no-plots
# The closed loop where eq. (18) binds (rt/README.md): diverging at 0.8x of it, passive at 1.0x.
for B in 8 10; do
  "$BUILD"/bin/haptic-station sim --scenario eq18-binds --damping "$B,$B" --out "$OUT/eq18-binds-$B" --trace-every 50 --no-plots
done
# B_i with the paper's loss allowance (one lost packet per direction) for the report's side-by-side table.
for s in paper-best paper-worst; do
  TOPO="$BEST"; [ "$s" = paper-worst ] && TOPO="$WORST"
  "$BUILD"/bin/haptic-station sim --scenario "$s" --topology "$TOPO" --seed "$SEED" --delay-matrix "$DELAYS" --loss-allowance 1 \
    --out "$OUT/$s-L1" --trace-every 50 --no-plots
done
/usr/bin/python3 tools/report/make_report.py "$OUT"
echo "report: $OUT/report.md"
