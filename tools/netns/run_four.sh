#!/usr/bin/env bash
# Four stations' network layers as four processes (build/bin/haptic-net-peer), the paper's
# star topology 1-2,1-3,1-4 (0-based 0-1,0-2,0-3) with the paper's per-link mean delays and
# impairment preset in each sender, for a bounded time. Modes:
#   udp     : UDP on 127.0.0.1 (no namespaces, no root)
#   raw     : raw Ethernet (EtherType 0x88B5) between the four namespaces of netns.sh (root)
#   udp-ns  : UDP over the namespaces' bridge, 10.77.0.x (root)
# Usage: run_four.sh MODE PEER_BIN [SECONDS] [WORKDIR] [PRESET]
# Writes WORKDIR/station-i.toml and station-i.json; exit 0 when all four processes succeed.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
mode="$1"; bin="$2"; secs="${3:-5}"; work="${4:-$(mktemp -d /tmp/hpn-four.XXXXXX)}"; preset="${5:-paper}"
mkdir -p "$work"
export HPN_PREFIX="${HPN_PREFIX:-hpn}"
# Per-station key pairs (net.key_file, 0600) from haptic-keygen next to PEER_BIN; each file lists
# its neighbours' public keys (pairwise traffic keys, agreed per run).
keygen="$(dirname "$bin")/haptic-keygen"
[ -x "$keygen" ] || { echo "run_four.sh: $keygen not found (build the haptic-keygen target)" >&2; exit 2; }
(umask 077; mkdir -p "$work/keys"); chmod 700 "$work/keys"
declare -A pub
for i in 0 1 2 3; do
  rm -f "$work/keys/station-$i.key"
  pub[$i]=$("$keygen" "$work/keys/station-$i.key" | awk '{print $2}')
done
session=$(( ($(date +%s) ^ $$) & 0x7fffffff ))
# Mean one-way delay (ms), row i receives from column j (DESIGN.md / paper Section V).
D=( "0 4 4 4" "8 0 80 200" "4 100 0 200" "6 240 200 0" )
delay() { local row=(${D[$1]}); echo "${row[$2]}"; }
peers_of() { if [ "$1" -eq 0 ]; then echo "1 2 3"; else echo "0"; fi; }
mac() { printf '02:48:50:00:00:%02x' $(( $1 + 1 )); }

case "$mode" in
  udp) ;;
  raw|udp-ns)
    if [ "$(id -u)" -ne 0 ]; then echo "run_four.sh: mode $mode needs root (namespaces, AF_PACKET)" >&2; exit 1; fi
    "$here/netns.sh" up >/dev/null ;;
  *) echo "usage: $0 udp|raw|udp-ns PEER_BIN [SECONDS] [WORKDIR] [PRESET]" >&2; exit 2 ;;
esac
cleanup() { if [ "$mode" != udp ]; then "$here/netns.sh" down >/dev/null || true; fi; }
trap cleanup EXIT

for i in 0 1 2 3; do
  f="$work/station-$i.toml"
  {
    echo "[net]"
    echo "station_id = $i"
    echo "session_id = $session"
    echo "key_file = \"keys/station-$i.key\""
    case "$mode" in
      udp) echo "transport = \"udp\""; echo "bind = \"127.0.0.1:$((47100 + i))\"" ;;
      udp-ns) echo "transport = \"udp\""; echo "bind = \"10.77.0.$((i + 1)):7000\"" ;;
      raw) echo "transport = \"raw\""; echo "interface = \"hpn0\"" ;;
    esac
    echo "[net.impairment]"
    echo "preset = \"$preset\""
    echo "seed = 1"
    for j in $(peers_of "$i"); do
      echo "[[net.peers]]"
      echo "id = $j"
      echo "mean_delay_ms = $(delay "$j" "$i")"   # link i -> j: row j receives from column i
      echo "public_key = \"${pub[$j]}\""
      case "$mode" in
        udp) echo "address = \"127.0.0.1:$((47100 + j))\"" ;;
        udp-ns) echo "address = \"10.77.0.$((j + 1)):7000\"" ;;
        raw) echo "mac = \"$(mac "$j")\"" ;;
      esac
    done
  } > "$f"
done

pids=()
for i in 0 1 2 3; do
  cmd=("$bin" --config "$work/station-$i.toml" --seconds "$secs" --probe-s 1)
  if [ "$mode" != udp ]; then cmd=(ip netns exec "$HPN_PREFIX-st$i" "${cmd[@]}"); fi
  "${cmd[@]}" > "$work/station-$i.json" 2> "$work/station-$i.err" &
  pids+=($!)
done
rc=0
for i in 0 1 2 3; do
  if ! wait "${pids[$i]}"; then echo "station $i failed: $(cat "$work/station-$i.err")" >&2; rc=1; fi
done
for i in 0 1 2 3; do cat "$work/station-$i.json"; done
echo "run_four.sh: mode $mode, preset $preset, ${secs}s, outputs in $work: $([ $rc -eq 0 ] && echo OK || echo FAILED)"
exit $rc
