#!/bin/sh
# Runs build/bin/haptic-devices under umockdev-run with the hand-written stand-ins and checks
# what it reports. Usage: haptic_devices_check.sh <haptic-devices> <umockdev dir> <fake libHD.so> root|nobody
set -u
tool=$1; dir=$2; fakehd=$3; who=$4
if ! command -v umockdev-run >/dev/null 2>&1; then
  echo "umockdev-run is not installed: haptic-devices was NOT checked against stand-ins (SKIPPED)"; exit 77
fi
if [ "$who" = nobody ]; then
  if [ "$(id -u)" -ne 0 ] || ! command -v setpriv >/dev/null 2>&1; then
    echo "needs root and setpriv to drop to an unprivileged user: permission path NOT checked (SKIPPED)"; exit 77
  fi
  out=$(umockdev-run -d "$dir/touch_usb.umockdev" -d "$dir/hid_devices.umockdev" -- sh -c \
    'chmod -R a+rX "$UMOCKDEV_DIR" && exec setpriv --reuid=65534 --regid=65534 --clear-groups "$0"' "$tool" 2>&1)
else
  out=$(umockdev-run -d "$dir/touch_usb.umockdev" -d "$dir/hid_devices.umockdev" -d "$dir/touch_acm.umockdev" -- "$tool" --hd-library "$fakehd" 2>&1)
fi
echo "$out"
fail=0
need() { if ! printf '%s\n' "$out" | grep -qE -- "$1"; then echo "MISSING: $1"; fail=1; fi; }
if [ "$who" = nobody ]; then
  need 'access: /dev/hidraw0 NO read/write permission'
  need 'SUBSYSTEM=="hidraw", ATTRS\{idVendor\}=="256f", ATTRS\{idProduct\}=="c635", GROUP="haptic", MODE="0660"'
  need 'OpenHaptics HD library \(libHD.so\): NOT available'
  need 'fix: device.hd_library_path = '
else
  need '2988:0302 .*bus 001 addr 005 port 1-3  serial "TOUCH-0001"'
  need 'backend: OpenHaptics HD library'
  need 'OpenHaptics HD library .*: loadable'
  need '256f:c635  3Dconnexion SpaceMouse Compact  /dev/hidraw0'
  need 'position input only, NO force feedback'
  need 'Touch HID model detected'
  need 'access: /dev/hidraw0 read/write OK'
  need '2988:0304  3D Systems Touch, HID model'
  need '2988:0302  3D Systems Touch, USB model .*/dev/ttyACM0  serial "TOUCH-ACM-3"'
  need 'Touch vendor configuration'
  if printf '%s\n' "$out" | grep -q '046d:c31c'; then echo "UNEXPECTED: unrelated keyboard listed"; fail=1; fi
  # `check` with device.kind auto: the Touch found on (stand-in) USB, servo through the fake library with its
  # scripted user and test plant (tests/drivers/haptic_devices_guided_check.sh has the failing cases)
  out=$(umockdev-run -d "$dir/touch_usb.umockdev" -- env FAKEHD_AUTO=1 FAKEHD_USER=1 FAKEHD_PLANT=0.05,5,0.05 \
    "$tool" check --hd-library "$fakehd" --yes --max-stale-reads 500 --timeout-s 20 2>&1); rc=$?
  printf '%s\n' "$out" | grep -v '^  t '
  if [ "$rc" -ne 0 ]; then echo "check: exit $rc, expected 0"; fail=1; fi
  need 'usb: found 2988:0302 .*serial "TOUCH-0001"'
  need 'touch: unplug detection on 2988:0302'
  need '^summary: 7 PASS, 0 FAIL, 0 SKIP; exit 0$'
fi
exit $fail
