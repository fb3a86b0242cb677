#!/usr/bin/env bash
# Builds tests/platform/tsan with -fsanitize=thread in its own build dir and runs it (bounded:
# fixed item counts, a few seconds). Usage: run_tsan.sh BUILD_DIR
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-/tmp/haptic-platform-tsan}"
mkdir -p "$build"
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Debug >"$build/configure.log" 2>&1 || { cat "$build/configure.log"; exit 1; }
cmake --build "$build" >"$build/build.log" 2>&1 || { cat "$build/build.log"; exit 1; }
# halt_on_error: any data race report fails the test.
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" "$build/handoff_stress_tsan"
