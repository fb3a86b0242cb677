#!/usr/bin/env bash
# `haptic-station solo` (one station, one user, no network) tells the truth:
#   contact   the simulated device for 2 s (and, as a control, a still hand for 1 s: no contact): exit 0; station-1.json says the proxy touched the object
#             (contact_ticks > 0, device_force_max_N > 0, matched by a trace row with contact and a
#             force) and keeps the energy/passivity bookkeeping (port and controller energies, B_i and
#             eq. 18's minimum, both 0 with no neighbour, passivity condition met, users 1, transport none)
#   diverged  a divergence bound the hand exceeds: exit 4, said in station-1.json, and no force after it
#   view      with --view-port: the URL is printed, http://127.0.0.1:P/ serves the page (view.js); SIGTERM
#             ends the run with the same report (exit 0, stopped_by_signal)
#   errors    a bad option is named (--device, --nodes, an unknown one): exit 2; no device for
#             --device auto: exit 9 with the station's "no device" message
# (one process at a time, loopback only; ~10 s)
set -uo pipefail
bin="$1"; out="$2"
rm -rf "$out"; mkdir -p "$out"
fail=0
say_fail() { echo "FAILED $*"; fail=1; }
expect() {  # expect NAME WANT_RC REGEX -- command...
  local name="$1" want="$2" re="$3"; shift 4
  "$@" > "$out/$name.log" 2>&1; local rc=$?
  if [ "$rc" -ne "$want" ]; then say_fail "$name: exit $rc, expected $want"; cat "$out/$name.log"; return; fi
  if ! grep -Eq -- "$re" "$out/$name.log"; then say_fail "$name: no /$re/ in:"; cat "$out/$name.log"; return; fi
  echo "ok $name: exit $rc, $(grep -Eo -- "$re" "$out/$name.log" | head -1)"
}

# contact: the simulated user (the random script) touches the object by itself
expect contact 0 "haptic-station solo: done" -- "$bin" solo --device simulated --duration 2 --out "$out/contact"
/usr/bin/python3 - "$out/contact" <<'EOF' || fail=1
import csv, json, math, sys
d = sys.argv[1]
j = json.load(open(d + "/station-1.json"))
rows = list(csv.DictReader(open(d + "/station-1-trace.csv")))
touched = [r for r in rows if r["contact"] == "1" and math.hypot(float(r["force_x_N"]), float(r["force_y_N"]), float(r["force_z_N"])) > 0]
checks = [
    ("exit_code 0", j["exit_code"] == 0),
    ("users 1, transport none", j["users"] == 1 and j["transport"] == "none"),
    ("ticks ran", j["ticks_run"] > 500),
    ("contact_ticks > 0", j["contact_ticks"] > 0),
    ("device_force_max_N > 0", j["device_force_max_N"] is not None and j["device_force_max_N"] > 0),
    ("a trace row in contact with a force", len(touched) > 0),
    ("contact ticks counted as the trace shows them (trace_every 1)", j["contact_ticks"] == sum(r["contact"] == "1" for r in rows)),
    ("port/controller energies", all(isinstance(j[k], float) for k in ("port_energy_final_J", "controller_energy_final_J", "port_energy_min_J"))),
    ("eq. 18 with no neighbour: B_i = minimum = 0, condition met",
     j["damping_min_Ns_per_m"] == 0 and j["damping_Ns_per_m"] == 0 and j["passivity_condition_met"] is True),
    ("no neighbour condition not named", "no_neighbour" not in j["conditions"] and j["no_neighbour_ticks"] == 0),
    ("verdict stable", j["verdict"] == "stable"),
    ("solo anchor recorded (default 2 N/m)", j["solo"]["anchor_N_per_m"] == 2.0),
]
bad = [name for name, ok in checks if not ok]
print(("FAILED contact summary: " + ", ".join(bad)) if bad else
      "ok contact summary: %d contact ticks of %d, max force %.3f N, port energy %.4f J (min %.4f J)" %
      (j["contact_ticks"], j["ticks_run"], j["device_force_max_N"], j["port_energy_final_J"], j["port_energy_min_J"]))
sys.exit(1 if bad else 0)
EOF

