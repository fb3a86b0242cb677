#!/usr/bin/env bash
# The paper's four stations as four `haptic-station run` processes, in real time, simulated users,
# the paper's impairment preset in every sender, then one merged summary.json/trace.csv/series.csv
# (the simulator's contract and metrics, `haptic-station merge`) and the simulator's figures.
# A thin case of haptic-lab (tools/lab): it writes a four-station lab file from these options and
# runs `haptic-lab plan --run-dir OUT`, `start`, `collect`; station files, keys, free ports,
# namespaces, progress and bounds are haptic-lab's.
#   --transport udp : UDP on 127.0.0.1 (no root needed)
#   --transport raw : AF_PACKET raw Ethernet (EtherType 0x88B5) between four network namespaces
#                     joined by veth pairs and a bridge (made and removed by haptic-lab; root)
# Usage: run4.sh [--transport udp|raw] [--bin PATH] [--out DIR] [--scenario NAME] [--duration S]
#                [--push-end S] [--release S] [--seed N] [--probe S] [--preset paper|none|bursty]
#                [--nodes N] [--state-every K] [--no-plots] [--rt-priority P]
#                [--net KEY=VALUE]...   (extra [net] keys in every station, TOML values: e.g.
#                                        --net tx_spin=true --net 'encoding="float64"')
#                [--station KEY=VALUE]... (extra [station] keys, e.g. --station max_no_neighbour_fraction=0.5)
#                [--device KEY=VALUE]... (extra [device] keys, e.g. --device ramp_in_s=1)
#                [--view-port P]         (live web view: station i serves it on port P + i - 1, 127.0.0.1)
#                [--kill I:KILL_S:RESTART_S] (SIGKILL station I at run time KILL_S, restart it with the
#                                        same configuration at RESTART_S: it rejoins; its first log is
#                                        station-I.log, the restarted one's station-I-restart.log; no
#                                        merge, tools/run4/rejoin_check.py checks the run instead)
#                [--restart-fresh-epoch] (with --kill: restart WITHOUT --start-at, so the restarted
#                                        station plans a fresh future epoch from station.start_delay_s
#                                        and must find out from its neighbours' packets that the
#                                        session already runs)
# OUT (default: a new /tmp/run4.XXXXXX) may exist but must not hold an earlier run. UDP ports are
# free ones the kernel gives haptic-lab. Exit 0 when all four stations finished and the merge
# succeeded; 1 a station or the merge failed; 2 bad options; 77 raw without root. Bounded: every
# process is sent SIGTERM after its planned time + 20 s, SIGKILL 5 s later.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
transport=udp; bin="$repo/build/bin/haptic-station"; out=""; scenario=paper-best
duration=8; push_end=2.5; release=5; seed=1; probe=1.5; preset=paper
nodes=33; state_every=5; plots=1; prio=80; net_extra=(); station_extra=(); device_extra=(); kill_spec=""; fresh_epoch=0; view_port=0
while [ $# -gt 0 ]; do
  case "$1" in
    --transport) transport="$2"; shift 2 ;;
    --bin) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --scenario) scenario="$2"; shift 2 ;;
    --duration) duration="$2"; shift 2 ;;
    --push-end) push_end="$2"; shift 2 ;;
    --release) release="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --probe) probe="$2"; shift 2 ;;
    --preset) preset="$2"; shift 2 ;;
    --nodes) nodes="$2"; shift 2 ;;
    --state-every) state_every="$2"; shift 2 ;;
    --rt-priority) prio="$2"; shift 2 ;;
    --no-plots) plots=0; shift ;;
    --net) [[ "$2" == *=* ]] || { echo "run4.sh: --net needs KEY=VALUE, got '$2'" >&2; exit 2; }; net_extra+=("$2"); shift 2 ;;
    --view-port) view_port="$2"; shift 2 ;;
    --station) [[ "$2" == *=* ]] || { echo "run4.sh: --station needs KEY=VALUE, got '$2'" >&2; exit 2; }; station_extra+=("$2"); shift 2 ;;
    --device) [[ "$2" == *=* ]] || { echo "run4.sh: --device needs KEY=VALUE, got '$2'" >&2; exit 2; }; device_extra+=("$2"); shift 2 ;;
    --kill) [[ "$2" =~ ^[1-4]:[0-9.]+:[0-9.]+$ ]] || { echo "run4.sh: --kill needs I:KILL_S:RESTART_S (e.g. 2:5:8), got '$2'" >&2; exit 2; }
            kill_spec="$2"; shift 2 ;;
    --restart-fresh-epoch) fresh_epoch=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    *) echo "run4.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$bin" ] || { echo "run4.sh: $bin not found (build haptic-station, or pass --bin)" >&2; exit 2; }
