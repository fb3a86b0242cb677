#!/usr/bin/env bash
# Captures a short state exchange on loopback (haptic-net-demo) and decodes it with tshark and
# tools/wireshark/hapn.lua; checks that every datagram is recognised with the right fields.
# Usage: test_dissector.sh DEMO_BINARY [WORK_DIR]. Needs tshark and capture rights (root).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
demo="$1"
work="${2:-$(mktemp -d /tmp/hapn-tshark.XXXXXX)}"
mkdir -p "$work"
if ! command -v tshark >/dev/null; then
  echo "test_dissector.sh: tshark is not installed (apt install tshark)" >&2; exit 1
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "test_dissector.sh: capturing on lo needs root (or wireshark group capabilities)" >&2; exit 1
fi
pa=47311; pb=47312
pcap="$work/hapn.pcapng"
rm -f "$pcap" "$work/tshark.err"
# Bounded capture: stops by itself after 20 s at the latest; we stop it earlier by its pid.
tshark -i lo -f "udp port $pa or udp port $pb" -a duration:20 -w "$pcap" 2>"$work/tshark.err" &
tpid=$!
for _ in $(seq 1 100); do grep -q "Capturing on" "$work/tshark.err" 2>/dev/null && break; sleep 0.1; done
"$demo" --port-a $pa --port-b $pb --packets 10 --nodes 33
"$demo" --port-a $pa --port-b $pb --packets 5 --nodes 33 --float32
sleep 1
kill -INT "$tpid" 2>/dev/null || true
wait "$tpid" || true
# 10 float64 packets x 2 datagrams + 5 float32 packets x 1 datagram, each direction.
fields=$(tshark -r "$pcap" -X lua_script:"$here/hapn.lua" -Y hapn -T fields -E separator=, \
  -e hapn.version -e hapn.sender -e hapn.dest -e hapn.seq -e hapn.frag_index -e hapn.frag_count \
  -e hapn.flags.float32 -e hapn.value_count -e hapn.session)
total=$(echo "$fields" | grep -c . || true)
f64=$(echo "$fields" | awk -F, '$7=="False" || $7=="0"' | grep -c . || true)
f32=$(echo "$fields" | awk -F, '$7=="True" || $7=="1"' | grep -c . || true)
bad=$(echo "$fields" | awk -F, '$1!="2" || $8!="99" || $9!="0x0000de30"' | grep -c . || true)
echo "tshark decoded $total HAPN datagrams ($f64 float64, $f32 float32), $bad with unexpected fields"
echo "$fields" | head -4
[ "$total" -eq 50 ] && [ "$f64" -eq 40 ] && [ "$f32" -eq 10 ] && [ "$bad" -eq 0 ]
