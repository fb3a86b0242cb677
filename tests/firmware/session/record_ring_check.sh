#!/usr/bin/env bash
# Recording as a ring of the last seconds (station.record_ring_s / sim --record-ring-s): a 1 s ring
# of a 3 s and of a 6 s run are files of the SAME size (bounded, however long
# the run); each holds exactly the last 500 ticks, in order once rotated by ring_next_row; every
# packet of the ticks from packets_complete_from_tick equals the whole-run log's; replay refuses a
# wrapped ring (exit 3, saying why); a ring longer than the run replays bit-exactly (~6 s).
set -uo pipefail
bin="$1"; out="$2"
rm -rf "$out"; mkdir -p "$out"
if ! /usr/bin/python3 -c 'import h5py' 2>/dev/null; then echo "SKIP: python3-h5py missing (apt-get install python3-h5py)"; exit 77; fi
sim() { "$bin" sim --scenario paper-best --push-end 1 --release 2 --record --no-plots --quiet "$@" > /dev/null; }
sim --out "$out/ring3" --duration 3 --record-ring-s 1 && sim --out "$out/ring6" --duration 6 --record-ring-s 1 \
  && sim --out "$out/whole6" --duration 6 && sim --out "$out/long-ring" --duration 2 --record-ring-s 5 || { echo "FAILED: sim --record"; exit 1; }
/usr/bin/python3 - "$out" <<'PY' || exit 1
import os, sys, h5py, numpy as np
out = sys.argv[1]
fail = []
def chrono(f, group, name):
    a = f[group][name][:]
    return np.roll(a, -int(f[group].attrs["ring_next_row"]), axis=0)
for i in range(1, 5):
    s3, s6 = os.path.getsize("%s/ring3/station-%d.h5" % (out, i)), os.path.getsize("%s/ring6/station-%d.h5" % (out, i))
    sw = os.path.getsize("%s/whole6/station-%d.h5" % (out, i))
    if s3 != s6: fail.append("station %d: ring file grew with the run: %d B (3 s) vs %d B (6 s)" % (i, s3, s6))
    if not s6 < 0.5 * sw: fail.append("station %d: ring %d B not below half the whole run's %d B" % (i, s6, sw))
    with h5py.File("%s/ring6/station-%d.h5" % (out, i)) as r, h5py.File("%s/whole6/station-%d.h5" % (out, i)) as w:
        k = chrono(r, "ticks", "k")
        if not (len(k) == 500 and k[0] == 2500 and np.all(np.diff(k) == 1) and r.attrs["first_tick"] == 2500):
            fail.append("station %d: ticks %s..%s (%d rows), first_tick %s; want 2500..2999" % (i, k.min(), k.max(), len(k), r.attrs["first_tick"]))
        if not np.array_equal(chrono(r, "ticks", "hash"), w["ticks/hash"][2500:]):
            fail.append("station %d: the ring's tick hashes differ from the whole run's last 500" % i)
        c = int(r.attrs["packets_complete_from_tick"])
        rt, wt = chrono(r, "packets", "tick"), w["packets/tick"][:]
        rsel, wsel = rt >= c, wt >= c
        if c > 2500 + 100 or not np.array_equal(rt[rsel], wt[wsel]) or \
           not np.array_equal(chrono(r, "packets", "x")[rsel], w["packets/x"][:][wsel]):
            fail.append("station %d: packets from tick %d are not the whole run's (%d vs %d rows)" % (i, c, rsel.sum(), wsel.sum()))
print("ring check: 1 s ring = %d B for a 3 s and a 6 s run (whole 6 s run: %d B); ticks 2500..2999 and their packets as in the whole run" % (s6, sw))
if fail:
    print("FAILED: " + "; ".join(fail)); sys.exit(1)
PY
"$bin" replay "$out/ring6/station-1.h5" > "$out/replay-ring.log" 2>&1; rc=$?
if [ $rc -ne 3 ] || ! grep -q "cannot replay a ring" "$out/replay-ring.log"; then echo "FAILED: replay of a wrapped ring: exit $rc"; cat "$out/replay-ring.log"; exit 1; fi
echo "ok: $(cat "$out/replay-ring.log")"
"$bin" replay "$out/long-ring/station-1.h5" > "$out/replay-long.log" 2>&1; rc=$?
if [ $rc -ne 0 ] || ! grep -q "bit-exact at every tick" "$out/replay-long.log"; then echo "FAILED: replay of a ring longer than the run: exit $rc"; cat "$out/replay-long.log"; exit 1; fi
echo "ok: $(cat "$out/replay-long.log")"