[ "$(basename "$bin")" = haptic-station ] || { echo "run4.sh: --bin must name a haptic-station binary, got $bin" >&2; exit 2; }
case "$transport" in
  udp) ;;
  raw) if [ "$(id -u)" -ne 0 ]; then echo "run4.sh: --transport raw needs root (network namespaces, AF_PACKET)" >&2; exit 77; fi
       command -v ip >/dev/null || { echo "run4.sh: --transport raw needs ip (iproute2)" >&2; exit 77; } ;;
  *) echo "run4.sh: --transport must be udp or raw" >&2; exit 2 ;;
esac
[ -n "$out" ] || out="$(mktemp -d /tmp/run4.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
export HAPTIC_BIN_DIR="$(cd "$(dirname "$bin")" && pwd)"  # haptic-lab starts this haptic-station
lab_tool="$repo/tools/lab/haptic-lab"
lab_file="$(mktemp /tmp/run4-lab.XXXXXX.toml)"
trap 'rm -f "$lab_file"' EXIT
{
  echo "# tools/run4/run4.sh: four stations, $transport, seed $seed"
  echo "[lab]"
  echo "users = 4"
  echo "scenario = \"$scenario\""
  echo "nodes = $nodes"
  echo "duration_s = $duration"
  echo "push_end_s = $push_end"
  echo "release_s = $release"
  echo "seed = $seed"
  echo "probe_s = $probe"
  echo "start_delay_s = 2.0"
  [ "$view_port" -gt 0 ] && echo "view_port_base = $view_port"
  echo "[network]"
  echo "transport = \"$transport\""
  echo "impairment = \"$preset\"             # per directed link: mean from the scenario's delay matrix"
  echo "[topology]"
  echo "from_scenario = true   # the scenario's links (haptic-station scenario $scenario)"
  echo "[rt]"
  echo "priority = $prio"
  echo "lock_memory = true"
  echo "[station]"
  echo "state_every = $state_every"
  for kv in "${station_extra[@]}"; do echo "${kv%%=*} = ${kv#*=}"; done
  echo "[net]"
  for kv in "${net_extra[@]}"; do echo "${kv%%=*} = ${kv#*=}"; done
  if [ "${#device_extra[@]}" -gt 0 ]; then
    echo "[device]"
    for kv in "${device_extra[@]}"; do echo "${kv%%=*} = ${kv#*=}"; done
  fi
} > "$lab_file"
"$lab_tool" plan "$lab_file" --run-dir "$out" > "$out/plan.log" || { cat "$out/plan.log" >&2; exit 2; }
"$lab_tool" check "$out" > "$out/check.log" 2>&1 || { cat "$out/check.log" >&2; exit 1; }
echo "run4.sh: $transport, scenario $scenario, $duration s (push end $push_end s, release $release s), seed $seed, out $out"
start_args=()
[ -n "$kill_spec" ] && start_args+=(--kill "$kill_spec")
[ "$fresh_epoch" -eq 1 ] && start_args+=(--restart-fresh-epoch)
rc=0
"$lab_tool" start "$out" "${start_args[@]}" || rc=$?
logs=("$out"/station-[1-4].log)
if [ -n "$kill_spec" ]; then logs[$((${kill_spec%%:*} - 1))]="$out/station-${kill_spec%%:*}-restart.log"; fi
for l in "${logs[@]}"; do tail -n 1 "$l"; done
[ "$rc" -eq 0 ] || { for l in "${logs[@]}"; do echo "--- $l"; tail -n 20 "$l"; done >&2; exit 1; }
if [ -n "$kill_spec" ]; then exit 0; fi  # a rejoin run: tools/run4/rejoin_check.py checks it
collect_args=()
[ "$plots" -eq 1 ] || collect_args+=(--no-plots)
"$lab_tool" collect "$out" "${collect_args[@]}" || exit 1
