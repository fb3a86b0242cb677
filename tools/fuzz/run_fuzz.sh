#!/usr/bin/env bash
# Builds the libFuzzer target with clang in its own build dir and fuzzes the wire decoder for
# a bounded time. Usage: run_fuzz.sh [BUILD_DIR] [SECONDS]   (default 30 s)
# Seeds: valid single- and multi-fragment datagrams written by make_seeds (below, via the
# fuzzer binary's own corpus dir), so the run starts past the MAC.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-/tmp/haptic-fuzz}"
secs="${2:-30}"
if ! command -v clang++ >/dev/null; then
  echo "run_fuzz.sh: clang++ not found (apt install clang libclang-rt-14-dev)" >&2; exit 1
fi
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=Debug >/dev/null
cmake --build "$build" >/dev/null
corpus="$build/corpus"
mkdir -p "$corpus"
cp -n "$here"/seeds/* "$corpus"/ 2>/dev/null || true
"$build/fuzz_wire" -max_total_time="$secs" -timeout=5 -rss_limit_mb=1024 -print_final_stats=1 \
  -artifact_prefix="$build/" "$corpus" 2>&1 | tail -15
