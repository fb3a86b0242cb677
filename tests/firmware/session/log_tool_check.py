#!/usr/bin/python3
"""`haptic-station log info|export` on a recorded simulated run (~3 s).

usage: log_tool_check.py HAPTIC_STATION OUT_DIR

Checks, each against the file as h5py reads it (not against the tool's own output):
- every dataset of the log has `units` and `description` attributes, /ticks/flags has `flag_bits`
  naming bit 0 contact_onset (the writer's one table, firmware/session/log.hpp);
- `log info` names the scenario, lists /ticks/force as (1000, 3) float64 N and decodes the flags with
  the number of ticks each bit was set, equal to numpy's count;
- `log export --field force,q,port_J` writes the header t_s,force_x_N,...,q_x_m,...,port_J and the
  values h5py reads, exactly; a /packets field has one column per dof; /ticks and /packets fields
  together are refused;
- a wrapped ring log is exported in run order;
- an unknown field is refused (exit 2) with "did you mean" and the log's fields;
- not a file, a directory, not HDF5, an HDF5 file that is not a session log: exit 2, saying which;
- a log written before units were stored (attributes removed) is described, saying so;
- `log plot RUN_DIR` draws the run's four stations (matplotlib; skipped without it);
- `log export --help` documents the exit statuses.
"""
import csv
import io
import os
import shutil
import subprocess
import sys

try:
    import h5py
    import numpy as np
except ImportError as e:
    print("SKIP: %s (apt-get install python3-h5py python3-numpy)" % e)
    sys.exit(77)

bin_, out = sys.argv[1], sys.argv[2]
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
failures = []


def check(ok, what, detail=""):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)
        if detail:
            print(detail)


