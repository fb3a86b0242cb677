#!/usr/bin/env bash
# End-to-end session with a stand-in Touch: the documented configuration path, then a
# two-station loopback lab (haptic-lab) whose station 1 drives the fake OpenHaptics library
# (tests/drivers/fake_hd, automatic 1 kHz servo thread, FAKEHD_PLANT: a free stylus of known
# damping; FAKEHD_FORCE_LOG: every servo frame's force) and station 2 a simulated user.
#   1. `haptic-devices diag --force-N 0.2 0.4` measures b_d on the stand-in (the deploy guide's step);
#      that figure goes into the station file as device.damping_Ns_per_m;
#   2. run with the default ramp-in (1 s): both stations exit 0, consensus after the release,
#      station 1 ran the Touch (not a simulated user, no device fault, proxy from the device), the
#      forces the device received are nonzero, never above its 3.3 N, and ramp in: the n-th coupled
#      tick's force <= F_max (n + 1) T / ramp_in_s, with n <= (time since the first force) / T + 6
#      (ticks never run ahead of their deadlines; 5 ticks of slack for a starved servo thread);
#   3. the same with ramp_in_s = 0: the first force is the jolt the ramp prevents (printed, and it must
#      exceed the ramped first force ten times over).
# Usage: device_session_check.sh BUILD_BIN_DIR FAKE_LIBHD WORK_DIR
set -euo pipefail
bin="$1"; fakehd="$2"; work="$3"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$bin" "$work"
rm -rf "$work"; mkdir -p "$work"
export PATH="$bin:$PATH"
plant="0.05,5,0.05"
out=$(FAKEHD_AUTO=1 FAKEHD_PLANT=$plant haptic-devices diag --kind touch --hd-library "$fakehd" --max-stale-reads 500 --force-N 0.2 0.4 --push-s 0.3)
bd=$(printf '%s\n' "$out" | sed -n 's/^b_d = (F2 - F1) \/ (v2 - v1) = \([0-9.e+-]*\) N s\/m.*/\1/p')
[ -n "$bd" ] || { printf '%s\n' "$out"; echo "FAIL: diag printed no b_d"; exit 1; }
echo "diag on the stand-in: b_d = $bd N s/m (plant: 5)"

run_lab() {  # run_lab NAME RAMP_S
  local dir="$work/$1"; mkdir -p "$dir"
  cat > "$dir/lab.toml" <<EOT
[lab]
users = 2
scenario = "paper-best"
duration_s = 2.0
push_end_s = 0.8
release_s = 1.2
probe_s = 1.0
start_delay_s = 0.5
default_host = "127.0.0.1"
[network]
transport = "udp"
[topology]
links = "1-2"
[station]
max_no_neighbour_fraction = 0.5   # this checks the device path, not the host: a loaded VM stalls for 0.5 s
loss_allowance_ticks = 1          # likewise: a loaded VM's skipped probe ticks would raise the measured allowance (and B_i)
[[stations]]
id = 1
host = "127.0.0.1"
device = { kind = "touch", hd_library_path = "$fakehd", damping_Ns_per_m = $bd, ramp_in_s = $2 }
[[stations]]
id = 2
host = "127.0.0.1"
device = "simulated"
EOT
  FAKEHD_AUTO=1 FAKEHD_PLANT=$plant FAKEHD_FORCE_LOG="$dir/forces.csv" \
    haptic-lab run "$dir/lab.toml" --runs-dir "$dir/runs" --no-plots > "$dir/lab.log" 2>&1 ||
    { cat "$dir/lab.log" >&2; echo "FAIL: haptic-lab run ($1)" >&2; exit 1; }  # stderr: stdout is the caller's $(...)
  ls -d "$dir"/runs/*/ | head -1
}
ramped=$(run_lab ramp 1.0)
jolt=$(run_lab noramp 0)
/usr/bin/python3 - "$ramped" "$work/ramp/forces.csv" "$jolt" "$work/noramp/forces.csv" <<'PY'
import csv, json, math, sys
fail = []
def load(run, log):
    rep = json.load(open(run + "lab-report.json"))
    st = json.load(open(run + "station-1.json"))
    rows = list(csv.DictReader(open(log)))
    F = [math.sqrt(sum(float(r[k]) ** 2 for k in ("fx_N", "fy_N", "fz_N"))) for r in rows]
    return rep, st, rows, F
rep, st, rows, F = load(sys.argv[1], sys.argv[2])
if not all(s["exit_code"] == 0 for s in rep["stations"]): fail.append("a station failed: %s" % rep["stations"])
if rep.get("consensus_time_s") is None: fail.append("no consensus after the release")
dev = st["lifecycle"]["device"]
if dev["simulated_user"] or dev["kind"] != "touch" or st["device"] != "Phantom/Touch via OpenHaptics HD": fail.append("station 1 did not run the Touch: %s" % dev)
if st["device_fault"] != "none" or st["safe_state_ticks"] != 0: fail.append("device fault %s, %s safe-state ticks" % (st["device_fault"], st["safe_state_ticks"]))
if not dev["proxy_from_device"]: fail.append("proxy not placed from the device")
Fmax, T, ramp = dev["force_limit_N"], 0.002, dev["ramp_in_s"]
nz = [i for i, f in enumerate(F) if f > 0]
if not nz or max(F) < 0.05: fail.append("the device received no force (max %.3g N)" % (max(F) if F else 0))
if max(F) > Fmax + 1e-6: fail.append("force %.4f N above the device's %.2f N" % (max(F), Fmax))
j0 = nz[0] if nz else 0
t = [float(r["t_s"]) for r in rows]
worst = max((F[j] - Fmax * ((t[j] - t[j0]) / T + 6) * T / ramp, j - j0) for j in range(j0, len(F)) if t[j] - t[j0] < ramp)
if worst[0] > 1e-9: fail.append("ramp-in bound exceeded by %.4g N at frame %d after the first force" % worst)
pos = [float(r["x_mm"]) ** 2 + float(r["y_mm"]) ** 2 + float(r["z_mm"]) ** 2 for r in rows]
if max(pos) < 1.0: fail.append("the stand-in stylus never moved under the forces")
first_ramped = F[j0]
_, st2, _, F2 = load(sys.argv[3], sys.argv[4])
first_jolt = next(f for f in F2 if f > 0)
print("end to end, Touch stand-in: %d servo frames, max force %.3f N (limit %.2f N), first force %.4f N with a %.1f s ramp-in "
      "(bound F_max T / ramp_in_s = %.4f N), %.3f N without; consensus %s s after the release"
      % (len(F), max(F), Fmax, first_ramped, ramp, Fmax * T / ramp, first_jolt, rep["consensus_time_s"]))
if not first_jolt > 10 * first_ramped: fail.append("without ramp-in the first force %.4f N is not the jolt (ramped %.4f N)" % (first_jolt, first_ramped))
if fail:
    print("FAILED: " + "; ".join(fail)); sys.exit(1)
PY
