#!/usr/bin/env bash
# The installed systemd unit verifies: install into a temporary prefix, then
# `systemd-analyze verify` an instance of haptic-station@.service (its ExecStart binary must exist
# in that prefix). Exit 77 (CTest SKIP) when systemd-analyze is not installed.
# Usage: unit_check.sh BUILD_DIR
set -euo pipefail
build="$1"
command -v systemd-analyze >/dev/null || { echo "SKIPPED: systemd-analyze not installed (apt-get install systemd)"; exit 77; }
work="$(mktemp -d /tmp/haptic-unit-check.XXXXXX)"
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
units="$work/units"
mkdir -p "$units"
cp "$work/prefix/lib/systemd/system/haptic-station@.service" "$units/"
out=$(cd "$units" && SYSTEMD_LOG_LEVEL=notice systemd-analyze verify --man=no "$units/haptic-station@1.service" 2>&1) || {
  echo "$out"; echo "FAIL: systemd-analyze verify haptic-station@1.service"; exit 1; }
if echo "$out" | grep -i "haptic-station@" | grep -iv "no such user\|Failed to resolve user\|group"; then
  echo "FAIL: systemd-analyze reports problems with the unit"; exit 1
fi
echo "$out"
echo "ok: systemd-analyze verify haptic-station@1.service (ExecStart $work/prefix/bin/haptic-station)"
