#!/usr/bin/env bash
# `haptic-station solo` with a stand-in Touch (the fake OpenHaptics library, tests/drivers/fake_hd,
# automatic 1 kHz servo thread, a free stylus of known damping):
#   touch        solo drives the Touch through the vendor library for 2 s: exit 0, station-1.json names the
#                device, no safe state, and the end-of-run explanation has no "links" line (solo has none)
#   calibration  the library reports a calibration needed (FAKEHD_CALIBRATION=0x5001): the device gives
#                no sample, a safety stop: exit 5, safe_state_latched, the cause line names the calibration
# (one process at a time; no network; ~5 s). Usage: solo_touch_check.sh HAPTIC_STATION FAKE_LIBHD WORK_DIR
set -uo pipefail
bin="$1"; fakehd="$2"; out="$3"
rm -rf "$out"; mkdir -p "$out"
fail=0
cat > "$out/touch.toml" <<EOT
[station]
id = 1
[device]
kind = "touch"
hd_library_path = "$fakehd"
damping_Ns_per_m = 5.0
max_stale_reads = 500   # a loaded test host may starve the stand-in's servo thread; a real Touch keeps 5
EOT
summary() {  # summary DIR PYTHON-EXPR-ON-j: exit 0 when it holds
  /usr/bin/python3 -c 'import json, sys; j = json.load(open(sys.argv[1] + "/station-1.json")); sys.exit(0 if eval(sys.argv[2]) else 1)' "$1" "$2"
}
FAKEHD_AUTO=1 FAKEHD_PLANT=0.05,5,0.05 "$bin" solo --config "$out/touch.toml" --duration 2 --out "$out/touch" > "$out/touch.log" 2>&1; rc=$?
if [ "$rc" -ne 0 ]; then echo "FAILED touch: exit $rc, expected 0"; cat "$out/touch.log"; fail=1
elif ! summary "$out/touch" 'j["exit_code"] == 0 and "Touch" in str(j["device"]) and "safe_state_latched" not in j["conditions"] and j["ticks_run"] > 500'; then
  echo "FAILED touch: station-1.json does not show a clean run on the Touch"; cat "$out/touch/station-1.json"; fail=1
elif grep -q "links over the run" "$out/touch.log"; then echo "FAILED touch: solo explained links it does not have"; cat "$out/touch.log"; fail=1
else echo "ok touch: exit 0 on the stand-in Touch ($(grep -o 'done, [0-9]* ticks' "$out/touch.log"))"; fi

FAKEHD_AUTO=1 FAKEHD_CALIBRATION=0x5001 "$bin" solo --config "$out/touch.toml" --duration 2 --out "$out/calibration" > "$out/calibration.log" 2>&1; rc=$?
if [ "$rc" -ne 5 ]; then echo "FAILED calibration: exit $rc, expected 5 (device fault: the safe state)"; cat "$out/calibration.log"; fail=1
elif ! summary "$out/calibration" 'j["exit_code"] == 5 and "safe_state_latched" in j["conditions"]'; then
  echo "FAILED calibration: station-1.json does not say the safe state latched"; cat "$out/calibration/station-1.json"; fail=1
elif ! grep -q "device fault: calibration" "$out/calibration.log"; then echo "FAILED calibration: the cause line does not name the calibration"; cat "$out/calibration.log"; fail=1
elif grep -q "links over the run" "$out/calibration.log"; then echo "FAILED calibration: solo explained links it does not have"; cat "$out/calibration.log"; fail=1
else echo "ok calibration: exit 5, safe state latched: $(grep -o 'the device gave no sample.*' "$out/calibration.log")"; fi
exit $fail
