#!/usr/bin/env bash
# Remote stations started and stopped through what a lab already runs: ssh and the installed unit
# (tools/lab/README.md "Remote PCs: ssh and the unit"). No packet leaves this machine and the real
# systemd is never touched: `ssh` is a stand-in (given with --ssh) that records its arguments and runs
# the command here with stand-in `sudo`, `systemctl` (a unit state file per PC, a start refused while
# the PC has no station file) and `install` (/etc/haptic of PC H is WORK/pcs/H/etc/haptic):
#   1. --dry-run prints every command and runs none;
#   2. start --remote ssh copies each station file (with one wall-clock station.start_at, nothing
#      else changed) and key (0600) before `sudo -n systemctl start haptic-station@N` on its PC,
#      waits for the units and exits 0;
#   3. a station whose unit last stopped in a safety stop (exit 5; SIGSEGV) or still runs is refused
#      (exit 3) naming station, host and why, and nothing starts; --rearm starts them;
#   4. a failed remote start exits 4 naming station and host, and the units already started are stopped;
#   5. a unit that ended with exit 7 makes start exit 4 naming station and host;
#   6. `haptic-lab stop` stops every unit, a failed stop exits 4 naming station and host;
#   7. a local run folder whose last start ended in a safety stop needs --rearm (this PC); stop sends
#      SIGTERM to its station processes only;
#   8. haptic-lab's safety stops are the unit's RestartPreventExitStatus (less 2, a configuration error).
# Usage: remote_ssh_check.sh BUILD_BIN_DIR SOURCE_DIR WORK_DIR   (~5 s, no stations run)
set -uo pipefail
bin="$1"; src="$2"; work="$3"
rm -rf "$work"; mkdir -p "$work/fakebin" "$work/pcbin" "$work/pcs"
fail() { echo "FAILED: $*"; exit 1; }
cat > "$work/fakebin/ssh" <<EOF
#!/bin/sh
echo "\$*" >> "$work/ssh.log"
while [ "\${1#-}" != "\$1" ]; do case "\$1" in -o) shift 2;; *) shift;; esac; done
host=\$1; shift
mkdir -p "$work/pcs/\$host"
PC="$work/pcs/\$host" PATH="$work/pcbin:\$PATH" exec "\$@"
EOF
printf '#!/bin/sh\n[ "$1" = -n ] && shift\nexec "$@"\n' > "$work/pcbin/sudo"
cat > "$work/pcbin/systemctl" <<'EOF'
#!/bin/bash
unit="${!#}"; n="${unit#haptic-station@}"
case "$1" in
  show) cat "$PC/$unit.state" 2>/dev/null || printf 'ActiveState=inactive\nResult=success\nExecMainCode=0\nExecMainStatus=0\n';;
  start) [ -e "$PC/fail-start" ] && { echo "Job for $unit failed because the control process exited with error code." >&2; exit 1; }
         [ -s "$PC/etc/haptic/station-$n.toml" ] || { echo "$unit: no station-$n.toml" >&2; exit 1; }
         c=$(cat "$PC/next-exit" 2>/dev/null || echo 0)
         if [ "$c" = 0 ]; then s="inactive success"; else s="failed exit-code"; fi
         set -- $s; printf 'ActiveState=%s\nResult=%s\nExecMainCode=1\nExecMainStatus=%s\n' "$1" "$2" "$c" > "$PC/$unit.state";;
  stop) [ -e "$PC/fail-stop" ] && { echo "Failed to stop $unit: Access denied" >&2; exit 4; }; echo "$unit" >> "$PC/stops";;
  *) echo "stand-in systemctl: $*?" >&2; exit 1;;
esac
EOF
cat > "$work/pcbin/install" <<'EOF'
#!/bin/bash
a=(); while [ $# -gt 0 ]; do case "$1" in -o|-g) shift 2;; /etc/haptic*) a+=("$PC$1"); shift;; *) a+=("$1"); shift;; esac; done
exec /usr/bin/install "${a[@]}"
EOF
chmod +x "$work/fakebin/ssh" "$work/pcbin/"*
lab="$bin/haptic-lab"
ssh_="$work/fakebin/ssh -o BatchMode=yes"
r=$("$lab" plan "$src/tools/lab/examples/lab-4-pcs.toml" --runs-dir "$work/runs" | tail -1) || fail "plan failed"
state() { printf 'ActiveState=%s\nResult=%s\nExecMainCode=%s\nExecMainStatus=%s\n' "$2" "$3" "$4" "$5" > "$work/pcs/192.168.10.1$1/haptic-station@$1.state"; }
starts() { grep -c "sudo -n systemctl start haptic-station@" "$work/ssh.log" 2>/dev/null; }

# 1. dry run
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --dry-run 2>&1) || { echo "$out"; fail "start --dry-run failed"; }
for i in 1 2 3 4; do grep -q "ssh -o BatchMode=yes 192.168.10.1$i sudo -n systemctl start haptic-station@$i$" <<<"$out" ||
  { echo "$out"; fail "--dry-run does not print station $i's systemctl start"; }; done
