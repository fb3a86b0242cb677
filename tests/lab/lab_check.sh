#!/usr/bin/env bash
# haptic-lab from one lab file (tools/lab/README.md):
#   1. plan twice: two different run folders and session ids (never overwritten), station files
#      and keys mode 0600, every peer on the loopback port planned for it;
#   2. the paper's four-PC lab file (192.168.10.0/24) plans, but `check` refuses it on a machine
#      with no interface on that network (exit 3, the station names the peer's key), so nothing
#      is sent out of this machine's default route;
#   3. `run` of three local stations (UDP loopback, free ports, asymmetric pushes, 4 s): every
#      station exits 0, consensus reached after release, lab-report.json lists overruns per station.
# Usage: lab_check.sh BUILD_BIN_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
bin="$1"; src="$2"; work="$3"
rm -rf "$work"; mkdir -p "$work"
lab="$bin/haptic-lab"
fail() { echo "FAIL: $*"; exit 1; }
cat >"$work/three.toml" <<EOT
[lab]
users = 3
duration_s = 4.0
push_end_s = 1.0
release_s = 2.0
pushes = "asymmetric"
probe_s = 1.0
start_delay_s = 1.5
[network]
impairment = "none"
[topology]
links = "1-2,2-3"
[station]
max_no_neighbour_fraction = 0.5   # this test checks the lab tool, not the host: a loaded VM stalls for 0.5 s
EOT
a=$("$lab" plan "$work/three.toml" --runs-dir "$work/runs" | tail -1)
b=$("$lab" plan "$work/three.toml" --runs-dir "$work/runs" | tail -1)
[ "$a" != "$b" ] && [ -d "$a" ] && [ -d "$b" ] || fail "two plans gave one folder: $a $b"
sa=$(python3 -c "import json;print(json.load(open('$a/plan.json'))['session_id'])")
sb=$(python3 -c "import json;print(json.load(open('$b/plan.json'))['session_id'])")
[ "$sa" != "$sb" ] || fail "two plans gave one session id $sa"
for f in "$a"/station-*.toml "$a"/keys/session.key; do
  [ "$(stat -c %a "$f")" = 600 ] || fail "$f has mode $(stat -c %a "$f"), not 600"
done
p2=$(python3 -c "import json;print(json.load(open('$a/plan.json'))['stations'][1]['port'])")
grep -q "address = \"127.0.0.1:$p2\"" "$a/station-1.toml" || fail "station 1 does not send to station 2's planned port $p2"
echo "ok: two plans, two folders ($(basename "$a"), $(basename "$b")), sessions $sa / $sb, files 0600"

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

"$lab" run "$work/three.toml" --runs-dir "$work/runs" --no-plots >"$work/run.log" 2>&1 || { cat "$work/run.log"; fail "haptic-lab run failed"; }
d=""  # the run folder (the only one with a lab-report.json; folder names sort by time, then by random session)
for x in "$work"/runs/*/; do
  if [ -f "$x/lab-report.json" ]; then d="$x"; break; fi
done
[ -n "$d" ] || { cat "$work/run.log"; fail "no run folder with lab-report.json"; }
python3 - "$d/lab-report.json" <<'EOT'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["users"] == 3, r
assert all(s["exit_code"] == 0 for s in r["stations"]), r["stations"]
assert all(isinstance(s["overruns"], int) for s in r["stations"]), r["stations"]
assert r.get("consensus_time_s") is not None, "no consensus after release: %s" % r.get("consensus_error_m")
print("ok: 3 stations exited 0, consensus %.3f s after release, overruns %s" % (r["consensus_time_s"], [s["overruns"] for s in r["stations"]]))
EOT
