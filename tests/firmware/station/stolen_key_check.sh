#!/usr/bin/env bash
# A stolen key's takeover, multi-process on loopback (net/README.md "Incarnations and restarts"):
# four stations (paper-best, the star: hub 1) planned by haptic-lab; 1 s into the run, haptic-flood
# holding station 2's key file (a compromised PC) announces a newer incarnation of station 2 to the hub
# from station 2's own address (spoofed: root) while the real station 2 keeps running (class
# keyed_restart: hellos MAC'd with the pair's static key, a fresh nonce). Checks: the hub never accepts
# it (no re-keying, incarnation unchanged), finds two live incarnations, refuses both (drops
# incarnation_while_live and key_compromise counted), logs and writes "key compromise suspected:
# station 2 has two live incarnations" (station-1.log, station-1.json key_compromise, condition
# key_compromise_suspected) and exits 12; stations 3 and 4 are unaffected (exit 0). Prints station 2's
# exit (it lost its only neighbour). Not root: exit 77 (SKIPPED).
# CLASS keyed_sequence_burn: the same key holder stays in station 2's incarnation and signs station 2's
# next sequences first (captured genuine states, 5 ticks ahead, net/README.md "Two signers in one
# incarnation"): the hub finds two different authentic datagrams with one sequence, refuses station 2,
# logs "key compromise suspected: station 2 sent two different authentic datagrams with sequence S" and
# exits 12 (no incarnation is refused: incarnation_while_live stays 0).
# Usage: stolen_key_check.sh BUILD_BIN_DIR OUT_DIR [CLASS]   (CLASS: keyed_restart (default), keyed_sequence_burn)
set -euo pipefail
bin="$(cd "$1" && pwd)"; out="$2"; class="${3:-keyed_restart}"
case "$class" in
  keyed_restart) named="key compromise suspected: station 2 has two live incarnations" ;;
  keyed_sequence_burn) named="key compromise suspected: station 2 sent two different authentic datagrams with sequence" ;;
  *) echo "FAILED: unknown class $class"; exit 1 ;;
esac
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
[ "$(id -u)" -eq 0 ] || { echo "SKIPPED: spoofing station 2's address and sniffing loopback need root"; exit 77; }
for b in haptic-station haptic-flood haptic-lab haptic-keygen; do [ -x "$bin/$b" ] || { echo "FAILED: $bin/$b not built"; exit 1; }; done
rm -rf "$out"; mkdir -p "$out"
fail() { echo "FAIL: $*"; exit 1; }
cat >"$out/lab.toml" <<EOT
[lab]
users = 4
scenario = "paper-best"
nodes = 33
duration_s = 4.0
push_end_s = 1.5
release_s = 2.5
probe_s = 1.5
start_delay_s = 5.0   # a loaded machine starts four processes slowly
[network]
transport = "udp"
impairment = "none"
[topology]
from_scenario = true
[station]
max_no_neighbour_fraction = 0.5   # a loaded machine's stalls are not what this checks
EOT
run="$out/run"
HAPTIC_BIN_DIR="$bin" "$bin/haptic-lab" plan "$out/lab.toml" --run-dir "$run" >"$out/plan.log" 2>&1 || { cat "$out/plan.log"; fail "haptic-lab plan"; }
read -r session pub1 ports <<<"$(python3 - "$run/plan.json" <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))
print(p["session_id"], p["stations"][0]["public_key"], " ".join("--station %d=%d" % (s["id"], s["port"]) for s in p["stations"]))
PY
)"
# The attack about 1 s into the run: start delay 5 s + probing 1.5 s + set-up gap 0.5 s + 1 s, and the
# attacker starts ~1 s before the epoch is set (haptic-lab start plans it); on a loaded machine it may land
# in the set-up gap instead, where the keepalive fingerprints keep station 2 alive: refused the same way.
# shellcheck disable=SC2086
"$bin/haptic-flood" --session "$session" $ports --link 2-1 --duration 15 --start-after 9.0 --rate 200 --max-datagrams 400 \
  --classes "$class" --sniff --stolen-key "2=$run/keys/station-2.key" --public-key "1=$pub1" --json "$out/attacker.json" \
  >"$out/attacker.log" 2>&1 &
attacker=$!
sleep 0.2  # the sniffer listens before the first hello
rc=0
HAPTIC_BIN_DIR="$bin" "$bin/haptic-lab" start "$run" >"$out/start.log" 2>&1 || rc=$?
wait "$attacker" || fail "haptic-flood failed: $(cat "$out/attacker.log")"
python3 - "$run" "$out/attacker.json" "$class" "$named" <<'PY'
import json, sys
run, att, cls, named = sys.argv[1], json.load(open(sys.argv[2])), sys.argv[3], sys.argv[4]
st = {i: json.load(open("%s/station-%d.json" % (run, i))) for i in (1, 2, 3, 4)}
sent = att["classes"][cls]["sent"]
assert sent > 0, "the attacker sent nothing of %s (it never saw station 2's states?): %s" % (cls, att)
h = st[1]
d = h["drops"]["by_reason"]
print("attacker: %d %s datagrams; hub drops incarnation_while_live %d, key_compromise %d" % (sent, cls, d["incarnation_while_live"], d["key_compromise"]))
print("exit codes: %s" % {i: s["exit_code"] for i, s in st.items()})
print("hub key_compromise: %s" % h["key_compromise"])
assert (d["incarnation_while_live"] >= 1) if cls == "keyed_restart" else (d["incarnation_while_live"] == 0), d
assert d["key_compromise"] >= 100, d  # every datagram of station 2 after the finding
assert len(h["key_compromise"]) == 1 and named in h["key_compromise"][0], h["key_compromise"]
assert "key_compromise_suspected" in h["conditions"], h["conditions"]
assert h["exit_code"] == 12, h["exit_code"]
assert st[3]["exit_code"] == 0 and st[4]["exit_code"] == 0, (st[3]["exit_code"], st[4]["exit_code"])
assert not st[3]["key_compromise"] and not st[4]["key_compromise"]
PY
grep -q "$named" "$run/station-1.log" || fail "station-1.log does not name the compromise"
grep -q "incarnation [0-9]* announced" "$run/station-2.log" || fail "station 2 does not log the incarnation it announced"
echo "ok: the stolen key's $class was refused; the hub named station 2 and exited 12 (haptic-lab start exit $rc)"
