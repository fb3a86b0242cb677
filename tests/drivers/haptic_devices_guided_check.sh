#!/bin/sh
# `haptic-devices check` (the guided pass/fail device check) against the fake OpenHaptics library
# (the Touch stand-in, tests/drivers/fake_hd) in its automatic mode, with its scripted user
# (FAKEHD_USER=1: sweeps the stylus through the usable workspace, presses each button, lets go at the
# first force) and its test plant (FAKEHD_PLANT, known b). Then the same stand-in made to fail, one
# way at a time, as a real device can: a force in the wrong direction, a dead motor, nobody moving
# the stylus, a dead button, an HD library of another major version, calibration needed, no library.
# Usage: haptic_devices_guided_check.sh <haptic-devices> <fake libHD.so>
set -u
tool=$1; fakehd=$2
fail=0
# --max-stale-reads 500: a loaded CI machine may stall the fake's servo thread; the stale check is
# not what these cases test (test_drivers does). --timeout-s 20: the scripted user needs about 2 s
# per guided item; the margin is for load, it never makes a case pass that should fail.
dev="--kind touch --hd-library $fakehd --max-stale-reads 500 --yes"
user="FAKEHD_AUTO=1 FAKEHD_USER=1 FAKEHD_PLANT=0.05,5,0.05"
check() {  # check NAME EXPECTED_RC OUTPUT RC REGEX...   (lines of live positions are not echoed)
  name=$1; want=$2; out=$3; rc=$4; shift 4
  if [ "$rc" -ne "$want" ]; then echo "FAIL $name: exit $rc, expected $want"; fail=1; fi
  for re in "$@"; do
    if ! printf '%s\n' "$out" | grep -qE -- "$re"; then echo "FAIL $name: missing /$re/"; fail=1; fi
  done
  printf '%s\n' "$out" | grep -v '^  t ' | sed "s/^/  [$name] /"
}
run() { env $1 "$tool" check $dev $2 2>&1; }

# 1. everything works: every item PASSes with its figure; b_d is the plant's 5 N s/m (Coulomb cancels)
out=$(run "$user" "--timeout-s 20"); rc=$?
check all_pass 0 "$out" $rc \
  '^PASS open: model "fake_hd stand-in \(tests/drivers/fake_hd, not a device\)".*HD library "3\.00 \(fake_hd test stand-in\)".*the driver binds the OpenHaptics 3\.x HD C API.*calibration OK' \
  '^PASS servo_rate: [0-9]+ Hz \([0-9]+ servo frames of the device.s own loop' \
  '^PASS encoders: largest move from the start x [0-9.]+ mm, y [0-9.]+ mm, z [0-9.]+ mm' \
  '^PASS workspace: extent reached x [0-9]+ of 160 mm \([0-9]+%\), y [0-9]+ of 120 mm \([0-9]+%\), z [0-9]+ of 70 mm' \
  '^PASS buttons: button 1 pressed and released, button 2 pressed and released$' \
  '^PASS force: \+0\.2 N along x: travel \+[0-9.]+ mm, mean velocity \+[0-9.]+ mm/s; -0\.2 N: travel -[0-9.]+ mm.*force sent unreduced: yes' \
  '^PASS b_d: b_d = ' '^summary: 7 PASS, 0 FAIL, 0 SKIP; exit 0$'
bd=$(printf '%s\n' "$out" | sed -n 's/^PASS b_d: .* = \([0-9.e+-]*\) N s\/m (device.damping_Ns_per_m.*/\1/p')
if ! awk -v b="$bd" 'BEGIN { exit !(b > 4.75 && b < 5.25) }'; then echo "FAIL all_pass: b_d '$bd' not within 5% of the plant's 5 N s/m"; fail=1; fi

# 2. the device pushes the wrong way along x (force gain -1): force FAILs saying so, exit 1
out=$(run "$user FAKEHD_FORCE_GAIN=-1,1,1" "--timeout-s 20 --skip b_d"); rc=$?
check wrong_direction 1 "$out" $rc '^FAIL force: \+F moved the stylus AGAINST the force \(wrong direction\); -F moved the stylus AGAINST the force' \
  '^PASS encoders' '^PASS buttons' '^SKIP b_d: not run \(--skip b_d\)' '^summary: 5 PASS, 1 FAIL \(force\), 1 SKIP; exit 1$'

