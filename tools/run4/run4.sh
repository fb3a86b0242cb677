#!/usr/bin/env bash
# The paper's four stations as four `haptic-station run` processes, in real time, simulated users,
# the paper's impairment preset in every sender, then one merged summary.json/trace.csv/series.csv
# (the simulator's contract and metrics, `haptic-station merge`) and the simulator's figures.
#   --transport udp : UDP on 127.0.0.1 (no root needed)
#   --transport raw : AF_PACKET raw Ethernet (EtherType 0x88B5) between four network namespaces
#                     joined by veth pairs and a bridge (tools/netns/netns.sh, prefix hpr; root)
# Usage: run4.sh [--transport udp|raw] [--bin PATH] [--out DIR] [--scenario NAME] [--duration S]
#                [--push-end S] [--release S] [--seed N] [--probe S] [--preset paper|none|bursty]
#                [--port-base P] [--nodes N] [--state-every K] [--no-plots] [--rt-priority P]
#                [--net KEY=VALUE]...   (extra [net] keys in every station, TOML values: e.g.
#                                        --net tx_spin=true --net 'encoding="float64"')
#                [--station KEY=VALUE]... (extra [station] keys, e.g. --station max_no_neighbour_fraction=0.5)
#                [--view-port P]         (live web view: station i serves it on port P + i - 1, 127.0.0.1)
#                [--kill I:KILL_S:RESTART_S] (SIGKILL station I at run time KILL_S, restart it with the
#                                        same configuration at RESTART_S: it rejoins; its first log is
#                                        station-I.log, the restarted one's station-I-restart.log; no
#                                        merge, tools/run4/rejoin_check.py checks the run instead)
#                [--restart-fresh-epoch] (with --kill: restart WITHOUT --start-at, so the restarted
#                                        station plans a fresh future epoch from station.start_delay_s
#                                        and must find out from its neighbours' packets that the
#                                        session already runs)
# Exit 0 when all four stations finished and the merge succeeded. Bounded: every process is
# sent SIGTERM after its planned time + 15 s, SIGKILL 5 s later.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
transport=udp; bin="$repo/build/bin/haptic-station"; out=""; scenario=paper-best
duration=8; push_end=2.5; release=5; seed=1; probe=1.5; preset=paper; port_base=47210
nodes=33; state_every=5; plots=1; prio=80; net_extra=(); station_extra=(); kill_spec=""; fresh_epoch=0; view_port=0
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
    --port-base) port_base="$2"; shift 2 ;;
    --nodes) nodes="$2"; shift 2 ;;
    --state-every) state_every="$2"; shift 2 ;;
    --rt-priority) prio="$2"; shift 2 ;;
    --no-plots) plots=0; shift ;;
    --net) [[ "$2" == *=* ]] || { echo "run4.sh: --net needs KEY=VALUE, got '$2'" >&2; exit 2; }; net_extra+=("$2"); shift 2 ;;
    --view-port) view_port="$2"; shift 2 ;;
    --station) [[ "$2" == *=* ]] || { echo "run4.sh: --station needs KEY=VALUE, got '$2'" >&2; exit 2; }; station_extra+=("$2"); shift 2 ;;
    --kill) [[ "$2" =~ ^[1-4]:[0-9.]+:[0-9.]+$ ]] || { echo "run4.sh: --kill needs I:KILL_S:RESTART_S (e.g. 2:5:8), got '$2'" >&2; exit 2; }
            kill_spec="$2"; shift 2 ;;
    --restart-fresh-epoch) fresh_epoch=1; shift ;;
    -h|--help) sed -n 2,23p "$0"; exit 0 ;;
    *) echo "run4.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$bin" ] || { echo "run4.sh: $bin not found (build haptic-station, or pass --bin)" >&2; exit 2; }
[ -n "$out" ] || out="$(mktemp -d /tmp/run4.XXXXXX)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
export HPN_PREFIX=hpr
ns() { echo "hpr-st$1"; }

