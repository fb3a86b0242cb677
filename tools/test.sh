#!/usr/bin/env bash
# The README's test command: configure, build everything, run every test (CTest), then the mutation
# suite (tools/mutation: it builds its own lean copy, so it runs alone, after the others).
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if command -v ccache >/dev/null; then
  # base_dir: compile lines relative to the tree, so the mutation suite's copy (build/mutation/src,
  # built in its own build/) hits the objects of this build
  export CCACHE_BASEDIR="$PWD"
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DHAPTIC_MUTATION_SUITE=ON "${launcher[@]}"
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)" -LE mutation
ctest --test-dir build -V -L mutation  # -V: the mutant -> killing tests table in the log
