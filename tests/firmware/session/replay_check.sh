#!/usr/bin/env bash
# Replay is bit-exact and the comparison can fail: a recorded simulated run
# replays with the same state hash at every tick for every station; the same log with ONE packet
# value changed in its last bit (h5py) fails the comparison at a tick; a re-run with other gains
# runs and differs in force; h5py reads the log; the steps' measured times are in it (~3 s).
set -uo pipefail
bin="$1"; out="$2"
rm -rf "$out"; mkdir -p "$out"
fail=0
if ! /usr/bin/python3 -c 'import h5py' 2>/dev/null; then echo "SKIP: python3-h5py missing (apt-get install python3-h5py)"; exit 77; fi
"$bin" sim --scenario paper-best --out "$out/sim" --duration 2 --push-end 1 --release 1.5 --record --no-plots --quiet > "$out/sim.log" 2>&1 \
  || { echo "FAILED: sim --record"; cat "$out/sim.log"; exit 1; }
for i in 1 2 3 4; do
  "$bin" replay "$out/sim/station-$i.h5" > "$out/replay-$i.log" 2>&1; rc=$?
  if [ $rc -ne 0 ] || ! grep -q "1000 ticks, bit-exact at every tick" "$out/replay-$i.log"; then
    echo "FAILED replay station $i (exit $rc):"; cat "$out/replay-$i.log"; fail=1
  else echo "ok station $i: $(cat "$out/replay-$i.log")"; fi
done
# The simulator records each step's time on this host in /ticks/exec_ns, as a station records its
# tick's, so a sim recording's view plots tick times and not a flat 0.
/usr/bin/python3 - "$out/sim/station-2.h5" <<'PY' || { echo "FAILED: a sim recording's exec_ns is not the steps' measured time"; fail=1; }
import sys, h5py, numpy as np
e = h5py.File(sys.argv[1], "r")["ticks/exec_ns"][:]
print("sim recording: exec_ns > 0 in %.1f %% of %d ticks, median %.1f us" % (100 * np.mean(e > 0), len(e), np.median(e) * 1e-3))
sys.exit(0 if len(e) == 1000 and np.mean(e > 0) > 0.99 else 1)
PY
# Variable steps (the simulator's timer jitter): the log stores each tick's T_k (/ticks/step_s) and
# replay hands it to the core: bit-exact; the same log with one step changed is not.
"$bin" sim --scenario paper-best --out "$out/steps" --duration 2 --push-end 1 --release 1.5 --timer-jitter-ms 0.4 --record --no-plots --quiet \
  > "$out/steps.log" 2>&1 || { echo "FAILED: sim --record --timer-jitter-ms"; cat "$out/steps.log"; exit 1; }
for i in 1 4; do
  "$bin" replay "$out/steps/station-$i.h5" > "$out/steps-$i.log" 2>&1; rc=$?
  if [ $rc -ne 0 ] || ! grep -q "1000 ticks, bit-exact at every tick" "$out/steps-$i.log"; then
    echo "FAILED replay with T_k, station $i (exit $rc):"; cat "$out/steps-$i.log"; fail=1
  else echo "ok T_k station $i: $(cat "$out/steps-$i.log")"; fi
done
# T_k is measured as a station measures it: this wake minus the previous one, so the first tick's step
# is the nominal period (no previous wake), as the station's first tick; every step within the bounds.
/usr/bin/python3 - "$out/steps/station-1.h5" <<'PY' || { echo "FAILED: the simulator's T_k is not this wake minus the previous one"; fail=1; }
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
s, c = f["ticks/step_s"][:], f["core"].attrs
print("sim steps: first %.9f s, range [%.6f, %.6f] ms, bounds [%.6f, %.6f] ms" % (s[0], 1e3 * s.min(), 1e3 * s.max(), 1e3 * c["period_min_s"], 1e3 * c["period_max_s"]))
sys.exit(0 if s[0] == 0.002 and s.min() >= c["period_min_s"] and s.max() <= c["period_max_s"] else 1)
PY
cp "$out/steps/station-1.h5" "$out/steps-perturbed.h5"
/usr/bin/python3 - "$out/steps-perturbed.h5" <<'PY' || { echo "FAILED: h5py (steps)"; exit 1; }
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r+") as f:
    s = f["ticks/step_s"]
    assert s.shape == (1000,), s.shape
    assert np.ptp(s[1:]) > 1e-4, "the timer jitter should vary the steps"
    s[600] = 0.002 if abs(s[600] - 0.002) > 1e-4 else 0.0023  # during the push (at rest the step changes nothing)
    print("step of tick 600 ->", s[600])
