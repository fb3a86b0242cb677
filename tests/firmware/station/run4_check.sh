#!/usr/bin/env bash
# Short four-process run (tools/run4/run4.sh) with the options the lab configurations ship
# (firmware/deploy/lab-4-stations: net.tx_direct = true, net.io_cpu = 0) and checks on the merged summary.json:
# not diverged, passivity condition (18) met with the measured bounds, consensus reached after
# the release, packets flowed on every directed link. Exit 77 (CTest: skipped) with the reason
# when the raw-Ethernet run cannot be done here (needs root and `ip netns`). Under run4.sh's emulated impairment the pushes take the I/O
# thread's path (direct TX declines an impaired link: io_thread.tx_direct_declined); the shipped lab
# run, station_device_documented_lab, has the tick send every push itself.
set -euo pipefail
mode="$1"; bin="$2"; out="$3"
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
if [ "$mode" = raw ]; then
  if [ "$(id -u)" -ne 0 ]; then echo "SKIPPED: raw-Ethernet run needs root (network namespaces, AF_PACKET)"; exit 77; fi
  if ! command -v ip >/dev/null || ! ip netns list >/dev/null 2>&1; then echo "SKIPPED: 'ip netns' (iproute2) is not available"; exit 77; fi
fi
[ -x /usr/bin/python3 ] || { echo "SKIPPED: /usr/bin/python3 missing for the checks"; exit 77; }
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$(dirname "$bin")" "$out"
rm -rf "$out"; mkdir -p "$out"
"$repo/tools/run4/run4.sh" --transport "$mode" --bin "$bin" --out "$out" --duration 4 --push-end 1.5 --release 2.5 \
  --probe 1.0 --seed 3 --no-plots --net tx_direct=true --net io_cpu=0
/usr/bin/python3 - "$out/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
fail = []
if s["diverged"]: fail.append("diverged")
if not s["passivity_condition_met"]:
    fail.append("passivity condition (18) not met: B %s vs min %s, bounds consistent on all links: %s" % (
        s["damping_Ns_per_m"], s["damping_min_Ns_per_m"], s["bounds_consistent_all_links"]))
if s["consensus_time_s"] is None: fail.append("no consensus after the release (final error %.3g mm)" % (1e3 * s["consensus_error_m"]))
if not s["consensus_error_m"] < 1e-3: fail.append("final consensus error %.3g mm >= 1 mm" % (1e3 * s["consensus_error_m"]))
if s["packets"]["delivered"] <= 0: fail.append("no packets delivered")
for l in s["link_stats"]:
    if l["delivered"] < 0.5 * l["sent"] or l["sent"] < 500:
        fail.append("link %d<-%d: sent %d delivered %d" % (l["to"], l["from"], l["sent"], l["delivered"]))
if not s["port_energy_min_J"] >= -s["passivity_bound_J"] - 1e-9:
    fail.append("port energy %.3g J below the bound -%.3g J" % (s["port_energy_min_J"], s["passivity_bound_J"]))
print("run4 check: consensus time %s s, final error %.4f mm, B %s (min %s), packets %s" % (
    s["consensus_time_s"], 1e3 * s["consensus_error_m"], [round(b, 2) for b in s["damping_Ns_per_m"]],
    [round(b, 2) for b in s["damping_min_Ns_per_m"]], s["packets"]))
if fail:
    print("FAILED: " + "; ".join(fail)); sys.exit(1)
PY
# The real run gets the simulator's figures (one summary/series/snapshots writer), checked alike.
if [ "$mode" = udp ] && /usr/bin/python3 -c 'import matplotlib' 2>/dev/null; then
  /usr/bin/python3 "$repo/tools/plots/check_figures.py" "$out"
fi