[ ! -e "$work/ssh.log" ] || fail "--dry-run ran ssh"
echo "ok: --dry-run prints each PC's systemctl start and runs nothing"

# 2. start through ssh and the unit
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console 2>&1) || { echo "$out"; fail "start --remote ssh failed"; }
epochs=""
for i in 1 2 3 4; do
  pc="$work/pcs/192.168.10.1$i"; log=$(grep -n "192.168.10.1$i " "$work/ssh.log")
  grep -q "^-o BatchMode=yes 192.168.10.1$i sudo -n systemctl start haptic-station@$i$" "$work/ssh.log" || { cat "$work/ssh.log"; fail "station $i not started by its unit"; }
  [ "$(grep -n "install .*station-$i.toml" <<<"$log" | cut -d: -f1)" -lt "$(grep -n "systemctl start" <<<"$log" | cut -d: -f1)" ] || fail "station $i started before its file was copied"
  d=$(diff "$r/station-$i.toml" "$pc/etc/haptic/station-$i.toml" | grep '^[<>]')
  [[ "$d" =~ ^\>\ start_at\ =\ [0-9]+\.[0-9]{3}$ ]] || { echo "$d"; fail "station $i's copied file differs from the run's by more than station.start_at"; }
  epochs+="${d#> start_at = } "
  cmp -s "$r/keys/station-$i.key" "$pc/etc/haptic/keys/station-$i.key" && [ "$(stat -c %a "$pc/etc/haptic/keys/station-$i.key")" = 600 ] ||
    fail "station $i's key is not on its PC with mode 0600"
done
[ "$(tr ' ' '\n' <<<"$epochs" | sort -u | grep -c .)" = 1 ] || fail "the stations got different start_at: $epochs"
grep -q "4/4 stations exited 0" <<<"$out" || { echo "$out"; fail "start does not report 4/4 exited 0"; }
echo "ok: start --remote ssh copied file (one start_at for all: ${epochs%% *}) and key (0600), then systemctl start on each PC; 4/4 exited 0"

# 3. safety stops need --rearm; a running unit is refused
state 2 failed exit-code 1 5; state 3 failed core-dump 3 11
n0=$(starts)
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console 2>&1); rc=$?
[ "$rc" = 3 ] || { echo "$out"; fail "start after a safety stop: exit $rc, not 3"; }
grep -q "station 2 on 192.168.10.12: .*safety stop, exit 5 (safe state latched).*--rearm" <<<"$out" || { echo "$out"; fail "the refusal does not name station 2, its host, exit 5 and --rearm"; }
grep -q "station 3 on 192.168.10.13: .*killed by SIGSEGV" <<<"$out" || { echo "$out"; fail "a crashed station 3 is not refused"; }
[ "$(starts)" = "$n0" ] || fail "a station was started although another was refused"
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console --rearm 2>&1) || { echo "$out"; fail "start --rearm failed"; }
[ "$(starts)" = $((n0 + 4)) ] || fail "start --rearm did not start the four units"
state 1 active success 0 0
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console 2>&1); rc=$?
[ "$rc" = 3 ] && grep -q "station 1 on 192.168.10.11: haptic-station@1 is active" <<<"$out" || { echo "$out"; fail "a unit still running was not refused (exit $rc)"; }
state 1 inactive success 1 0
echo "ok: exit 5 and SIGSEGV refused (exit 3) naming station, host and --rearm, nothing started; --rearm starts; a running unit refused"

# 4. a failed remote start
touch "$work/pcs/192.168.10.13/fail-start"; rm -f "$work/pcs/"*/stops
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console 2>&1); rc=$?
[ "$rc" = 4 ] || { echo "$out"; fail "a failed remote start: exit $rc, not 4"; }
grep -q "station 3 on 192.168.10.13: systemctl start haptic-station@3 failed (exit 1" <<<"$out" || { echo "$out"; fail "the failure does not name station 3 and its host"; }
[ -s "$work/pcs/192.168.10.11/stops" ] && [ -s "$work/pcs/192.168.10.12/stops" ] && [ ! -e "$work/pcs/192.168.10.14/stops" ] ||
  fail "stations 1 and 2 (started) were not stopped again, or station 4 (never started) was"
rm "$work/pcs/192.168.10.13/fail-start"
echo "ok: a failed remote start exits 4 naming station 3 on 192.168.10.13; stations 1, 2 stopped again"