PY
"$bin" replay "$out/steps-perturbed.h5" > "$out/steps-perturbed.log" 2>&1; rc=$?
if [ $rc -ne 3 ] || ! grep -q "state hash differs first at tick 600" "$out/steps-perturbed.log"; then
  echo "FAILED: a log with one step changed must differ at that tick (exit $rc):"; cat "$out/steps-perturbed.log"; fail=1
else echo "ok step perturbed: $(cat "$out/steps-perturbed.log")"; fi
# A compressed log (shuffle + deflate, --record-deflate / station.record_deflate) is lossless: bit-exact too.
"$bin" sim --scenario paper-best --out "$out/deflate" --duration 2 --push-end 1 --release 1.5 --record --record-deflate 1 --no-plots --quiet \
  > "$out/deflate.log" 2>&1 || { echo "FAILED: sim --record --record-deflate 1"; cat "$out/deflate.log"; exit 1; }
"$bin" replay "$out/deflate/station-1.h5" > "$out/deflate-replay.log" 2>&1; rc=$?
/usr/bin/python3 -c 'import sys, h5py; x = h5py.File(sys.argv[1], "r")["packets/x"]; sys.exit(0 if x.compression == "gzip" and x.shuffle else 1)' "$out/deflate/station-1.h5" \
  && [ $rc -eq 0 ] && grep -q "1000 ticks, bit-exact at every tick" "$out/deflate-replay.log" \
  && echo "ok deflated log ($(stat -c %s "$out/deflate/station-1.h5") B vs $(stat -c %s "$out/sim/station-1.h5") B): $(cat "$out/deflate-replay.log")" \
  || { echo "FAILED: the shuffled + deflated log (exit $rc):"; cat "$out/deflate-replay.log"; fail=1; }
# The size bound (--record-max-mb, as station.record_max_mb): the log stops at a tick and says so; replay
# re-runs up to there, says the inputs are incomplete and exits 3; with --to before that tick it is whole.
"$bin" sim --scenario paper-best --out "$out/bounded" --duration 2 --push-end 1 --release 1.5 --record --record-max-mb 1 --no-plots --quiet \
  > "$out/bounded.log" 2>&1 || { echo "FAILED: sim --record --record-max-mb 1"; cat "$out/bounded.log"; exit 1; }
cut_at=$(/usr/bin/python3 -c 'import sys, h5py; print(int(h5py.File(sys.argv[1], "r").attrs["truncated_at_tick"]))' "$out/bounded/station-1.h5")
"$bin" replay "$out/bounded/station-1.h5" > "$out/bounded-replay.log" 2>&1; rc=$?
"$bin" replay "$out/bounded/station-1.h5" --to $(( cut_at - 1 )) > "$out/bounded-to.log" 2>&1; rc_to=$?
if [ "$cut_at" -gt 0 ] && [ "$cut_at" -lt 1000 ] && [ $rc -eq 3 ] && grep -q "incomplete from tick $cut_at" "$out/bounded-replay.log" \
   && [ $rc_to -eq 0 ] && grep -q "$cut_at ticks, bit-exact at every tick" "$out/bounded-to.log"; then
  echo "ok size bound: truncated at tick $cut_at, $(stat -c %s "$out/bounded/station-1.h5") B; $(cat "$out/bounded-replay.log") (exit 3); --to: exit 0"
else
  echo "FAILED: the size-bounded log (truncated_at_tick ${cut_at:-?}; exit $rc, --to exit $rc_to):"; cat "$out/bounded-replay.log" "$out/bounded-to.log"; fail=1
fi
# h5py reads it; flip the lowest mantissa bit of one received packet value in a copy.
cp "$out/sim/station-1.h5" "$out/perturbed.h5"
/usr/bin/python3 - "$out/perturbed.h5" <<'PY' || { echo "FAILED: h5py"; exit 1; }
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r+") as f:
    assert f.attrs["format"] == "haptic-session", f.attrs["format"]
    assert f["ticks/hash"].shape == (1000,), f["ticks/hash"].shape
    f.visit(lambda name: print("  h5py:", name, getattr(f[name], "shape", "(group)")) if name.count("/") < 1 or name.startswith(("ticks/", "packets/")) else None)
    assert "scene hash" in f.attrs["fingerprint"] and f.attrs["damping_min_Ns_per_m"] > 0, dict(f.attrs)
    assert len(f.attrs["build_id"]) >= 16, "the writing program's GNU build ID: %r" % f.attrs["build_id"]
    x = f["packets/x"]
    row = 200
    v = x[row, 7]
    x[row, 7] = np.nextafter(v, np.inf)
    print("perturbed packet", row, "tick", int(f["packets/tick"][row]), "value", repr(v), "->", repr(x[row, 7]))
