#!/usr/bin/env bash
# One-way latency over raw Ethernet (AF_PACKET), our stack against a minimal raw-socket pair
# (bench_net's BM_OneWayPeriodicRaw): makes a network namespace of its own holding seven veth
# pairs (<prefix>0a/<prefix>0b .. <prefix>6a/<prefix>6b: pair 0 for the minimal pair, 1-6 for the
# stack's endpoints), runs bench_net inside it, and removes the namespace (also on failure).
# Traffic stays inside the namespace. Needs root (ip netns, CAP_NET_RAW); exits 77 without it.
#   tools/bench/raw_oneway.sh build/bin/bench_net [bench_net options ...]
# e.g. --benchmark_repetitions=5 --benchmark_out=tools/bench/results/net_oneway_raw.json --benchmark_out_format=json
set -euo pipefail
bench=${1:?usage: raw_oneway.sh BENCH_NET [options]}
shift
if [[ $(id -u) -ne 0 ]] || ! command -v ip >/dev/null; then
  echo "raw_oneway.sh: needs root and iproute2 (ip netns) for raw sockets in a namespace" >&2
  exit 77
fi
ns=hpnraw$$
prefix=hr
ip netns add "$ns"
trap 'ip netns del "$ns" 2>/dev/null || true' EXIT
ip -n "$ns" link set lo up
for i in 0 1 2 3 4 5 6; do
  ip -n "$ns" link add "${prefix}${i}a" type veth peer name "${prefix}${i}b"
  ip -n "$ns" link set "${prefix}${i}a" up
  ip -n "$ns" link set "${prefix}${i}b" up
done
ip netns exec "$ns" env NET_BENCH_RAW_PREFIX=$prefix "$bench" --benchmark_filter=OneWayPeriodicRaw "$@"
