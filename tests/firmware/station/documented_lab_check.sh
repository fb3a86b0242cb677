#!/usr/bin/env bash
# The shipped four-station lab (firmware/deploy/lab-4-stations/station-1..4.toml, installed as
# share/haptic/examples/lab-4-stations) run end to end on loopback, edited ONLY as the deploy guide
# (firmware/deploy/README.md, steps 5 and "Measuring b_d") tells a lab, plus the test-only lines
# named below. Station 1 drives a stand-in Touch (the fake OpenHaptics library), station 2 a stand-in
# Falcon (the umockdev usbdevfs stand-in attached by falcon_station_session, which runs this script
# and then checks the Falcon side: firmware, homing, servo packets, last packet zero), stations 3 and
# 4 a simulated user, asked for explicitly.
# The deploy guide's edits:
#   keys: haptic-keygen station-N.key next to each file, the other stations' public keys into peers;
#   addresses: each station's listen/peer address (here 127.0.0.1 with free ports);
#   [device] 1: hd_library_path (a path relative to the station file's folder: vendor/libHD.so),
#               damping_Ns_per_m = the b_d `haptic-devices diag --force-N 0.2 0.4` measured, the three
#               map_* lines `haptic-devices map` printed;
#   [device] 2: kind = "falcon", falcon_firmware_path = "falcon-firmware.bin" (next to the file),
#               damping_Ns_per_m;   [device] 3, 4: kind = "simulated";
#   [rt] for this PC: cpu = -1 (no core reserved here), hold_dma_latency = false.
# Test-only (a short run on a loaded shared VM, not what a lab sets): station.duration_s = 2 with the
# push/release at 0.8/1.2 s, probe_s = 1, max_no_neighbour_fraction = 0.5, loss_allowance_ticks = 1;
# station 2 max_stale_reads = 250 (the stand-in answers through umockdev's
# socket, a few hundred exchanges/s) and falcon_homing_timeout_s = 10; all four get one --start-at.
# Each station runs in its own working directory, as the unit's /var/lib/haptic/station-N.
# Usage: documented_lab_check.sh BUILD_BIN_DIR FAKE_LIBHD DEPLOY_DIR WORK_DIR FALCON_FIRMWARE
set -euo pipefail
bin="$1"; fakehd="$2"; deploy="$3"; work="$4"; firmware="$5"
export PATH="$bin:$PATH"
rm -rf "$work"; mkdir -p "$work/etc/vendor"
etc="$work/etc"
cp "$deploy"/lab-4-stations/station-{1,2,3,4}.toml "$etc/"
cp "$fakehd" "$etc/vendor/libHD.so"
cp "$firmware" "$etc/falcon-firmware.bin"
plant="0.05,5,0.05"
held_mm="12,-5,30"

# b_d and the mapping, with the guide's commands, against the stand-in Touch
out=$(FAKEHD_AUTO=1 FAKEHD_PLANT=$plant haptic-devices diag --kind touch --hd-library "$etc/vendor/libHD.so" --max-stale-reads 500 --force-N 0.2 0.4 --push-s 0.3)
bd=$(printf '%s\n' "$out" | sed -n 's/^b_d = (F2 - F1) \/ (v2 - v1) = \([0-9.e+-]*\) N s\/m.*/\1/p')
[ -n "$bd" ] || { printf '%s\n' "$out"; echo "FAIL: diag printed no b_d"; exit 1; }
map=$(FAKEHD_AUTO=1 FAKEHD_POSITION_MM=$held_mm haptic-devices map --kind touch --hd-library "$etc/vendor/libHD.so" --centre-m 0 0 0 --still-s 0.3 | grep '^map_')
[ "$(printf '%s\n' "$map" | wc -l)" = 3 ] || { echo "FAIL: haptic-devices map printed no map_* lines"; exit 1; }
echo "deploy guide steps on the stand-ins: b_d = $bd N s/m; $(printf '%s' "$map" | tr '\n' ' ')"

ports=$(/usr/bin/python3 -c '
import socket
ss = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(4)]
for s in ss: s.bind(("127.0.0.1", 0))
print(" ".join(str(s.getsockname()[1]) for s in ss))')
read -r p1 p2 p3 p4 <<<"$ports"
declare -A port=([1]=$p1 [2]=$p2 [3]=$p3 [4]=$p4) pub=()
for n in 1 2 3 4; do
  pub[$n]=$( (cd "$etc" && haptic-keygen "station-$n.key") | awk '{print $2}')
