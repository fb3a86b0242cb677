#!/usr/bin/env bash
# N station network namespaces (HPN_STATIONS, default 4, at most 200) joined by veth pairs to one
# bridge (in its own namespace, so nothing touches the host's interfaces or addresses).
#
#   hpn-st0 [hpn0 02:48:50:00:00:01 10.77.0.1 fd77::1] --veth-- hpn-p0 \
#   hpn-st1 [hpn0 02:48:50:00:00:02 10.77.0.2 fd77::2] --veth-- hpn-p1  > br0 in hpn-sw
#   hpn-st2 [hpn0 02:48:50:00:00:03 10.77.0.3 fd77::3] --veth-- hpn-p2 /
#   hpn-st3 [hpn0 02:48:50:00:00:04 10.77.0.4 fd77::4] --veth-- hpn-p3
#   ...     (station i, 0-based: MAC 02:48:50:00:00:<i+1 in hex>, 10.77.0.<i+1>, fd77::<i+1>)
#
# Every station's interface is "hpn0" (net.interface = "hpn0" for transport = "raw"); UDP
# configs use 10.77.0.x:7000 or [fd77::x]:7000. Needs root and iproute2.
# HPN_PREFIX (default hpn) names the namespaces, so several sets can exist at once.
# Usage: netns.sh up | down | status | check | exec STATION CMD...
set -euo pipefail
N="${HPN_STATIONS:-4}"
[[ "$N" =~ ^[0-9]+$ ]] && [ "$N" -ge 2 ] && [ "$N" -le 200 ] || { echo "netns.sh: HPN_STATIONS=$N must be 2..200" >&2; exit 2; }
P="${HPN_PREFIX:-hpn}"
SW="$P-sw"
ns() { echo "$P-st$1"; }
mac() { printf '02:48:50:00:00:%02x' $(( $1 + 1 )); }

need_root() {
  if [ "$(id -u)" -ne 0 ]; then echo "netns.sh: needs root (ip netns, veth, bridge)" >&2; exit 1; fi
  command -v ip >/dev/null || { echo "netns.sh: ip (iproute2) not found" >&2; exit 1; }
}

down() {
  for i in $(seq 0 $((N - 1))); do ip netns del "$(ns "$i")" 2>/dev/null || true; done
  ip netns del "$SW" 2>/dev/null || true
}

up() {
  down
  ip netns add "$SW"
  ip -n "$SW" link add br0 type bridge
  ip -n "$SW" link set br0 up
  ip -n "$SW" link set lo up
  for i in $(seq 0 $((N - 1))); do
    local s; s="$(ns "$i")"
    ip netns add "$s"
    ip link add hpn0 netns "$s" type veth peer name "hpn-p$i" netns "$SW"
    ip -n "$s" link set hpn0 address "$(mac "$i")"
    ip -n "$s" link set lo up
    ip -n "$s" addr add "10.77.0.$((i + 1))/24" dev hpn0
    ip -n "$s" addr add "fd77::$((i + 1))/64" dev hpn0 nodad
    ip -n "$s" link set hpn0 up
    ip -n "$SW" link set "hpn-p$i" master br0
    ip -n "$SW" link set "hpn-p$i" up
  done
  echo "netns.sh: up: $(for i in $(seq 0 $((N - 1))); do printf '%s ' "$(ns "$i")"; done)+ $SW (bridge br0)"
}

status() {
  for i in $(seq 0 $((N - 1))); do
    local s; s="$(ns "$i")"
    if ip netns list | grep -qw "$s"; then
      echo "$s: $(ip -n "$s" -br link show hpn0 2>/dev/null | tr -s ' ') $(ip -n "$s" -br addr show hpn0 2>/dev/null | awk '{print $3, $4}')"
    else
      echo "$s: absent"
    fi
  done
}

# Every station reaches every other over the bridge (IPv4 and IPv6); bounded (1 ping, 2 s).
check() {
  local fail=0
  for i in $(seq 0 $((N - 1))); do
    for j in $(seq 0 $((N - 1))); do
      [ "$i" -eq "$j" ] && continue
      ip netns exec "$(ns "$i")" ping -c1 -W2 -q "10.77.0.$((j + 1))" >/dev/null || { echo "no IPv4 path st$i -> st$j"; fail=1; }
      ip netns exec "$(ns "$i")" ping -6 -c1 -W2 -q "fd77::$((j + 1))" >/dev/null || { echo "no IPv6 path st$i -> st$j"; fail=1; }
    done
  done
  [ "$fail" -eq 0 ] && echo "netns.sh: all $((N * (N - 1))) directed paths up (IPv4 and IPv6)"
  return "$fail"
}

cmd="${1:-}"
case "$cmd" in
  up) need_root; up ;;
  down) need_root; down; echo "netns.sh: down" ;;
  status) status ;;
  check) need_root; check ;;
  exec) need_root; shift; i="$1"; shift; exec ip netns exec "$(ns "$i")" "$@" ;;
  *) echo "usage: $0 up | down | status | check | exec STATION CMD..." >&2; exit 2 ;;
esac
