#!/usr/bin/python3
"""Stability map around the tight case.

The tight case: `haptic-station sim --scenario paper-unstable` with every one-way delay 1.33 ms, no
loss, no duplication, no loss allowance and D_ij = 0 (eq. 18 gives B = (6, 2, 2, 2) N s/m there).
Around it, one parameter at a time (delay, delay jitter, loss, T_k jitter, D, node mass), for the
i.i.d. delay model and the time-correlated one (--delay-correlation RHO, same uniform support),
this finds by bisection the smallest scale f of eq. (18)'s damping (B_i = f x eq. 18, all users)
at which the run is stable: no divergence by speed AND no growth of the consensus error
(summary.json `unstable` = diverged or growth_detected_at_s, firmware/model/growth_detector.hpp).
The eq. (18) line is f = 1: below it eq. (18) is conservative, above it (18) does not suffice.

Bounded: small grids, short runs (--duration, default 8 s), one run at a time, progress on stderr.
Writes tools/study/results/tight_map.{json,png} (or --out DIR). Usage:
    /usr/bin/python3 tools/study/tight_map.py [--station build/bin/haptic-station] [--duration 8]
        [--quick] [--out tools/study/results]
"""
import argparse, json, math, os, subprocess, sys, tempfile, time

TIGHT = ["--scenario", "paper-unstable", "--loss", "0", "--duplication", "0", "--loss-allowance", "0",
         "--d-gain", "0", "--damping-margin", "0", "--edge-energy-bound", "0", "--no-plots", "--quiet"]  # eq. (18) alone


def delay_matrix(ms):
    rows = [",".join("0" if i == j else repr(ms) for j in range(4)) for i in range(4)]
    return ";".join(rows)


# one axis: (name, unit, values, function value -> extra sim args); the tight case's value first
AXES = [
    ("one-way delay", "ms", [1.33, 4.0, 10.0, 30.0], lambda v: ["--delay-matrix", delay_matrix(v)]),
    ("delay jitter (fraction of mean)", "", [0.0, 0.25, 0.5, 0.9], lambda v: ["--jitter", repr(v), "--delay-matrix", delay_matrix(10.0)]),
    ("loss probability", "", [0.0, 0.05, 0.2], lambda v: ["--loss", repr(v), "--loss-allowance", "1" if v > 0 else "0"]),
    ("timer jitter T_k", "ms", [0.0, 0.2, 0.35, 0.5], lambda v: ["--timer-jitter-ms", repr(v)]),
    ("D_ij", "N s/m", [0.0, 1.0, 5.0], lambda v: ["--d-gain", repr(v)]),
    ("node mass", "kg", [0.01, 0.04, 0.16], lambda v: ["--node-mass-kg", repr(v)]),
    # Gilbert-Elliott bursts (5 packets mean, all lost inside) on top of no loss; the allowance from the burst chain
    ("burst entry probability", "per packet", [0.0, 0.01, 0.05],
     lambda v: ["--burst-enter", repr(v), "--burst-length", "5", "--loss-allowance", None] if v > 0 else []),
]
DEFAULT_DELAY = ["--delay-matrix", delay_matrix(1.33)]


def merged(args):
    """The tight case's options with `args` (option, value pairs) overriding them."""
    opts, flags = {}, []
    base = TIGHT + DEFAULT_DELAY
    for lst in (base, args):
        i = 0
        while i < len(lst):
            if lst[i] in ("--no-plots", "--quiet"):
                flags.append(lst[i])
                i += 1
            else:
                opts[lst[i]] = lst[i + 1]
                i += 2
    out = sorted(set(flags))
    for k, v in opts.items():
        if v is not None:  # None removes the tight case's value (the simulator's default applies)
            out += [k, v]
    return out


def run(station, args, duration, out):
    cmd = [station, "sim"] + merged(args) + ["--duration", repr(duration), "--out", out]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode not in (0, 1):
        sys.exit("haptic-station failed (%d): %s\n%s" % (p.returncode, " ".join(cmd), p.stderr[-2000:]))
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def unstable(s):
    return bool(s.get("diverged")) or s.get("growth_detected_at_s") is not None


