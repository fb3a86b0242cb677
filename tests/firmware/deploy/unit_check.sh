#!/usr/bin/env bash
# The installed systemd unit, from a temporary prefix (cmake --install BUILD_DIR --prefix <tmp>):
#   verify:  `systemd-analyze verify` an instance of haptic-station@.service (its ExecStart binary
#            must exist in that prefix); exit 77 (CTest SKIP) when systemd-analyze is not installed.
#   restart: the unit never restarts after a safety stop (unit_restart_check.py: the firmware's
#            kSafetyStopExitCodes and the crash signals against Restart=/RestartPreventExitStatus=).
# Usage: unit_check.sh BUILD_DIR verify | unit_check.sh BUILD_DIR restart SOURCE_DIR
set -euo pipefail
build="$1"
mode="${2:-verify}"
here="$(cd "$(dirname "$0")" && pwd)"
if [ "$mode" = verify ]; then
  command -v systemd-analyze >/dev/null || { echo "SKIPPED: systemd-analyze not installed (apt-get install systemd)"; exit 77; }
fi
work="$(mktemp -d /tmp/haptic-unit-check.XXXXXX)"
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
unit="$work/prefix/lib/systemd/system/haptic-station@.service"
[ -f "$unit" ] || { echo "FAIL: no $unit"; exit 1; }
case "$mode" in
  restart)
    exec python3 "$here/unit_restart_check.py" "$unit" "$3/firmware" ;;
  verify) ;;
  *) echo "unit_check.sh: unknown mode '$mode' (verify or restart)"; exit 2 ;;
esac
units="$work/units"
mkdir -p "$units"
cp "$unit" "$units/"
out=$(cd "$units" && SYSTEMD_LOG_LEVEL=notice systemd-analyze verify --man=no "$units/haptic-station@1.service" 2>&1) || {
  echo "$out"; echo "FAIL: systemd-analyze verify haptic-station@1.service"; exit 1; }
if echo "$out" | grep -i "haptic-station@" | grep -iv "no such user\|Failed to resolve user\|group"; then
  echo "FAIL: systemd-analyze reports problems with the unit"; exit 1
fi
echo "$out"
echo "ok: systemd-analyze verify haptic-station@1.service (ExecStart $work/prefix/bin/haptic-station)"
