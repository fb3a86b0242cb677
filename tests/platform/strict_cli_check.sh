#!/usr/bin/env bash
# Every program we ship answers the command line strictly, from an install into a temporary prefix:
#   version:  every file in P/bin prints `NAME VERSION (git DESCRIBE, build ID; ...)` for --version,
#             exit 0, all with the same git describe and build id (one implementation, platform/version.hpp);
#   strict:   a negative or out-of-range number is refused (exit 2, or haptic-devices' 2) naming the
#             option; an unknown option or subcommand is named with "did you mean" the nearest one;
#             haptic-keygen never creates a file named like an option; haptic-lab plan refuses a
#             disconnected topology before writing anything (no run folder, not even --run-dir's).
# Nothing here runs a station or sends a packet (parse and plan errors only; ~10 s).
# Usage: strict_cli_check.sh BUILD_DIR version|strict
set -uo pipefail
build="$1"; mode="$2"
work="$(mktemp -d /tmp/haptic-cli-check.XXXXXX)"
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log" || { cat "$work/install.log"; echo "FAIL: cmake --install"; exit 1; }
bin="$work/prefix/bin"
export PATH="$bin:/usr/bin:/bin"
fail=0
bad() { echo "FAILED $*"; fail=1; }

if [ "$mode" = version ]; then
  ids=()
  for p in "$bin"/*; do
    name=$(basename "$p")
    out=$("$p" --version 2>&1); rc=$?
    line=$(printf '%s\n' "$out" | head -1)
    if [ "$rc" -ne 0 ] || ! [[ "$line" =~ ^$name\ [0-9]+\.[0-9]+\.[0-9]+\ \(git\ ([^,]+),\ build\ ([0-9a-f]{12})\; ]]; then
      bad "$name --version: exit $rc: $out"
      continue
    fi
    ids+=("${BASH_REMATCH[1]} ${BASH_REMATCH[2]}")
    echo "ok $line"
  done
  [ "${#ids[@]}" -ge 7 ] || bad "only ${#ids[@]} programs in $bin answered --version"
  [ "$(printf '%s\n' "${ids[@]}" | sort -u | wc -l)" -le 1 ] || bad "the programs disagree on git describe / build id: $(printf '%s; ' "${ids[@]}" | sort -u)"
  exit $fail
fi

expect() {  # expect NAME WANT_RC REGEX -- command...   (the regex is matched against stdout+stderr)
  local name="$1" want="$2" re="$3"; shift 4
  "$@" >"$work/$name.log" 2>&1; local rc=$?
  if [ "$rc" -ne "$want" ]; then bad "$name: exit $rc, expected $want: $*"; cat "$work/$name.log"; return; fi
  if ! grep -Eq -- "$re" "$work/$name.log"; then bad "$name: no /$re/ in:"; cat "$work/$name.log"; return; fi
  echo "ok $name: exit $rc, $(grep -Eo -- "$re" "$work/$name.log" | head -1)"
}
cd "$work"
sim=(haptic-station sim --scenario paper-best --out "$work/sim" --no-plots --quiet)
expect sim_duration_negative 2 "haptic-station sim: error: --duration: Value -5 must be > 0" -- "${sim[@]}" --duration -5
expect sim_duration_zero 2 "--duration: Value 0 must be > 0" -- "${sim[@]}" --duration 0
expect sim_seed_negative 2 "--seed: Value -1 must be >= 0" -- "${sim[@]}" --seed -1
expect sim_push_seed_negative 2 "--push-seed: Value -1 must be >= 0" -- "${sim[@]}" --push-seed -1
expect sim_jitter_sentinel 2 "--jitter: Value -1 not in range" -- "${sim[@]}" --jitter -1
expect sim_node_mass_negative 2 "--node-mass-kg: Value -1 must be > 0" -- "${sim[@]}" --node-mass-kg -1
expect sim_trace_node_negative 2 "--trace-node: Value -5 must be >= 0" -- "${sim[@]}" --trace-node -5
expect sim_edge_bound_sentinel 2 "--edge-energy-bound: Value -1 must be >= 0" -- "${sim[@]}" --edge-energy-bound -1
expect sim_push_end_before_start 2 "--push-end \(0\.500000 s\) must lie after the push start" -- "${sim[@]}" --push-end 0.5 --release 1
expect sim_view_station_zero 2 "--view-station: Value 0 not in range" -- "${sim[@]}" --view-station 0
expect sim_unknown_option 2 "unknown option --scenaro \(did you mean --scenario\?\)" -- haptic-station sim --scenaro paper-best --out "$work/sim"
expect station_unknown_subcommand 2 "unknown subcommand simm \(did you mean sim\?\)" -- haptic-station simm
expect run_unknown_option 2 "unknown option --chek-config \(did you mean --check-config\?\)" -- haptic-station run --config x.toml --chek-config
[ ! -e "$work/sim" ] || bad "a refused sim wrote $work/sim"
key=5f0c9e1a77d24b3c8e6f0a19d2b4c6e8a1f3b5d7092c4e6a8b0d2f4a6c8e0b1d
printf '[station]\nid = 2\nduration_s = 1\nout_dir = "%s"\n[device]\nkind = "simulated"\n[net]\nbind = "127.0.0.1:50990"\nshared_session_key = "%s"\n[[net.peers]]\nid = 1\naddress = "127.0.0.1:50991"\n' \
  "$work/out" "$key" >"$work/station.toml"
expect run_check_ok 0 "config ok: station 2" -- haptic-station run --config "$work/station.toml" --check-config
expect run_duration_negative 2 "--duration: Value -5 must be > 0" -- haptic-station run --config "$work/station.toml" --duration -5 --check-config
expect run_start_at_negative 2 "--start-at: Value -5 must be >= 0" -- haptic-station run --config "$work/station.toml" --start-at -5 --check-config
sed 's/^bind = "127.0.0.1:/bind = "198.51.100.7:/' "$work/station.toml" >"$work/foreign-bind.toml"
expect run_bind_not_owned 2 "net\.bind = \"198\.51\.100\.7:50990\" is not an address of this machine" -- haptic-station run --config "$work/foreign-bind.toml" --check-config

expect topology_seed_negative 2 "--seed: Value -1 must be >= 0" -- haptic-topology --users 4 --seed -1
expect topology_users_negative 2 "haptic-topology: error: --users: Value -5 not in range" -- haptic-topology --users -5
expect topology_unknown_option 2 "unknown option --delayz \(did you mean --delays\?\)" -- haptic-topology --delayz "0,4;8,0"
expect devices_unknown_option 2 "unknown option --al \(did you mean --all\?\)" -- haptic-devices --al
expect devices_unknown_subcommand 2 "unknown subcommand diagg \(did you mean diag\?\)" -- haptic-devices diagg
expect devices_unknown_sub_option 2 "unknown option --forse-N \(did you mean --force-N\?\)" -- haptic-devices diag --forse-N 0.2
expect jitter_loops_negative 2 "--loops: Value -1 must be >= 0" -- haptic-jitter --loops -1
expect jitter_unknown_option 2 "unknown option --overun-every \(did you mean --overrun-every\?\)" -- haptic-jitter --overun-every 3
expect study_unknown_subcommand 2 "unknown subcommand accurcy \(did you mean accuracy\?\)" -- haptic-study accurcy
expect study_duration_negative 2 "--duration: Value -1 must be > 0" -- haptic-study energy --duration -1
expect keygen_unknown_option 2 "unknown option --verison \(did you mean --version\?\)" -- haptic-keygen --verison
[ ! -e "$work/--verison" ] || bad "haptic-keygen created a key file named --verison"
expect lab_unknown_subcommand 2 "invalid choice: 'plna'.*did you mean plan\?" -- haptic-lab plna
expect lab_unknown_option 2 "--runs-dirr: did you mean --runs-dir\?" -- haptic-lab plan lab.toml --runs-dirr x
expect lab_timeout_negative 2 "argument --timeout: -5 must be > 0 s" -- haptic-lab run lab.toml --timeout -5

printf '[lab]\nusers = 4\n[topology]\nlinks = "1-2,3-4"\n' >"$work/split.toml"
expect lab_plan_disconnected 2 "topology\.links = '1-2,3-4': .*must connect all users.*no link path from user 1 reaches users 3, 4" -- \
  haptic-lab plan "$work/split.toml" --runs-dir "$work/runs"
[ ! -e "$work/runs" ] || bad "the refused plan left $(ls -A "$work/runs" | wc -l) entries in $work/runs"
expect lab_plan_disconnected_run_dir 2 "must connect all users" -- haptic-lab plan "$work/split.toml" --run-dir "$work/exact"
[ ! -e "$work/exact" ] || bad "the refused plan created --run-dir $work/exact"
exit $fail