def critical_scale(station, args, duration, out, lo=0.02, hi=2.0, steps=6):
    """Smallest f in [lo, hi] (log bisection) with a stable run at B = f x eq. (18)."""
    base = run(station, args, duration, out)  # eq. (18) of a run this long: the loss allowance grows with the run
    b18 = base["damping_min_Ns_per_m"]
    def stable_at(f):
        s = run(station, args + ["--damping", ",".join(repr(f * b) for b in b18)], duration, out)
        return not unstable(s), s
    ok_hi, _ = stable_at(hi)
    if not ok_hi:
        return {"eq18_Ns_per_m": b18, "critical_scale": None, "note": "unstable at %g x eq. (18)" % hi}
    ok_lo, _ = stable_at(lo)
    if ok_lo:
        return {"eq18_Ns_per_m": b18, "critical_scale": lo, "note": "stable at %g x eq. (18) (upper bound)" % lo}
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        ok, _ = stable_at(mid)
        if ok:
            hi = mid
        else:
            lo = mid
    return {"eq18_Ns_per_m": b18, "critical_scale": hi, "bracket": [lo, hi]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--station", default="build/bin/haptic-station")
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--correlation", type=float, default=0.99, help="AR(1) coefficient of the correlated model (default 0.99)")
    ap.add_argument("--quick", action="store_true", help="two values per axis, 4 bisection steps")
    ap.add_argument("--out", default="tools/study/results")
    ap.add_argument("--lo", type=float, default=0.02, help="smallest scale of eq. (18) tried (default 0.02)")
    ap.add_argument("--only", help="only the axes whose name contains this text; writes tight_map-<text>.{json,png}")
    a = ap.parse_args()
    axes = [ax for ax in AXES if a.only is None or a.only in ax[0]]
    if not axes:
        ap.error("--only %r matches no axis (axes: %s)" % (a.only, ", ".join(ax[0] for ax in AXES)))
    stem = "tight_map" if a.only is None else "tight_map-" + a.only.replace(" ", "_")
    tmp = tempfile.mkdtemp(prefix="tight-map-")
    models = [("i.i.d.", []), ("correlated rho=%g" % a.correlation, ["--delay-correlation", repr(a.correlation)])]
    res = {"tight_case": " ".join(TIGHT + DEFAULT_DELAY), "duration_s": a.duration, "lowest_scale_tried": a.lo, "axes": []}
    t0 = time.time()
    total = sum(len(ax[2][:2] if a.quick else ax[2]) for ax in axes) * len(models)
    done = 0
    for name, unit, values, fn in axes:
        if a.quick:
            values = values[:2]
        axis = {"name": name, "unit": unit, "values": values, "models": {}}
        for mname, margs in models:
            pts = []
            for v in values:
                r = critical_scale(a.station, fn(v) + margs, a.duration, tmp, lo=a.lo, steps=4 if a.quick else 6)
                r["value"] = v
                pts.append(r)
                done += 1
                print("  [%d/%d] %s = %g %s, %s: critical B / eq.(18) = %s (%.0f s)" % (done, total, name, v, unit, mname,
                      r["critical_scale"], time.time() - t0), file=sys.stderr, flush=True)
            axis["models"][mname] = pts
        res["axes"].append(axis)
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, stem + ".json"), "w") as f:
        json.dump(res, f, indent=1)
    plot(res, os.path.join(a.out, stem + ".png"))
    print("wrote %s/%s.json, %s.png" % (a.out, stem, stem))


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    axes = res["axes"]
    cols = min(3, len(axes))
    rows = (len(axes) + cols - 1) // cols
    fig, axs = plt.subplots(rows, cols, figsize=(max(4.4 * cols, 10.0), 3.75 * rows + 0.8), squeeze=False)
    for ax in list(axs.flat)[len(axes):]:
        ax.set_visible(False)
    for ax, axis in zip(axs.flat, axes):
        for mname, pts in axis["models"].items():
            xs = [p["value"] for p in pts if p["critical_scale"] is not None]
            ys = [p["critical_scale"] for p in pts if p["critical_scale"] is not None]
            ax.plot(xs, ys, "o-", label="stability boundary, " + mname)
            # stable at the smallest scale tried: the boundary is at or below it (an upper bound)
            low = [(p["value"], p["critical_scale"]) for p in pts if "upper bound" in p.get("note", "")]
            if low:
                ax.plot([v for v, _ in low], [c for _, c in low], "v", color="0.3", ms=9)
        ax.axhline(1.0, color="k", ls="--", label="eq. (18)")
        ax.set_yscale("log")
        ax.set_xlabel(axis["name"] + (" (%s)" % axis["unit"] if axis["unit"] else ""))
        ax.set_ylabel("smallest stable B_i / eq. (18)")
        ax.grid(True, which="both", alpha=0.3)
    axs.flat[0].legend(fontsize=7)
    fig.suptitle("Around the tight case (paper-unstable, 1.33 ms, D = 0): where the simulated system becomes unstable\n"
                 "(unstable = diverged by speed or consensus error growing 1.5x per s for 3 s); %g s runs" % res["duration_s"])
    fig.tight_layout()
    fig.savefig(path, dpi=90)


if __name__ == "__main__":
    main()