PY
"$bin" replay "$out/perturbed.h5" > "$out/perturbed.log" 2>&1; rc=$?
# (written and replayed by this build: the replay must not blame another build)
if [ $rc -ne 3 ] || ! grep -q "state hash differs first at tick" "$out/perturbed.log" || grep -q "another build" "$out/perturbed.log"; then
  echo "FAILED: a perturbed log must not replay bit-exactly (exit $rc):"; cat "$out/perturbed.log"; fail=1
else echo "ok perturbed: $(cat "$out/perturbed.log")"; fi
"$bin" replay "$out/sim/station-2.h5" --damping 60 --trace "$out/regain.csv" > "$out/regain.log" 2>&1; rc=$?
if [ $rc -ne 0 ] || ! grep -Eq "changed gains; max \|F - F_recorded\| = [0-9.e-]+ N" "$out/regain.log" || grep -q "= 0 N" "$out/regain.log"; then
  echo "FAILED: re-run with other gains (exit $rc):"; cat "$out/regain.log"; fail=1
else echo "ok re-run: $(cat "$out/regain.log")"; fi
# Stepping through: --from/--to print each tick (the replayed and the recorded hash) and stop at --to;
# --state-json writes the core's state there. The printed hashes are the log's rows for those ticks
# and the state's VP is the full replay's (--trace) at the same tick.
"$bin" replay "$out/sim/station-1.h5" --trace "$out/full.csv" > /dev/null 2>&1
"$bin" replay "$out/sim/station-1.h5" --from 600 --to 602 --state-json "$out/state-602.json" > "$out/step.log" 2>&1; rc=$?
/usr/bin/python3 - "$out/sim/station-1.h5" "$out/step.log" "$out/state-602.json" "$out/full.csv" $rc <<'PY' || fail=1
import csv, json, re, sys, h5py
log, step, state, full, rc = sys.argv[1], open(sys.argv[2]).read(), json.load(open(sys.argv[3])), sys.argv[4], int(sys.argv[5])
lines = [l for l in step.splitlines() if l.startswith("tick ")]
with h5py.File(log, "r") as f:
    hashes = f["ticks/hash"][600:603]
    dofs = int(f.attrs["dofs"])
ok = rc == 0 and "603 ticks, bit-exact at every tick" in step and "stopped at tick 602" in step and len(lines) == 3
for i, l in enumerate(lines):
    m = re.match(r"tick (\d+) .* hash=([0-9a-f]{16}) recorded=([0-9a-f]{16}) match$", l)
    ok = ok and m is not None and int(m.group(1)) == 600 + i and int(m.group(3), 16) == int(hashes[i]) and m.group(2) == m.group(3)
row = [r for r in csv.DictReader(open(full)) if r["k"] == "602"][0]
ok = ok and state["tick"] == 602 and len(state["x_m"]) == dofs and len(state["links"]) == 3
ok = ok and all(abs(state["vp_m"][a] - float(row["vp_%s_m" % "xyz"[a]])) <= 1e-8 * max(1.0, abs(state["vp_m"][a])) for a in range(3))
print(("ok" if ok else "FAILED") + " stepping: exit %d, %d tick lines, state at tick %s (%d values)" % (rc, len(lines), state.get("tick"), len(state.get("x_m", []))))
if not ok: print(step); sys.exit(1)
PY
"$bin" replay "$out/perturbed.h5" --from 60 --to 80 > "$out/step-perturbed.log" 2>&1
grep -q "DIFFERS" "$out/step-perturbed.log" || { echo "FAILED: stepping through the perturbed log shows no tick that DIFFERS"; fail=1; }
"$bin" replay "$out/sim/station-1.h5" --from 10 --to 5 > /dev/null 2>&1; rc=$?
[ $rc -eq 2 ] || { echo "FAILED: --to before --from must exit 2 (exit $rc)"; fail=1; }
"$bin" replay "$out/sim.log" > "$out/bad.log" 2>&1; rc=$?
if [ $rc -ne 2 ]; then echo "FAILED: a non-log must exit 2 (exit $rc)"; cat "$out/bad.log"; fail=1; else echo "ok not a log: $(head -1 "$out/bad.log")"; fi
exit $fail
