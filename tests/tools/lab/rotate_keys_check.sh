#!/usr/bin/env bash
# A stolen key is revoked and the lab's keys rotated (tools/lab/README.md "Keys: revoke and rotate";
# net/README.md "Incarnations and restarts"), checked with every station's `run --check-config` (no
# station runs, nothing is sent):
#   1. a lab file's [net] revoked_keys (a TOML list) reaches every station file as one string;
#   2. `haptic-lab rotate-keys RUN_DIR` gives every station a new key pair and its neighbours the new
#      public keys: every station file still passes --check-config, and every old public key is in
#      every station file's net.revoked_keys;
#   3. station 2 given back its old (stolen) key file is refused (exit 2) naming net.key_file as written
#      and the key; station 1's file given back station 2's old public key is refused naming
#      net.peers[0].public_key as written.
# Usage: rotate_keys_check.sh BUILD_BIN_DIR WORK_DIR
set -euo pipefail
bin="$1"; work="$2"
rm -rf "$work"; mkdir -p "$work"
fail() { echo "FAIL: $*"; exit 1; }
check_config() { "$bin/haptic-station" run --config "$1" --check-config 2>&1; }
stolen=$("$bin/haptic-keygen" "$work/stolen.key" | awk '{print $2}')
cat >"$work/lab.toml" <<EOT
[lab]
users = 3
duration_s = 4.0
push_end_s = 1.0
release_s = 2.0
[network]
transport = "udp"
impairment = "none"
[topology]
links = "1-2,2-3"
[net]
revoked_keys = ["$stolen"]
EOT
d=$("$bin/haptic-lab" plan "$work/lab.toml" --runs-dir "$work/runs" | tail -1)
grep -q "^revoked_keys = \"$stolen\"$" "$d/station-1.toml" || fail "the lab file's revoked key is not in station-1.toml"
for i in 1 2 3; do check_config "$d/station-$i.toml" >/dev/null || fail "station $i does not pass --check-config before the rotation"; done
pub() { python3 -c 'import json,sys;print(json.load(open(sys.argv[1]))["stations"][int(sys.argv[2])-1]["public_key"])' "$d/plan.json" "$1"; }
old1=$(pub 1); old2=$(pub 2); old3=$(pub 3)
cp -p "$d/keys/station-2.key" "$work/old-station-2.key"
"$bin/haptic-lab" rotate-keys "$d" || fail "rotate-keys failed"
new2=$(pub 2)
[ "$new2" != "$old2" ] || fail "station 2 kept its public key"
for i in 1 2 3; do
  out=$(check_config "$d/station-$i.toml") || { echo "$out"; fail "station $i does not pass --check-config after the rotation"; }
  line=$(grep '^revoked_keys = ' "$d/station-$i.toml") || fail "station-$i.toml has no revoked_keys"
  for k in "$stolen" "$old1" "$old2" "$old3"; do echo "$line" | grep -q "$k" || fail "station-$i.toml does not revoke $k"; done
done
grep -q "public_key = \"$new2\"" "$d/station-1.toml" || fail "station 1 does not know station 2's new public key"
[ "$(stat -c %a "$d/keys/station-2.key")" = 600 ] || fail "the new key file is not 0600"
cp -p "$work/old-station-2.key" "$d/keys/station-2.key"  # station 2 with its old (stolen) key
if out=$(check_config "$d/station-2.toml"); then fail "station 2 with its revoked key passed --check-config"; else rc=$?; fi
[ "$rc" = 2 ] || fail "station 2 with its revoked key: exit $rc, not 2"
echo "$out" | grep -qF 'net.key_file = "keys/station-2.key"' || { echo "$out"; fail "the refusal does not name net.key_file as written"; }
echo "$out" | grep -qF "$old2" || { echo "$out"; fail "the refusal does not name the revoked key"; }
sed -i "s/public_key = \"$new2\"/public_key = \"$old2\"/" "$d/station-1.toml"  # station 1 told station 2's old key
if out=$(check_config "$d/station-1.toml"); then fail "station 1 with station 2's revoked key passed --check-config"; fi
echo "$out" | grep -qF "net.peers[0].public_key = \"$old2\"" || { echo "$out"; fail "the refusal does not name net.peers[0].public_key as written"; }
echo "ok: revoked in the lab file, rotated, old keys refused by name (station 2: $old2)"
