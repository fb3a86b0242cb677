#!/usr/bin/env bash
# The lab console of a lab on other PCs (tools/lab/examples/lab-4-pcs.toml, 192.168.10.0/24), with no
# station running and no packet leaving this machine (no lab.view_port_base: nothing is polled; `ssh`
# is a stand-in on PATH that records its arguments):
#   1. `haptic-lab console RUN` shows a row per station, each "missing" and red;
#   2. plan with lab.view_port_base writes station.view_bind = the PC's lab address into each remote
#      station file (its view and /status.json readable by the console on the lab network);
#   3. stop-all with lab.remote_control = "ssh" runs `ssh HOST sudo -n systemctl stop haptic-station@N` for
#      every PC (the installed unit; no agent of ours); by default it only lists them on the page;
#      a stop without the page's token is refused (403).
# Usage: console_remote_check.sh BUILD_BIN_DIR SOURCE_DIR WORK_DIR   (~10 s, no stations)
set -uo pipefail
bin="$1"; src="$2"; work="$3"
rm -rf "$work"; mkdir -p "$work/fakebin"
fail() { echo "FAILED: $*"; exit 1; }
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done' EXIT
printf '#!/bin/sh\necho "$*" >> %s/ssh.log\n' "$work" > "$work/fakebin/ssh"; chmod +x "$work/fakebin/ssh"
export PATH="$work/fakebin:$PATH"
lab="$bin/haptic-lab"
serve() {  # serve RUN NAME: starts `haptic-lab console RUN`, prints its URL
  "$lab" console "$1" --for 60 > "$work/$2.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 1 100); do
    u=$(sed -n 's/^haptic-lab console: \(http:[^ ]*\) .*/\1/p' "$work/$2.log" | head -1)
    [ -n "$u" ] && { echo "$u"; return 0; }; sleep 0.1
  done
  cat "$work/$2.log" >&2; return 1
}
page() { /usr/bin/python3 -c 'import sys, urllib.request as u; print(u.build_opener(u.ProxyHandler({})).open(sys.argv[1], timeout=5).read().decode())' "$1"; }
stop() {  # stop URL TOKEN -> HTTP status
  /usr/bin/python3 - "$1" "$2" <<'PY'
import sys, urllib.parse, urllib.request as u
class NoRedirect(u.HTTPRedirectHandler):
    def redirect_request(self, *a): return None
o = u.build_opener(u.ProxyHandler({}), NoRedirect())
try:
    print(o.open(sys.argv[1] + "stop", data=urllib.parse.urlencode({"token": sys.argv[2]}).encode(), timeout=5).status)
except u.HTTPError as e:
    print(e.code)
PY
}
token() { sed -n 's/.*name="token" value="\([0-9a-f]*\)".*/\1/p'; }

# 2. remote station files with view_port_base: the view binds the PC's lab address
sed "s/^\[lab\]$/[lab]\nview_port_base = 47000/" "$src/tools/lab/examples/lab-4-pcs.toml" > "$work/views.toml"
v=$("$lab" plan "$work/views.toml" --runs-dir "$work/runs" | tail -1)
for i in 1 2 3 4; do
  grep -q "^view_port = $(( 47000 + i - 1 ))$" "$v/station-$i.toml" && grep -q "^view_bind = \"192.168.10.1$i\"$" "$v/station-$i.toml" ||
    fail "station-$i.toml does not serve its view on 192.168.10.1$i:$(( 47000 + i - 1 ))"
done
echo "ok: remote station files serve their view (and /status.json) on their lab address, port base + i - 1"

# 1. + 3. (default): rows missing and red; stop-all lists the ssh commands and runs none
r=$("$lab" plan "$src/tools/lab/examples/lab-4-pcs.toml" --runs-dir "$work/runs" | tail -1)
"$lab" start "$r" > "$work/start.log" 2>&1 || fail "start of the four-PC lab (printing) failed"
grep -q "haptic-lab console $r" "$work/start.log" || { cat "$work/start.log"; fail "start's remote steps do not name the console"; }
url=$(serve "$r" console-print) || fail "haptic-lab console printed no URL"
p=$(page "$url")
[ "$(grep -c '<tr class="station bad" id="station-[1-4]" data-station="[1-4]" data-state="missing">' <<<"$p")" = 4 ] ||
  { echo "$p"; fail "the four remote stations with no status are not four red 'missing' rows"; }
[ "$(stop "$url" 00)" = 403 ] || fail "a stop without the page's token was not refused"
[ "$(stop "$url" "$(token <<<"$p")")" = 303 ] || fail "stop-all with the page's token was refused"
sleep 1
[ ! -e "$work/ssh.log" ] || { cat "$work/ssh.log"; fail "stop-all ran ssh without lab.remote_control = \"ssh\""; }
p=$(page "$url"); grep -q "ssh -o BatchMode=yes -o ConnectTimeout=5 192.168.10.14 sudo -n systemctl stop haptic-station@4" <<<"$p" || fail "the page does not list the remote stop commands"
echo "ok: four red 'missing' rows; stop-all lists ssh HOST sudo -n systemctl stop haptic-station@N and runs none by default; no token: 403"

# 3. lab.remote_control = "ssh": stop-all runs them
sed "s/^\[lab\]$/[lab]\nremote_control = \"ssh\"/" "$src/tools/lab/examples/lab-4-pcs.toml" > "$work/ssh.toml"
s=$("$lab" plan "$work/ssh.toml" --runs-dir "$work/runs" | tail -1)
url=$(serve "$s" console-ssh) || fail "haptic-lab console printed no URL"
[ "$(stop "$url" "$(page "$url" | token)")" = 303 ] || fail "stop-all with the page's token was refused"
for _ in $(seq 1 50); do [ "$(wc -l < "$work/ssh.log" 2>/dev/null || echo 0)" -ge 4 ] && break; sleep 0.1; done
for i in 1 2 3 4; do
  grep -qx -- "-o BatchMode=yes -o ConnectTimeout=5 192.168.10.1$i sudo -n systemctl stop haptic-station@$i" "$work/ssh.log" ||
    { cat "$work/ssh.log" 2>/dev/null; fail "stop-all did not run ssh 192.168.10.1$i sudo -n systemctl stop haptic-station@$i"; }
done
echo "ok: with lab.remote_control = \"ssh\" stop-all ran ssh HOST sudo -n systemctl stop haptic-station@N for the 4 PCs"