if [ "$transport" = raw ]; then
  if [ "$(id -u)" -ne 0 ]; then echo "run4.sh: --transport raw needs root (network namespaces, AF_PACKET)" >&2; exit 77; fi
  command -v ip >/dev/null || { echo "run4.sh: --transport raw needs ip (iproute2)" >&2; exit 77; }
  "$repo/tools/netns/netns.sh" up >/dev/null
elif [ "$transport" != udp ]; then
  echo "run4.sh: --transport must be udp or raw" >&2; exit 2
fi

pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  if [ "$transport" = raw ]; then "$repo/tools/netns/netns.sh" down >/dev/null 2>&1 || true; fi
}
trap cleanup EXIT
trap 'echo "run4.sh: interrupted, stopping the stations" >&2; for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done' INT TERM

key=$(od -An -N32 -tx1 /dev/urandom | tr -d ' \n')  # a fresh secret per run; station files are written 0600
session=$(( ($(date +%s%N) ^ $$) & 0x7fffffff ))
peers_of() {  # neighbours (1-based) of station $1 in the scenario's topology
  case "$scenario" in
    paper-worst) case "$1" in 1) echo 2;; 2) echo "1 4";; 3) echo 4;; 4) echo "2 3";; esac ;;
    *) if [ "$1" -eq 1 ]; then echo "2 3 4"; else echo 1; fi ;;
  esac
}
for i in 1 2 3 4; do
  f="$out/station-$i.toml"
  rm -f "$f"
  (umask 077; : > "$f")  # created private: never world-readable, not even briefly
  {
    echo "# generated by tools/run4/run4.sh ($transport, seed $seed)"
    echo "[station]"
    echo "id = $i"
    echo "scenario = \"$scenario\""
    echo "nodes = $nodes"
    echo "duration_s = $duration"
    echo "push_end_s = $push_end"
    echo "release_s = $release"
    echo "seed = $seed"
    echo "probe_s = $probe"
    echo "out_dir = \"$out\""
    echo "state_every = $state_every"
    for kv in "${station_extra[@]}"; do echo "${kv%%=*} = ${kv#*=}"; done
    if [ "$view_port" -gt 0 ]; then echo "view_port = $((view_port + i - 1))"; fi
    echo "[device]"
    echo "kind = \"simulated\""
    echo "sim_max_force_N = 50.0      # the simulator's user model has no output clamp"
    echo "max_power_W = 0             # nor a power cap"
    echo "[rt]"
    echo "priority = $prio"
    echo "lock_memory = true"
    echo "[net]"
    echo "session_id = $session"
    echo "session_key = \"$key\""
    echo "rtt_min_probe_samples = 20"
    for kv in "${net_extra[@]}"; do echo "${kv%%=*} = ${kv#*=}"; done
    if [ "$transport" = udp ]; then
      echo "transport = \"udp\""
      echo "bind = \"127.0.0.1:$((port_base + i))\""
    else
      echo "transport = \"raw\""
      echo "interface = \"hpn0\""
    fi
    echo "[net.impairment]"
    echo "preset = \"$preset\"             # per directed link: mean from the scenario's delay matrix"
    for j in $(peers_of "$i"); do
      echo "[[net.peers]]"
      echo "id = $j"
      if [ "$transport" = udp ]; then echo "address = \"127.0.0.1:$((port_base + j))\""
      else printf 'mac = "02:48:50:00:00:%02x"\n' "$j"; fi
    done
  } > "$f"
  chmod 600 "$f"  # it holds the session key
  "$bin" run --config "$f" --check-config >/dev/null
done

# Common epoch on CLOCK_MONOTONIC (all processes share it, namespaces included).
rm -f "$out/station-pids.txt"
start_at=$(/usr/bin/python3 -c 'import time; print("%.3f" % (time.monotonic() + 2.0))')
echo "run4.sh: $transport, scenario $scenario, $duration s (push end $push_end s, release $release s), seed $seed, epoch $start_at, out $out"
for i in 1 2 3 4; do
  cmd=("$bin" run --config "$out/station-$i.toml" --start-at "$start_at")
  if [ "$transport" = raw ]; then cmd=(ip netns exec "$(ns $((i - 1)))" "${cmd[@]}"); fi
  "${cmd[@]}" > "$out/station-$i.log" 2>&1 &
  pids+=($!)
  echo "$!" >> "$out/station-pids.txt"  # every station process this run started (trace filters use it)
