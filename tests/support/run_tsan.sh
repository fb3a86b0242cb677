#!/usr/bin/env bash
# Builds a stand-alone ThreadSanitizer project (tests/net/tsan, tests/platform/tsan) in its own
# build dir and runs its program (bounded: each program uses fixed item counts).
# Usage: run_tsan.sh SOURCE_DIR BUILD_DIR PROGRAM
set -euo pipefail
src="$1"
build="$2"
program="$3"
mkdir -p "$build"
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Debug >"$build/configure.log" 2>&1 || { cat "$build/configure.log"; exit 1; }
cmake --build "$build" >"$build/build.log" 2>&1 || { cat "$build/build.log"; exit 1; }
# halt_on_error: any data race report fails the test.
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" "$build/$program"
