#!/usr/bin/env bash
# The `haptic-station run` command line tells the truth: --help lists the exit codes,
# --check-config exits 2 naming the key as written in the file, and a station whose neighbour
# never answers exits 7 saying so (UDP on 127.0.0.1, a private port; ~1 s).
set -uo pipefail
bin="$1"; out="$2"
rm -rf "$out"; mkdir -p "$out"
fail=0
port=$(( 50950 + ($$ % 40) ))
key=5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d
write() {  # write FILE PEER_ID EXTRA_NET
  printf '[station]\nid = 2\nprobe_s = 0.3\nsetup_gap_s = 0.1\nstart_delay_s = 0.2\nduration_s = 1\nio_priority = 0\nout_dir = "%s"\n[device]\nkind = "simulated"\n[rt]\nlock_memory = false\n[net]\nbind = "127.0.0.1:%d"\nshared_session_key = "%s"\n%s[[net.peers]]\nid = %d\naddress = "127.0.0.1:%d"\n' \
    "$out" "$port" "$key" "$3" "$2" "$((port + 1))" > "$1"
}
expect() {  # expect NAME WANT_RC REGEX -- command...
  local name="$1" want="$2" re="$3"; shift 4
  "$@" > "$out/$name.log" 2>&1; local rc=$?
  if [ "$rc" -ne "$want" ]; then echo "FAILED $name: exit $rc, expected $want"; cat "$out/$name.log"; fail=1; return; fi
  if ! grep -Eq "$re" "$out/$name.log"; then echo "FAILED $name: no /$re/ in:"; cat "$out/$name.log"; fail=1; return; fi
  echo "ok $name: exit $rc, $(grep -Eo "$re" "$out/$name.log" | head -1)"
}
expect help 0 "7 no neighbour" -- "$bin" run --help
expect top_help 0 "4 diverged; 5 safe state latched" -- "$bin" --help
write "$out/not-neighbour.toml" 3 ""
expect not_neighbour 2 "net\.peers\[0\]\.id = 3 is not a neighbour" -- "$bin" run --config "$out/not-neighbour.toml" --check-config
write "$out/spin.toml" 1 $'tx_spin = true\ntx_spin_lead_us = 2500\n'
expect tx_spin 2 "net\.tx_spin_lead_us = 2500" -- "$bin" run --config "$out/spin.toml" --check-config
write "$out/alone.toml" 1 ""
expect check_ok 0 "config ok: station 2" -- "$bin" run --config "$out/alone.toml" --check-config
expect usage 2 "required" -- "$bin" run
expect alone 7 "no neighbour answered" -- "$bin" run --config "$out/alone.toml"
exit $fail