def run(*args):
    p = subprocess.run([bin_, *args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


rc, so, se = run("sim", "--scenario", "paper-best", "--duration", "2", "--push-end", "1", "--release", "1.5", "--record", "--no-plots",
                 "--quiet", "--out", out + "/sim")
if rc != 0:
    print("FAILED: sim --record (exit %d)\n%s%s" % (rc, so, se))
    sys.exit(1)
log = out + "/sim/station-1.h5"

# The file: units and description on every dataset, flag_bits on the flags.
with h5py.File(log, "r") as f:
    paths = []
    f.visititems(lambda name, obj: paths.append(name) if isinstance(obj, h5py.Dataset) else None)
    missing = [p for p in paths if "units" not in f[p].attrs or "description" not in f[p].attrs]
    check(len(paths) > 20 and not missing, "units and description on every dataset (%d datasets)" % len(paths), "without: %s" % missing)
    check(f["ticks/force"].attrs.get("units") == "N" and f["ticks/q"].attrs.get("units") == "m" and f["packets/v"].attrs.get("units") == "m/s"
          and f["core/scene/K/values"].attrs.get("units") == "N/m", "units of force, q, packets/v, K are N, m, m/s, N/m")
    bits = f["ticks/flags"].attrs.get("flag_bits", "")
    check(bits.splitlines()[:1] and bits.splitlines()[0].startswith("0 contact_onset "), "flag_bits names bit 0 contact_onset", repr(bits))
    force = f["ticks/force"][:]
    q = f["ticks/q"][:]
    port = f["ticks/port_J"][:]
    flags = f["ticks/flags"][:].astype(np.uint64)
    x = f["packets/x"][:]
    dofs = int(f.attrs["dofs"])
    period = float(f.attrs["period_s"])
    k = f["ticks/k"][:]

# log info
rc, info, se = run("log", "info", log)
check(rc == 0, "log info exits 0", se)
check("scenario paper-best" in info, "log info names the scenario", info)
line = [l for l in info.splitlines() if l.strip().startswith("ticks/force ")]
check(len(line) == 1 and line[0].split()[1:5] == ["(1000,", "3)", "float64", "N"], "log info: ticks/force (1000, 3) float64 N", "\n".join(line) or info)
check("1000 ticks" in info and "names from the log's flag_bits" in info, "log info: 1000 ticks, flag names from the log", info)
counts = {b: int(np.count_nonzero((flags >> np.uint64(b)) & np.uint64(1))) for b in range(32)}
onset = [l.split() for l in info.splitlines() if l.strip().startswith("bit ") and " contact_onset " in l]
check(counts[0] > 0 and len(onset) == 1 and onset[0][1] == "0" and int(onset[0][3]) == counts[0],
      "log info: bit 0 contact_onset set in %d ticks (numpy: %d)" % (int(onset[0][3]) if onset else -1, counts[0]), info)
decoded = {int(l.split()[1]): int(l.split()[3]) for l in info.splitlines() if l.strip().startswith("bit ")}
check(all(decoded.get(b, 0) == c for b, c in counts.items() if c > 0) and all(counts[b] == c for b, c in decoded.items()),
      "log info: every bit's tick count equals numpy's", "info %s numpy %s" % (decoded, {b: c for b, c in counts.items() if c}))

# log export
csv_path = out + "/force.csv"
rc, so, se = run("log", "export", log, "--field", "force,q,port_J", "--out", csv_path)
check(rc == 0 and os.path.exists(csv_path), "log export --out exits 0 and writes the file", se)
rows = list(csv.reader(open(csv_path))) if os.path.exists(csv_path) else [[]]
want = ["t_s", "force_x_N", "force_y_N", "force_z_N", "q_x_m", "q_y_m", "q_z_m", "port_J"]
check(rows[0] == want, "export header " + ",".join(want), "got %s" % rows[0])
if rows[0] == want:
    data = np.array([[float(v) for v in r] for r in rows[1:]])
    exact = data.shape == (1000, 8) and np.array_equal(data[:, 1:4], force) and np.array_equal(data[:, 4:7], q) and np.array_equal(data[:, 7], port)
    check(exact, "export values equal h5py's, exactly (1000 rows)")
    check(np.allclose(data[:, 0], (k + 1) * period, rtol=0, atol=1e-9), "export t_s is the run time at the end of each tick ((k+1) T at nominal steps)",
          "t_s %s vs %s" % (data[:3, 0], (k[:3] + 1) * period))
rc, so, se = run("log", "export", log, "--field", "packets/x")
head = so.splitlines()[0].split(",") if so else []
check(rc == 0 and head == ["x_%d_m" % i for i in range(dofs)] and len(so.splitlines()) == len(x) + 1
      and np.array_equal(np.array([float(v) for v in so.splitlines()[1].split(",")]), x[0]),
      "export packets/x: x_0_m..x_%d_m, one row per packet, values exact" % (dofs - 1), se + so[:300])
rc, so, se = run("log", "export", log, "--field", "force,x")
check(rc == 2 and "export them separately" in se, "export of a /ticks and a /packets field together is refused (exit 2)", "exit %d: %s" % (rc, se))

# Unknown field: did you mean, and the list.
rc, so, se = run("log", "export", log, "--field", "forc")
check(rc == 2 and "no field 'forc'" in se and "did you mean force?" in se and "ticks/step_s [s]" in se and "packets/v [m/s]" in se and so == "",
      "unknown field refused (exit 2) with 'did you mean force?' and the fields with units", "exit %d: %s" % (rc, se))

# Bad input.
notlog = out + "/sim.txt"
open(notlog, "w").write("not a log\n")
other = out + "/other.h5"
with h5py.File(other, "w") as f:
    f["a"] = np.arange(3)
for args, say in [((notlog,), "not an HDF5 file (a session log is"), ((out + "/missing.h5",), "no such file"), ((out,), "is a directory"),
                  ((other,), "not a haptic session log")]:
    for sub in (["info"], ["export", "--field", "force"]):
        rc, so, se = run("log", *sub, *args)
        check(rc == 2 and say in se and "error:" in se, "log %s %s: exit 2, '%s'" % (sub[0], os.path.basename(args[0]), say), "exit %d: %s" % (rc, se))

# A log written before units were stored: described, saying so.
old = out + "/old.h5"
shutil.copy(log, old)
with h5py.File(old, "r+") as f:
    del f.attrs["field_units"]
    del f.attrs["scenario"]
    def strip(name, obj):
        for a in ("units", "description", "flag_bits"):
            if isinstance(obj, h5py.Dataset) and a in obj.attrs:
                del obj.attrs[a]
    f.visititems(strip)
rc, so, se = run("log", "info", old)
check(rc == 0 and "units not recorded (log written before" in so and "scenario paper-best (from the fingerprint)" in so and "this program's rt::kTickFlagNames" in so,
      "log info on a log without units: exit 0, 'units not recorded (log written before ...)'", "exit %d\n%s%s" % (rc, so, se))
rc, so, se = run("log", "export", old, "--field", "force")
check(rc == 0 and so.splitlines()[0] == "t_s,force_x_N,force_y_N,force_z_N" and "units not recorded" in se,
      "log export on a log without units: this program's units, and a note", "exit %d\n%s%s" % (rc, so[:200], se))

# A ring log that wrapped (--record-ring-s): its rows are exported in run order (k consecutive, t_s rising).
rc, so, se = run("sim", "--scenario", "paper-best", "--duration", "2", "--record", "--record-ring-s", "0.3", "--no-plots", "--quiet", "--out", out + "/ring")
with h5py.File(out + "/ring/station-1.h5", "r") as f:
    next_row = int(f["ticks"].attrs["ring_next_row"])
rc, so, se = run("log", "export", out + "/ring/station-1.h5", "--field", "k")
rows = [r.split(",") for r in so.split()[1:]]
ks = [int(r[1]) for r in rows]
check(rc == 0 and next_row > 0 and len(ks) == 150 and ks == list(range(850, 1000)),
      "export of a wrapped ring log (ring_next_row %d): k 850..999 in run order" % next_row, "exit %d: %s %s" % (rc, ks[:5], se))

# log plot: a run folder's stations on one run-time axis.
try:
    import matplotlib  # noqa: F401
    png = out + "/timeline.png"
    rc, so, se = run("log", "plot", out + "/sim", "--field", "force,port_J", "--out", png)
    check(rc == 0 and "4 station(s), 2 field(s)" in so and os.path.getsize(png) > 10000, "log plot RUN_DIR: 4 stations drawn (%s)" % so.strip(),
          "exit %d: %s%s" % (rc, so, se))
    rc, so, se = run("log", "plot", out + "/sim", "--field", "forc", "--out", png + "2")
    check(rc == 2 and "did you mean force?" in se and not os.path.exists(png + "2"), "log plot: unknown field refused (exit 2)", "exit %d: %s" % (rc, se))
except ImportError:
    print("skip log plot: python3-matplotlib missing")

rc, so, se = run("log", "export", "--help")
check(rc == 0 and "Exit status: 0 done; 2 bad options" in so and "3 the log is damaged" in so, "log export --help documents the exit statuses", so)

print("%d failure(s)" % len(failures))
sys.exit(1 if failures else 0)