done
if [ -n "$kill_spec" ]; then
  IFS=: read -r kill_i kill_s restart_s <<< "$kill_spec"
  run0=$(/usr/bin/python3 -c "print($start_at + $probe + 0.5)")  # run start (setup_gap_s default 0.5)
  sleep_to() { /usr/bin/python3 -c "import time; time.sleep(max(0.0, $1 - time.monotonic()))"; }
  sleep_to "$(/usr/bin/python3 -c "print($run0 + $kill_s)")"
  kill -KILL "${pids[$((kill_i - 1))]}" 2>/dev/null || true
  wait "${pids[$((kill_i - 1))]}" 2>/dev/null || true
  echo "run4.sh: SIGKILL station $kill_i at run time $kill_s s"
  sleep_to "$(/usr/bin/python3 -c "print($run0 + $restart_s)")"
  restart_mono=$(/usr/bin/python3 -c 'import time; print("%.6f" % time.monotonic())')
  cmd=("$bin" run --config "$out/station-$kill_i.toml" --start-at "$start_at")
  [ "$fresh_epoch" -eq 1 ] && cmd=("$bin" run --config "$out/station-$kill_i.toml")  # epoch = now + station.start_delay_s
  if [ "$transport" = raw ]; then cmd=(ip netns exec "$(ns $((kill_i - 1)))" "${cmd[@]}"); fi
  "${cmd[@]}" > "$out/station-$kill_i-restart.log" 2>&1 &
  pids[$((kill_i - 1))]=$!
  echo "$!" >> "$out/station-pids.txt"
  echo "{\"station\": $kill_i, \"kill_run_s\": $kill_s, \"restart_run_s\": $restart_s, \"restart_monotonic_s\": $restart_mono, \"run_start_monotonic_s\": $run0}" > "$out/restart.json"
  echo "run4.sh: restarted station $kill_i at run time $restart_s s"
fi
limit=$(/usr/bin/python3 -c "print(int(2.0 + $probe + 0.5 + $duration + 15))")
rc=0
for idx in 0 1 2 3; do
  p=${pids[$idx]}
  waited=0
  while kill -0 "$p" 2>/dev/null && [ "$waited" -lt $((limit * 10)) ]; do sleep 0.1; waited=$((waited + 1)); done
  if kill -0 "$p" 2>/dev/null; then
    echo "run4.sh: station $((idx + 1)) still running after ${limit} s: SIGTERM" >&2
    kill -TERM "$p" 2>/dev/null || true; sleep 5; kill -KILL "$p" 2>/dev/null || true
  fi
  if wait "$p"; then :; else s=$?; echo "run4.sh: station $((idx + 1)) exited with $s (log: $out/station-$((idx + 1)).log)" >&2; rc=1; fi
done
pids=()
logs=("$out/station-1.log" "$out/station-2.log" "$out/station-3.log" "$out/station-4.log")
[ -n "$kill_spec" ] && logs[$((kill_i - 1))]="$out/station-$kill_i-restart.log"
for l in "${logs[@]}"; do tail -n 1 "$l"; done
[ "$rc" -eq 0 ] || { for l in "${logs[@]}"; do echo "--- $l"; tail -n 20 "$l"; done >&2; exit 1; }
if [ -n "$kill_spec" ]; then exit 0; fi  # a rejoin run: tools/run4/rejoin_check.py checks it
"$bin" merge "$out"
if [ "$plots" -eq 1 ]; then
  /usr/bin/python3 "$repo/tools/plots/plot_run.py" "$out" && echo "run4.sh: figures in $out/*.png" || echo "run4.sh: figure script failed" >&2
fi
