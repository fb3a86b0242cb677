#!/bin/sh
# `haptic-devices diag` and `haptic-devices map` against the fake OpenHaptics library (the Touch
# stand-in, tests/drivers/fake_hd) in its automatic mode: a 1 kHz servo thread and, through
# FAKEHD_PLANT, a stylus that moves as a mass with known viscous damping b and Coulomb friction c
# under the commanded force (a test model with a known answer, not a Touch model).
# Usage: haptic_devices_session_check.sh <haptic-devices> <fake libHD.so>
set -u
tool=$1; fakehd=$2
fail=0
# --max-stale-reads 500: a loaded CI machine may stall the fake's servo thread; the stale check is
# not what these cases test (test_drivers does).
dev="--kind touch --hd-library $fakehd --max-stale-reads 500"
check() {  # check NAME EXPECTED_RC OUTPUT RC REGEX...
  name=$1; want=$2; out=$3; rc=$4; shift 4
  if [ "$rc" -ne "$want" ]; then echo "FAIL $name: exit $rc, expected $want"; fail=1; fi
  for re in "$@"; do
    if ! printf '%s\n' "$out" | grep -qE -- "$re"; then echo "FAIL $name: missing /$re/"; fail=1; fi
  done
  printf '%s\n' "$out" | sed "s/^/  [$name] /"
}

# 1. b_d from two force levels: plant b = 5 N s/m, c = 0.05 N. F/v at one level would say 5.71.
out=$(FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,5,0.05 "$tool" diag $dev --force-N 0.2 0.4 --axis x 2>&1); rc=$?
check bd 0 "$out" $rc 'calibration: OK \(hdCheckCalibration = HD_CALIBRATION_OK\)' 'test force 0.2 N along x: mean \|speed\|' 'servo rate: [0-9]+ Hz \([0-9]+ servo frames' 'b_d = \(F2 - F1\) / \(v2 - v1\) = '
bd=$(printf '%s\n' "$out" | sed -n 's/^b_d = (F2 - F1) \/ (v2 - v1) = \([0-9.e+-]*\) N s\/m.*/\1/p')
if ! awk -v b="$bd" 'BEGIN { exit !(b > 4.75 && b < 5.25) }'; then echo "FAIL bd: b_d '$bd' not within 5% of the plant's 5 N s/m"; fail=1; fi
# the servo rate is the fake's own 1 kHz loop, not the tool's 500 Hz tick
hz=$(printf '%s\n' "$out" | sed -n 's/^servo rate: \([0-9]*\) Hz.*/\1/p')
if ! awk -v h="$hz" 'BEGIN { exit !(h >= 700 && h <= 1100) }'; then echo "FAIL rate: servo rate '$hz' Hz, the fake runs 1000 frames/s"; fail=1; fi

# 2. the deploy guide's form, one level along y; the stylus comes back (+F then -F)
out=$(FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,5,0 "$tool" diag $dev --force-N 0.3 --axis y 2>&1); rc=$?
check one_level 0 "$out" $rc 'force 0.3 N along y' 'force -0.3 N along y' 'test force 0.3 N along y: mean \|speed\| over the second half of each push 6[0-9]\.[0-9]+ mm/s'

# 3. a push that runs away (b = 0.1 N s/m: 10 m/s terminal speed) trips the device's speed check: exit 5, fault named
out=$(FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,0.1,0 "$tool" diag $dev --force-N 1 --max-travel-mm 200 2>&1); rc=$?
check fault 5 "$out" $rc 'device fault: out-of-range sample'

# 3b. calibration status: a Touch whose calibration needs an update is refused (exit 5) saying what to do
out=$(FAKEHD_AUTO=1 FAKEHD_CALIBRATION=0x5001 "$tool" diag $dev --force-N 0.2 2>&1); rc=$?
check calibration 5 "$out" $rc 'device fault: calibration needed' 'calibration: NOT OK \(hdCheckCalibration = 0x5001, HD_CALIBRATION_NEEDS_UPDATE: put the stylus in its inkwell'

# 4. map: held still at (12, -5, 30) mm, object centre (0.1, 0, 0) m, rotation z 90 deg, scale 2:
#    offset = centre - 2 Rz(90) p = (0.1 - 0.010, -0.024, -0.060)
out=$(FAKEHD_AUTO=1 FAKEHD_POSITION_MM=12,-5,30 "$tool" map $dev --centre-m 0.1 0 0 --rotation-deg 0 0 90 --scale 2 --still-s 0.3 2>&1); rc=$?
check map 0 "$out" $rc 'held still at \(12.00, -5.00, 30.00\) mm' '^map_offset_m = \[0.090000, -0.024000, -0.060000\]$' \
  '^map_rotation_deg = \[0, 0, 90\]$' '^map_scale = 2$'

# 5. map with a stylus that never stops: exit 3 after the timeout
out=$(FAKEHD_AUTO=1 FAKEHD_CIRCLE_MM=20 "$tool" map $dev --still-s 0.3 --timeout-s 1 2>&1); rc=$?
check not_still 3 "$out" $rc 'timed out after 1 s: the stylus was never still'

# 6. no device: a missing vendor library is exit 9 with the library error and the key that fixes it
out=$("$tool" diag --kind touch --hd-library /nonexistent/libHD.so 2>&1); rc=$?
check no_device 9 "$out" $rc 'no device: device.kind = "touch"' 'dlopen\("/nonexistent/libHD.so"\) failed' 'device.hd_library_path'

# 7. bad options: exit 2, option named; --help tells the exit statuses
out=$("$tool" diag --force-N 3 2>&1); rc=$?
check bad_force 2 "$out" $rc '--force-N: 3.000000 N is outside \(0, 1\] N'
out=$("$tool" diag --force-N 0.4 0.2 2>&1); rc=$?
check bad_levels 2 "$out" $rc '--force-N: the second level must be larger'
out=$("$tool" map --scale 0 2>&1); rc=$?
check bad_scale 2 "$out" $rc '--scale: outside \(0, 100\]'
out=$("$tool" diag --help 2>&1); rc=$?
check help 0 "$out" $rc 'Exit status: 0 done; 2 bad option' '--force-N' '--axis'
exit $fail