done
for n in 1 2 3 4; do
  f="$etc/station-$n.toml"
  for m in 1 2 3 4; do
    sed -i "s/REPLACE-with-station-$m-public-key/${pub[$m]}/; s/192\.168\.10\.1$m:47000/127.0.0.1:${port[$m]}/g" "$f"
  done
  sed -i 's/^cpu = 1 /cpu = -1 /; s/^hold_dma_latency = true/hold_dma_latency = false/' "$f"
  sed -i 's/^duration_s = 0 /duration_s = 2 /; s/^probe_s = 1\.5/probe_s = 1.0/' "$f"
  sed -i 's/^\[station\]$/[station]\npush_end_s = 0.8\nrelease_s = 1.2\nmax_no_neighbour_fraction = 0.5\nloss_allowance_ticks = 1/' "$f"
  case $n in
    1) sed -i "s|^hd_library_path = .*|hd_library_path = \"vendor/libHD.so\"|; s|^# damping_Ns_per_m = \.\.\..*|damping_Ns_per_m = $bd|" "$f"
       printf '%s\n' "$map" > "$work/map.txt"
       sed -i "/^damping_Ns_per_m = /r $work/map.txt" "$f" ;;
    2) sed -i 's|^kind = "touch" |kind = "falcon"|; s|^hd_library_path = .*|falcon_firmware_path = "falcon-firmware.bin"\nfalcon_homing_timeout_s = 10\nmax_stale_reads = 250|; s|^# damping_Ns_per_m = \.\.\..*|damping_Ns_per_m = 5|' "$f" ;;
    *) sed -i 's|^kind = "touch" |kind = "simulated"|' "$f" ;;
  esac
  haptic-station run --config "$f" --check-config > "$work/check-$n.log" 2>&1 || { cat "$work/check-$n.log"; echo "FAIL: --check-config station $n"; exit 1; }
done
grep -q 'SIMULATED user' "$work/check-3.log" || { cat "$work/check-3.log"; echo "FAIL: --check-config of a simulated user does not warn"; exit 1; }

epoch=$(/usr/bin/python3 -c 'import time; print("%.3f" % (time.time() + 2.0))')
pids=()
for n in 1 2 3 4; do
  mkdir -p "$work/var/station-$n"
  (cd "$work/var/station-$n" && FAKEHD_AUTO=1 FAKEHD_PLANT=$plant FAKEHD_FORCE_LOG="$work/forces.csv" \
     timeout -k 5 40 haptic-station run --config "$etc/station-$n.toml" --start-at "$epoch" > "$work/station-$n.log" 2>&1) &
  pids[$n]=$!
done
fail=0
for n in 1 2 3 4; do
  rc=0; wait "${pids[$n]}" || rc=$?
  [ "$rc" = 0 ] || { cat "$work/station-$n.log"; echo "FAIL: station $n exited $rc"; fail=1; }
done
[ "$fail" = 0 ] || exit 1
/usr/bin/python3 - "$work" <<'PY'
import csv, glob, json, math, sys
work = sys.argv[1]
fail = []
st = {}
for n in (1, 2, 3, 4):
    files = glob.glob("%s/var/station-%d/*/station-%d.json" % (work, n, n))
    if len(files) != 1: fail.append("station %d: %d summaries" % (n, len(files))); continue
    st[n] = json.load(open(files[0]))
    if st[n]["exit_code"] != 0: fail.append("station %d exit %s %s" % (n, st[n]["exit_code"], st[n]["conditions"]))
def dev(n): return st[n]["lifecycle"]["device"] if n in st else {}
if dev(1).get("kind") != "touch" or dev(1).get("simulated_user") or not dev(1).get("proxy_from_device"): fail.append("station 1: %s" % dev(1))
if n in st and st[1]["device_fault"] != "none": fail.append("station 1 device fault %s" % st[1]["device_fault"])
if dev(2).get("kind") != "falcon" or dev(2).get("simulated_user") or st.get(2, {}).get("device") != "Novint Falcon via libusb": fail.append("station 2: %s" % dev(2))
for n in (3, 4):
    if not dev(n).get("simulated_user") or not any("SIMULATED user" in w for w in st.get(n, {}).get("warnings", [])):
        fail.append("station %d: simulated user not recorded (%s, warnings %s)" % (n, dev(n), st.get(n, {}).get("warnings")))
# The shipped [network] section (net.tx_direct = true): the tick sends its pushes itself. A push is
# declined (the I/O thread sends it, counted) only when a ticket is being rewritten at that moment or
# a neighbour's keys are not yet agreed: at most 1 % here (no emulated impairment).
for n in sorted(st):
    io = st[n].get("io_thread", {})
    sent, declined = io.get("tx_direct_sent", 0), io.get("tx_direct_declined", 0)
    pushes = sent + declined + io.get("tx_direct_unfinished", 0)
    if not io.get("tx_direct") or pushes == 0 or sent < 0.99 * pushes:
        fail.append("station %d: pushes not sent by the tick (tx_direct %s, sent %s of %s, declined %s)" % (
            n, io.get("tx_direct"), sent, pushes, declined))
rows = list(csv.DictReader(open(work + "/forces.csv")))
F = [math.sqrt(sum(float(r[k]) ** 2 for k in ("fx_N", "fy_N", "fz_N"))) for r in rows]
nz = [f for f in F if f > 0]
Fmax, ramp = dev(1).get("force_limit_N", 0), dev(1).get("ramp_in_s", 0)
bound = Fmax * 0.002 / ramp if ramp else 0
if not nz: fail.append("the stand-in Touch received no force")
elif nz[0] > bound + 1e-9: fail.append("first force %.4f N above F_max T / ramp_in_s = %.4f N" % (nz[0], bound))
if nz and max(F) > Fmax + 1e-6: fail.append("force %.3f N above the device's %.2f N" % (max(F), Fmax))
print("documented lab: 4 stations exit 0, every push sent by the tick (direct TX); station 1 Touch (%d servo frames, first force %.4f N <= %.4f N, max %.3f N), "
      "station 2 Falcon, stations 3 and 4 simulated users (warned, recorded)" % (len(F), nz[0] if nz else 0, bound, max(F) if F else 0))
if fail:
    print("FAILED: " + "; ".join(fail)); sys.exit(1)
PY