# 2b. the same along y, checked along y (the axis option reaches the push)
out=$(run "$user FAKEHD_FORCE_GAIN=1,-1,1" "--timeout-s 20 --axis y --force-N 0.3 --skip encoders,workspace,buttons"); rc=$?
check wrong_direction_y 1 "$out" $rc '^FAIL force: \+F moved the stylus AGAINST the force.*\+0\.3 N along y' '^SKIP b_d: one --force-N level given'

# 3. a dead motor along x (gain 0): the stylus (at rest, nobody holding it) does not move, force FAILs
out=$(run "FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,5,0.05 FAKEHD_FORCE_GAIN=0,1,1" "--skip encoders,workspace,buttons,b_d"); rc=$?
check dead_motor 1 "$out" $rc '^FAIL force: \+F moved the stylus less than 2 mm its way \(held, blocked, no force\?\); -F moved the stylus less than 2 mm'

# 4. nobody moves the stylus or presses a button (no scripted user): encoders, workspace and buttons FAIL after the timeout
out=$(run "FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,5,0.05" "--timeout-s 1 --force-N 0.3"); rc=$?
check no_motion 1 "$out" $rc '^FAIL encoders: largest move from the start x 0\.0 mm, y 0\.0 mm, z 0\.0 mm in 1 s' \
  '^FAIL workspace: extent reached x 0 of 160 mm \(0%\)' '^FAIL buttons: button 1 never pressed, button 2 never pressed$' \
  '^PASS force' '^summary: 3 PASS, 3 FAIL \(encoders, workspace, buttons\), 1 SKIP; exit 1$'

# 5. a broken switch: button 2 never reads pressed
out=$(run "$user FAKEHD_DEAD_BUTTONS=2" "--timeout-s 3 --skip force,b_d"); rc=$?
check dead_button 1 "$out" $rc '^FAIL buttons: button 1 pressed and released, button 2 never pressed$' '^PASS workspace'

# 6. an HD library of another major version than the ABI the driver binds: open FAILs naming both
out=$(run "$user FAKEHD_HD_VERSION=4.1" "--timeout-s 20 --skip encoders,workspace,buttons,force,b_d"); rc=$?
check hd_version 1 "$out" $rc '^FAIL open: HD library version "4\.1" is not OpenHaptics 3\.x: the driver binds the OpenHaptics 3\.x HD C API'

# 6b. a servo loop slower than asked for: servo_rate FAILs with the measured rate (the fake runs 1 kHz)
out=$(run "$user" "--min-servo-hz 5000 --skip encoders,workspace,buttons,force,b_d"); rc=$?
check servo_rate 1 "$out" $rc '^FAIL servo_rate: [0-9]+ Hz \([0-9]+ servo frames of the device.s own loop in [0-9.]+ s\); threshold 5000 Hz'

# 7. not verified is not passed: skipped items give exit 4, never 0
out=$(run "$user" "--timeout-s 20 --skip encoders,workspace,buttons --force-N 0.3"); rc=$?
check skipped 4 "$out" $rc '^SKIP encoders: not run \(--skip encoders\)' '^SKIP b_d: one --force-N level given' '^summary: 3 PASS, 0 FAIL, 4 SKIP; exit 4$'

# 8. calibration needed: the device enters its safe state, open FAILs naming it, the rest is not run: exit 5
out=$(run "$user FAKEHD_CALIBRATION=0x5001" ""); rc=$?
check calibration 5 "$out" $rc '^FAIL open: the device entered its safe state: calibration needed' \
  'HD_CALIBRATION_NEEDS_UPDATE: put the stylus in its inkwell' '6 not run \(the device entered its safe state\); exit 5$'

# 9. no device: exit 9 with the library error and the key that fixes it
out=$("$tool" check --kind touch --hd-library /nonexistent/libHD.so --yes 2>&1); rc=$?
check no_device 9 "$out" $rc 'dlopen\("/nonexistent/libHD.so"\) failed' 'device.hd_library_path' '^FAIL open: no device could be opened'

# 10. bad options (named, exit 2) and --help (the exit statuses)
out=$("$tool" check --skip motors 2>&1); rc=$?
check bad_skip 2 "$out" $rc '--skip: unknown item "motors"'
out=$("$tool" check --force-N 2 2>&1); rc=$?
check bad_force 2 "$out" $rc '--force-N: 2.000000 N is outside \(0, 1\] N'
out=$("$tool" check --help 2>&1); rc=$?
check help 0 "$out" $rc 'Exit status: 0 every item PASSed; 1 an item FAILed' '4 no item failed but some were SKIPped' '9 no device' '--yes' '--skip'
exit $fail