# diverged: a divergence bound the hand's first touches exceed (station.divergence_speed_m_per_s in a
# --config file) is a safety stop: exit 4, station-1.json says diverged and when, the verdict is not
# "stable", and from then on no force is commanded although the hand still touches the object
printf '[station]\ndivergence_speed_m_per_s = 1e-4\n' > "$out/diverge.toml"
expect diverged 4 "error: diverged at [0-9.]+ s" -- "$bin" solo --device simulated --duration 2 --config "$out/diverge.toml" --out "$out/diverged"
/usr/bin/python3 - "$out/diverged" <<'EOF' || fail=1
import csv, json, math, sys
d = sys.argv[1]
j = json.load(open(d + "/station-1.json"))
rows = list(csv.DictReader(open(d + "/station-1-trace.csv")))
after = [r for r in rows if j.get("diverged_at_s") is not None and float(r["t_s"]) > j["diverged_at_s"]]
force = lambda r: math.hypot(float(r["force_x_N"]), float(r["force_y_N"]), float(r["force_z_N"]))
checks = [
    ("exit_code 4, diverged, named in conditions", j["exit_code"] == 4 and j["diverged"] is True and "diverged" in j["conditions"]),
    ("verdict not stable", j["verdict"] != "stable"),
    ("rows after the divergence", len(after) > 100),
    ("the hand still touches after it", sum(r["contact"] == "1" for r in after) > 0),
    ("no force after it (safe state held)", all(force(r) == 0 for r in after)),
]
bad = [name for name, ok in checks if not ok]
print(("FAILED diverged summary: " + ", ".join(bad)) if bad else
      "ok diverged summary: diverged at %.3f s, %d rows after it (%d in contact), all with zero force, verdict %s" %
      (j["diverged_at_s"], len(after), sum(r["contact"] == "1" for r in after), j["verdict"]))
sys.exit(1 if bad else 0)
EOF

# control: a still hand (--script hold) at the same start point touches nothing, so the contact above
# came from the simulated user's motion, not from where the proxy starts
expect hold 0 "haptic-station solo: done" -- "$bin" solo --script hold --duration 1 --out "$out/hold"
/usr/bin/python3 -c 'import json, sys; j = json.load(open(sys.argv[1])); sys.exit(0 if j["contact_ticks"] == 0 and j["device_force_max_N"] == 0 else 1)' \
  "$out/hold/station-1.json" && echo "ok hold: no contact, no force" || say_fail "hold: a still hand touched the object (contact_ticks or force > 0)"

# view: the page is served while the run runs; SIGTERM ends it with its report
port=$(( 47300 + ($$ % 40) * 2 ))
"$bin" solo --device simulated --duration 120 --view-port "$port" --out "$out/view" > "$out/view.log" 2>&1 &
pid=$!
served=0
for _ in $(seq 1 300); do
  /usr/bin/python3 -c 'import sys, urllib.request; sys.exit(0 if b"view.js" in urllib.request.urlopen(sys.argv[1], timeout=1).read() else 1)' \
    "http://127.0.0.1:$port/" 2>/dev/null && { served=1; break; }
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
kill -TERM "$pid" 2>/dev/null; wait "$pid"; rc=$?
if [ "$served" -ne 1 ]; then say_fail "view: http://127.0.0.1:$port/ never served the page"; cat "$out/view.log"
elif [ "$rc" -ne 0 ]; then say_fail "view: exit $rc after SIGTERM, expected 0"; cat "$out/view.log"
elif ! grep -q "live view at http://127.0.0.1:$port" "$out/view.log"; then say_fail "view: the URL was not printed"; cat "$out/view.log"
elif ! /usr/bin/python3 -c 'import json, sys; sys.exit(0 if json.load(open(sys.argv[1]))["stopped_by_signal"] else 1)' "$out/view/station-1.json"; then
  say_fail "view: station-1.json does not say the run was stopped by the signal"
else echo "ok view: http://127.0.0.1:$port/ served view.js; SIGTERM: exit 0, stopped_by_signal"; fi

# errors: the option named as written
expect bad_device 2 "--device: phantom" -- "$bin" solo --device phantom
expect bad_nodes 2 "--nodes \(station\.nodes\) must be" -- "$bin" solo --nodes 3 --out "$out/bad"
expect unknown_option 2 "--bogus" -- "$bin" solo --bogus 1
if "$bin" solo --device auto --duration 1 --out "$out/auto" > "$out/auto.log" 2>&1; then rc=0; else rc=$?; fi
if grep -q "no device to start on this machine" "$out/auto.log"; then
  [ "$rc" -eq 9 ] && echo "ok no_device: exit 9, no device to start" || { say_fail "no_device: exit $rc, expected 9"; cat "$out/auto.log"; }
elif [ "$rc" -eq 9 ]; then say_fail "no_device: exit 9 without the station's message"; cat "$out/auto.log"
else echo "note: a device is present on this host (--device auto exit $rc): the no-device case is not checked here"; fi
exit $fail
