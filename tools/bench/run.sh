#!/usr/bin/env bash
# Runs the Google Benchmark programs and keeps their JSON in tools/bench/results/.
# Usage: tools/bench/run.sh [build-dir]   (default build). Run on a quiet machine.
set -euo pipefail
cd "$(dirname "$0")/../.."
B=${1:-build}
OUT=tools/bench/results
mkdir -p "$OUT"
if [ -x "$B/bin/bench-rt-tick" ]; then
  "$B/bin/bench-rt-tick" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
    --benchmark_out="$OUT/rt_tick.json" --benchmark_out_format=json
fi
for b in bench_platform bench_net bench_drivers_latency; do
  if [ -x "$B/bin/$b" ]; then
    # bench_drivers_latency's FalconUmockdev row needs the umockdev preload (else it is a visible skip)
    pre=""; name=$b
    if [ "$b" = bench_drivers_latency ] && /sbin/ldconfig -p 2>/dev/null | grep -q libumockdev-preload.so.0; then pre="libumockdev-preload.so.0"; fi
    [ "$b" = bench_drivers_latency ] && name=drivers_latency  # the file drivers/README.md cites
    LD_PRELOAD="$pre" "$B/bin/$b" --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
      --benchmark_out="$OUT/$name.json" --benchmark_out_format=json
  fi
done
/usr/bin/python3 tools/bench/summarize.py "$OUT"
