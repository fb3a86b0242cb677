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
pa=47311; pb=47312; pw=47313
pcap="$work/hapn.pcapng"
rm -f "$pcap" "$work/tshark.err" "$work/tshark.out"
# Bounded capture: stops by itself after 40 s at the latest; we stop it earlier by its pid. -P prints
# each packet as it is written, so we can see when packets really start being captured: "Capturing on"
# comes out before the capture filter is active on a loaded machine (CI missed the first 16 datagrams).
tshark -i lo -f "udp port $pa or udp port $pb or udp port $pw" -a duration:40 -w "$pcap" \
  -P -l -T fields -e udp.dstport >"$work/tshark.out" 2>"$work/tshark.err" &
tpid=$!
# Warm-up: a non-HAPN datagram to port $pw every 0.1 s until tshark shows one (at most 20 s).
seen=0
for _ in $(seq 1 200); do
  echo warmup >/dev/udp/127.0.0.1/$pw 2>/dev/null || true
  if grep -q "^$pw\$" "$work/tshark.out" 2>/dev/null; then seen=1; break; fi
  sleep 0.1
done
if [ "$seen" -ne 1 ]; then
  echo "test_dissector.sh: tshark captured nothing on lo within 20 s; its stderr:" >&2
  cat "$work/tshark.err" >&2; kill -INT "$tpid" 2>/dev/null || true; wait "$tpid" || true; exit 1
fi
"$demo" --port-a $pa --port-b $pb --packets 10 --nodes 33
"$demo" --port-a $pa --port-b $pb --packets 5 --nodes 33 --float32
# Wait (at most 10 s) until tshark has written all 50 demo datagrams, then stop it.
for _ in $(seq 1 100); do
  [ "$(grep -c -E "^($pa|$pb)\$" "$work/tshark.out" || true)" -ge 50 ] && break
  sleep 0.1
done
kill -INT "$tpid" 2>/dev/null || true
wait "$tpid" || true
# 10 float64 packets x 2 datagrams + 5 float32 packets x 1 datagram, each direction.
fields=$(tshark -r "$pcap" -X lua_script:"$here/hapn.lua" -Y hapn -T fields -E separator=, \
  -e hapn.version -e hapn.sender -e hapn.dest -e hapn.seq -e hapn.frag_index -e hapn.frag_count \
  -e hapn.flags.float32 -e hapn.value_count -e hapn.session)
total=$(echo "$fields" | grep -c . || true)
f64=$(echo "$fields" | awk -F, '$7=="False" || $7=="0"' | grep -c . || true)
f32=$(echo "$fields" | awk -F, '$7=="True" || $7=="1"' | grep -c . || true)
bad=$(echo "$fields" | awk -F, '$1!="3" || $8!="99" || $9!="0x0000de30"' | grep -c . || true)
echo "tshark decoded $total HAPN datagrams ($f64 float64, $f32 float32), $bad with unexpected fields"
echo "$fields" | head -4
[ "$total" -eq 50 ] && [ "$f64" -eq 40 ] && [ "$f32" -eq 10 ] && [ "$bad" -eq 0 ]