# 5. a station that ended badly
echo 7 > "$work/pcs/192.168.10.14/next-exit"
out=$("$lab" start "$r" --remote ssh --ssh "$ssh_" --no-console 2>&1); rc=$?
[ "$rc" = 4 ] && grep -q "station 4 on 192.168.10.14: exited 7" <<<"$out" || { echo "$out"; fail "station 4's exit 7 not reported (start exit $rc)"; }
rm "$work/pcs/192.168.10.14/next-exit"; state 4 inactive success 1 0
echo "ok: a unit that exited 7 makes start exit 4 naming station 4 on 192.168.10.14"

# 6. stop
rm -f "$work/pcs/"*/stops
out=$("$lab" stop "$r" --ssh "$ssh_" 2>&1) || { echo "$out"; fail "stop failed"; }
for i in 1 2 3 4; do grep -qx "haptic-station@$i" "$work/pcs/192.168.10.1$i/stops" || fail "stop did not stop station $i's unit"; done
touch "$work/pcs/192.168.10.12/fail-stop"
out=$("$lab" stop "$r" --ssh "$ssh_" 2>&1); rc=$?
[ "$rc" = 4 ] && grep -q "station 2 on 192.168.10.12: systemctl stop haptic-station@2 failed" <<<"$out" || { echo "$out"; fail "a failed stop: exit $rc, or not named"; }
echo "ok: stop runs sudo -n systemctl stop on each PC; a failed stop exits 4 naming station 2 on 192.168.10.12"

# 7. a local run folder: its last start's safety stop needs --rearm
cat > "$work/local.toml" <<EOT
[lab]
users = 3
[topology]
links = "1-2,2-3"
EOT
l=$("$lab" plan "$work/local.toml" --runs-dir "$work/runs" | tail -1) || fail "plan of the local lab failed"
echo '{"exit_codes": [0, 4, -6]}' > "$l/start.json"
out=$("$lab" start "$l" --no-console 2>&1); rc=$?
[ "$rc" = 3 ] && grep -q "station 2 on this PC: .*exit 4 (diverged).*--rearm" <<<"$out" && grep -q "station 3 on this PC: .*SIGABRT" <<<"$out" ||
  { echo "$out"; fail "a local start after a safety stop was not refused (exit $rc) naming stations 2 and 3"; }
out=$("$lab" start "$l" --no-console --rearm --dry-run 2>&1) || { echo "$out"; fail "start --rearm --dry-run of the local lab failed"; }
[ "$(grep -c "haptic-station run --config $l/station-[1-3].toml --start-at" <<<"$out")" = 3 ] || { echo "$out"; fail "--dry-run does not print the 3 local commands"; }
echo "ok: a local run folder whose stations 2 and 3 ended in exit 4 and SIGABRT is refused without --rearm"
# stop of a local run: SIGTERM by station-pids.txt, only to a process of this run's station file (a
# stand-in process whose command line names station-1.toml; a pid of another program is left alone)
/usr/bin/python3 -c 'import time; time.sleep(120)' "$l/station-1.toml" & fake=$!
sleep 120 & other=$!
printf '%s\n%s\n' "$fake" "$other" > "$l/station-pids.txt"
out=$("$lab" stop "$l" --dry-run 2>&1) && grep -q "kill -TERM $fake  # station 1" <<<"$out" && kill -0 "$fake" || { echo "$out"; fail "stop --dry-run of a local run"; }
out=$("$lab" stop "$l" 2>&1) || { echo "$out"; fail "stop of a local run failed"; }
wait "$fake"; frc=$?
[ "$frc" = 143 ] && kill -0 "$other" 2>/dev/null || { echo "$out"; fail "stop: station 1's process ended with $frc (not SIGTERM), or another pid was signalled"; }
kill "$other"
echo "ok: stop of a local run sends SIGTERM to its station's process only (--dry-run: printed, not sent)"

# 8. one list of safety stops: the unit's
/usr/bin/python3 - "$lab" "$src/firmware/deploy/haptic-station@.service.in" <<'PY' || fail "haptic-lab's safety stops are not the unit's"
import importlib.machinery, importlib.util, re, sys
loader = importlib.machinery.SourceFileLoader("haptic_lab", sys.argv[1])
m = importlib.util.module_from_spec(importlib.util.spec_from_loader("haptic_lab", loader))
loader.exec_module(m)
unit = set(re.search(r"^RestartPreventExitStatus=(.*)$", open(sys.argv[2]).read(), re.M).group(1).split()) - {"2"}
ours = {str(c) for c in m.SAFETY_EXITS} | {s.name for s in m.SAFETY_SIGNALS}
if unit != ours:
    sys.exit("unit %s, haptic-lab %s" % (sorted(unit), sorted(ours)))
PY
echo "ok: haptic-lab's safety stops are the unit's RestartPreventExitStatus less 2"
