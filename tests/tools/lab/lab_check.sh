#!/usr/bin/env bash
# haptic-lab from one lab file (tools/lab/README.md):
#   1. plan twice: two different run folders and session ids (never overwritten), station files
#      and keys mode 0600, every peer on the loopback port planned for it; `plan --run-dir` over
#      an earlier run and `start --kill` with a station out of range are refused (exit 2);
#      topology.from_scenario takes a paper scenario's links from haptic-station scenario;
#   2. the paper's four-PC lab file (192.168.10.0/24) plans, but `check` refuses it on a machine
#      with no interface on that network (exit 3, the station names the peer's key), so nothing
#      is sent out of this machine's default route;
#   3. `run` of three local stations (UDP loopback, free ports, asymmetric pushes, 4 s): every
#      station exits 0, consensus reached after release, lab-report.json lists overruns per station.
# With a fourth argument `raw8` it checks instead: `run` of eight stations over raw Ethernet, each in
# a network namespace the tool makes and removes (root; exit 77 = skipped without root/iproute2):
# every station file says transport "raw" with peers by MAC, every station exits 0, consensus after
# release, and no namespace of the run is left afterwards.
# Usage: lab_check.sh BUILD_BIN_DIR SOURCE_DIR WORK_DIR [raw8]
set -euo pipefail
bin="$1"; src="$2"; work="$3"; mode="${4:-udp}"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$bin" "$work"
rm -rf "$work"; mkdir -p "$work"
lab="$bin/haptic-lab"
fail() { echo "FAIL: $*"; exit 1; }
check_report() {  # check_report RUN_DIR USERS: every station exited 0, consensus reached, overruns listed
  python3 - "$1/lab-report.json" "$2" <<'EOT'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["users"] == int(sys.argv[2]), r
assert all(s["exit_code"] == 0 for s in r["stations"]), r["stations"]
assert all(isinstance(s["overruns"], int) for s in r["stations"]), r["stations"]
assert r.get("consensus_time_s") is not None, "no consensus after release: %s" % r.get("consensus_error_m")
print("ok: %d stations exited 0, consensus %.3f s after release, overruns %s" % (r["users"], r["consensus_time_s"], [s["overruns"] for s in r["stations"]]))
EOT
}
write_lab() {  # write_lab FILE USERS TRANSPORT LINKS DURATION PUSH_END RELEASE PROBE START_DELAY (asymmetric pushes)
  cat >"$1" <<EOT
[lab]
users = $2
duration_s = $5
push_end_s = $6
release_s = $7
pushes = "asymmetric"
probe_s = $8
start_delay_s = $9
[network]
transport = "$3"
impairment = "none"
[topology]
links = "$4"
[station]
max_no_neighbour_fraction = 0.5   # this test checks the lab tool, not the host: a loaded VM stalls for 0.5 s
loss_allowance_ticks = 1          # likewise: a loaded VM's skipped probe ticks would raise the measured allowance (and B_i)
EOT
}
run_folder() {  # the run folder (the only one with a lab-report.json; names sort by time, then by random session)
  for x in "$work"/runs/*/; do
    if [ -f "$x/lab-report.json" ]; then echo "$x"; return 0; fi
  done
  return 1
}

if [ "$mode" = raw8 ]; then
  if [ "$(id -u)" -ne 0 ] || ! command -v ip >/dev/null; then echo "SKIPPED: raw Ethernet in namespaces needs root and iproute2"; exit 77; fi
  ip netns add hpltest-probe 2>/dev/null || { echo "SKIPPED: cannot create network namespaces here"; exit 77; }
  ip netns del hpltest-probe
  write_lab "$work/raw8.toml" 8 raw "1-2,2-3,3-4,4-5,5-6,6-7,7-8,8-1,1-5" 5.0 1.5 3.0 1.5 2.0
  "$lab" run "$work/raw8.toml" --runs-dir "$work/runs" --no-plots >"$work/run.log" 2>&1 || { cat "$work/run.log"; fail "haptic-lab run (raw) failed"; }
  d=$(run_folder) || { cat "$work/run.log"; fail "no run folder with lab-report.json"; }
  for i in 1 2 3 4 5 6 7 8; do
    grep -q '^transport = "raw"' "$d/station-$i.toml" || fail "station-$i.toml is not a raw-Ethernet station"
  done
  grep -q 'mac = "02:48:50:00:00:02"' "$d/station-1.toml" || fail "station 1 does not name station 2 by its namespace's MAC"
  prefix=$(python3 -c "import json,sys;print(json.load(open(sys.argv[1]))['netns_prefix'])" "$d/plan.json")
  if ip netns list | grep -q "^$prefix-"; then fail "namespaces $prefix-* are left after the run"; fi
  check_report "$d" 8
  echo "ok: eight raw-Ethernet stations in namespaces $prefix-st0..7, removed after the run"
  exit 0
fi
write_lab "$work/three.toml" 3 udp "1-2,2-3" 4.0 1.0 2.0 1.0 1.5
a=$("$lab" plan "$work/three.toml" --runs-dir "$work/runs" | tail -1)
b=$("$lab" plan "$work/three.toml" --runs-dir "$work/runs" | tail -1)
[ "$a" != "$b" ] && [ -d "$a" ] && [ -d "$b" ] || fail "two plans gave one folder: $a $b"
sa=$(python3 -c "import json;print(json.load(open('$a/plan.json'))['session_id'])")
sb=$(python3 -c "import json;print(json.load(open('$b/plan.json'))['session_id'])")
[ "$sa" != "$sb" ] || fail "two plans gave one session id $sa"
for f in "$a"/station-*.toml "$a"/keys/station-*.key; do
  [ "$(stat -c %a "$f")" = 600 ] || fail "$f has mode $(stat -c %a "$f"), not 600"
done
[ "$(stat -c %a "$a/keys")" = 700 ] || fail "$a/keys has mode $(stat -c %a "$a/keys"), not 700"
[ "$(ls "$a"/keys/station-*.key | wc -l)" = 3 ] || fail "not one key file per station in $a/keys"
# each station's own key file, and its neighbours' public keys (station 2 is the middle of 1-2-3)
grep -q 'key_file = "keys/station-2.key"' "$a/station-2.toml" || fail "station 2 does not read its own key file"
for j in 1 3; do
  pk=$(grep '^public_key' "$a/keys/station-$j.key" | cut -d'"' -f2)
  grep -q "public_key = \"$pk\"" "$a/station-2.toml" || fail "station 2 does not list station $j's public key"
done
! grep -q "secret_key\|session_key" "$a/station-2.toml" || fail "a station file holds a secret"
p2=$(python3 -c "import json;print(json.load(open('$a/plan.json'))['stations'][1]['port'])")
grep -q "address = \"127.0.0.1:$p2\"" "$a/station-1.toml" || fail "station 1 does not send to station 2's planned port $p2"
echo "ok: two plans, two folders ($(basename "$a"), $(basename "$b")), sessions $sa / $sb, files 0600"
# check --probe: the stations themselves measure reachability (round trips per link) and clock
# offsets, probing only, nothing coupled; 1-2-3 has four directed links
"$lab" check --probe "$a" >"$work/probe.log" 2>&1 || { cat "$work/probe.log"; fail "check --probe of three local stations failed"; }
[ "$(grep -cE '^  station [123] -> [123]: [1-9][0-9]* round trips, mean [0-9.]+ ms, .*clock offset -?[0-9.]+ ms' "$work/probe.log")" = 4 ] ||
  { cat "$work/probe.log"; fail "check --probe did not report round trips and a clock offset for each of the 4 directed links"; }
for i in 1 2 3; do
  python3 -c "import json,sys;j=json.load(open('$a/probe/station-$i.json'));sys.exit(0 if j['ticks_run']==0 and j['lifecycle']['probe_only'] else 1)" ||
    fail "station $i's probe ran ticks or is not marked probe_only"
done
echo "ok: check --probe measured every link's round trips and clock offset, no run ($(grep -m1 'round trips' "$work/probe.log" | sed 's/^ *//'))"
set +e
"$lab" plan "$work/three.toml" --run-dir "$a" >"$work/rerun.log" 2>&1; rc_dir=$?
"$lab" start "$a" --kill 4:1:2 >"$work/kill.log" 2>&1; rc_kill=$?
set -e
[ "$rc_dir" -eq 2 ] && grep -q "already holds a run" "$work/rerun.log" || { cat "$work/rerun.log"; fail "plan --run-dir over an earlier run exited $rc_dir"; }
[ "$rc_kill" -eq 2 ] && grep -q "station I in 1..3" "$work/kill.log" || { cat "$work/kill.log"; fail "start --kill 4:1:2 on 3 stations exited $rc_kill"; }
echo "ok: plan --run-dir refuses a folder that holds a run; start --kill names the bad station (exit 2)"

# topology.from_scenario: the links come from the scenario's one definition (haptic-station scenario)
write_lab "$work/worst.toml" 4 udp "" 4.0 1.0 2.0 1.0 1.5
sed -i 's/^links = ""$/from_scenario = true/; s/^\[lab\]$/[lab]\nscenario = "paper-worst"/' "$work/worst.toml"
w=$("$lab" plan "$work/worst.toml" --runs-dir "$work/runs" | tail -1)
wl=$(python3 -c "import json;print(json.load(open('$w/plan.json'))['links'])")
[ "$wl" = "1-2,2-4,3-4" ] || fail "topology.from_scenario for paper-worst planned links $wl, not the scenario's 1-2,2-4,3-4"
sed -i 's/^users = 4$/users = 3/' "$work/worst.toml"
runs_before=$(ls "$work/runs" | wc -l)
set +e
"$lab" plan "$work/worst.toml" --runs-dir "$work/runs" >"$work/worst3.log" 2>&1; rc_w=$?
set -e
[ "$rc_w" -eq 2 ] && grep -q "scenario paper-worst has 4 users, the lab has 3" "$work/worst3.log" || { cat "$work/worst3.log"; fail "from_scenario with 3 users exited $rc_w"; }
[ "$(ls "$work/runs" | wc -l)" -eq "$runs_before" ] || fail "the refused plan left a half-written run folder in $work/runs"
rm -rf "$w"
echo "ok: topology.from_scenario plans paper-worst's links $wl; a 3-user lab with that scenario is refused (exit 2) and leaves no run folder"

c=$("$lab" plan "$src/tools/lab/examples/lab-4-pcs.toml" --runs-dir "$work/runs" | tail -1)
set +e
"$lab" check "$c" >"$work/check-4pcs.log" 2>&1
rc=$?
set -e
if ip -4 addr | grep -q "inet 192\.168\.10\."; then
  echo "NOTE: this machine is on 192.168.10.0/24: the refusal is not checked here"
else
  [ "$rc" -eq 3 ] || { cat "$work/check-4pcs.log"; fail "check of the 192.168.10.x lab exited $rc, not 3"; }
  grep -q 'net.peers\[0\].address = "192.168.10.1[234]:47000" is on no network of this machine' "$work/check-4pcs.log" ||
    { cat "$work/check-4pcs.log"; fail "the refusal does not name the peer"; }
  echo "ok: the four-PC lab file is refused here (no interface on 192.168.10.0/24), exit 3"
fi
# remote stations: start prints the per-PC steps (and sends nothing); each PC gets its station file
# AND its key, and the outputs come back from the station's <UTC>-s<session> folder
"$lab" start "$c" >"$work/start-4pcs.log" 2>&1 || { cat "$work/start-4pcs.log"; fail "start of the four-PC lab (printing) failed"; }
n=$(basename "$c")
grep -q "scp -p $c/keys/station-4.key 192.168.10.14:$n/keys/" "$work/start-4pcs.log" &&
  grep -q "\[192.168.10.12\] cd $n && haptic-station run --config station-2.toml --start-at" "$work/start-4pcs.log" &&
  grep -q "scp -p '192.168.10.13:$n/\*-s${n##*-s}/station-3\*' $c/" "$work/start-4pcs.log" ||
  { cat "$work/start-4pcs.log"; fail "the printed per-PC steps do not copy each station's key or fetch its outputs"; }
echo "ok: the four-PC lab's printed steps give each PC its station file and key and fetch its outputs"
"$lab" check --probe "$c" >"$work/probe-4pcs.log" 2>&1 || true  # exit 3 here: the station files are refused on this machine
grep -q "\[192.168.10.13\] cd $n && haptic-station run --config station-3.toml --probe-only --out probe --start-at" "$work/probe-4pcs.log" ||
  { cat "$work/probe-4pcs.log"; fail "check --probe of the four-PC lab does not print each PC's probe-only command"; }
echo "ok: check --probe of the four-PC lab prints each PC's probe-only command (one epoch)"

"$lab" run "$work/three.toml" --runs-dir "$work/runs" --no-plots >"$work/run.log" 2>&1 || { cat "$work/run.log"; fail "haptic-lab run failed"; }
d=$(run_folder) || { cat "$work/run.log"; fail "no run folder with lab-report.json"; }
check_report "$d" 3
