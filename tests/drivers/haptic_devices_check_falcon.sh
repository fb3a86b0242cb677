#!/bin/sh
# `haptic-devices check --kind falcon` through our libusb Falcon driver against the Falcon stand-in
# (falcon_standin.hpp, attached by `falcon_station_session --run`, which also checks the Falcon side:
# firmware byte for byte, homing, motor commands sent, last packet zero). The stand-in plays the
# documented protocol but is not a mechanism: its encoders never follow the motors and nobody moves
# it or presses its buttons. So: open and servo_rate PASS; encoders, workspace, buttons and b_d are
# SKIPped (--skip: the stand-in cannot exercise them); force runs (the motors are commanded) and must
# FAIL, because the stylus did not move: the check never passes what it did not see.
# Usage (under falcon_station_session --run): haptic_devices_check_falcon.sh <haptic-devices>
set -u
tool=$1
# --min-servo-hz 50: the stand-in answers through umockdev's socket, a few hundred exchanges per second
# (drivers/README.md); --max-stale-reads 250 for the same reason.
out=$("$tool" check --kind falcon --falcon-firmware "$FALCON_FIRMWARE" --max-stale-reads 250 --yes --min-servo-hz 50 \
  --skip encoders,workspace,buttons,b_d --force-N 0.3 --push-s 0.3 2>&1); rc=$?
printf '%s\n' "$out" | grep -v '^  t ' | sed 's/^/  [check falcon] /'
fail=0
if [ "$rc" -ne 1 ]; then echo "FAIL: exit $rc, expected 1 (force FAILs on a stand-in that does not move)"; fail=1; fi
for re in '^PASS open: Novint Falcon via libusb: firmware loaded \(every byte echoed\) and homed' \
          '^PASS servo_rate: [0-9]+ Hz \([0-9]+ servo frames of the device.s own loop' \
          '^SKIP encoders: not run \(--skip encoders\)' \
          '^FAIL force: \+F moved the stylus less than 2 mm its way' \
          '^summary: 2 PASS, 1 FAIL \(force\), 4 SKIP; exit 1$'; do
  if ! printf '%s\n' "$out" | grep -qE -- "$re"; then echo "FAIL: missing /$re/"; fail=1; fi
done
exit $fail
