#!/usr/bin/python3
"""Prints the medians of tools/bench/results/rt_tick.json and the ratios the issues ask for,
and draws tick cost against scene size (rt_tick_scaling.png); for every net_oneway*.json with
BM_OneWayPeriodic* runs (bench_net --benchmark_filter=Periodic --benchmark_repetitions=N) prints
each mode's median p50 latency and its ratio to minimal UDP, and draws net_oneway_periodic.png
(a row a file, a panel an encoding, a dot a repetition).

usage: /usr/bin/python3 tools/bench/summarize.py RESULTS_DIR
"""
import json
import os
import sys


def medians(path):
    data = json.load(open(path))
    out = {}
    for b in data["benchmarks"]:
        if b.get("aggregate_name") == "median" or b.get("run_type") == "iteration" and "aggregate_name" not in b:
            name = b["run_name"] if "run_name" in b else b["name"]
            out[name] = b
    return out, data.get("context", {})


MODES = [("udp", "minimal pair"), ("stack_wake", "stack, eventfd wake-up"), ("stack_spin", "stack, tick-synchronous TX"),
         ("stack_direct", "stack, direct TX")]


def oneway_runs(path):
    """The BM_OneWayPeriodic* repetitions of one bench_net JSON, by encoding, and the modes it has."""
    data = json.load(open(path))
    runs = [b for b in data["benchmarks"] if b.get("run_type") == "iteration" and "BM_OneWayPeriodic" in b["name"]]
    modes = [m for m in MODES if runs and all(m[0] + "_p50_us" in b for b in runs)]
    by_enc = {}
    for b in runs:
        enc = ("raw " if "Raw" in b["name"] else "") + ("float32" if "f32:1" in b["name"] else "float64")
        by_enc.setdefault(enc, []).append(b)
    return by_enc, modes, data.get("context", {})


def net_oneway(d):
    """Every net_oneway*.json with periodic runs: the ratios printed, one row of the figure each."""
    import glob
    files = []
    for p in sorted(glob.glob(os.path.join(d, "net_oneway*.json"))):
        by_enc, modes, ctx = oneway_runs(p)
        if not by_enc:
            continue
        files.append((os.path.basename(p), by_enc, modes))
        print("\n%s (load %s): one-way latency, 2 ms periodic sender, modes interleaved period by period" % (
            os.path.basename(p), ", ".join("%.2f" % x for x in ctx.get("load_avg", []))))
        for enc, bs in sorted(by_enc.items()):
            def med(k):
                return sorted(x[k] for x in bs)[len(bs) // 2]
            cells = ["%s p50 %.0f us" % (label, med(m + "_p50_us")) for m, label in modes]
            ratios = ["%s/minimal %.2f" % (m, med("ratio_%s_p50" % m)) for m, _ in modes if m != "udp" and ("ratio_%s_p50" % m) in bs[0]]
            print("  %-13s median of %d: %s; p50 %s" % (enc, len(bs), ", ".join(cells), ", ".join(ratios)))
    if not files:
        return
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing: no plot")
        return
    cols = max(len(f[1]) for f in files)
    fig, axes = plt.subplots(len(files), cols, figsize=(4.6 * cols, 3.2 * len(files)), sharey=True, squeeze=False)
    for row, (name, by_enc, modes) in enumerate(files):
        for col in range(cols):
            ax = axes[row][col]
            if col >= len(by_enc):
                ax.axis("off")
                continue
            enc, bs = sorted(by_enc.items())[col]
            for i, (m, label) in enumerate(modes):
                xs = [i + 0.1 * (j - len(bs) / 2) for j in range(len(bs))]
                ax.scatter(xs, [b[m + "_p50_us"] for b in bs], marker="o", color="C%d" % i, label=label + " p50")
                ax.scatter(xs, [b[m + "_p99_us"] for b in bs], marker="^", color="C%d" % i, alpha=0.4)
            ax.set_xticks(range(len(modes)))
            ax.set_xticklabels([m[1].replace("stack, ", "stack,\n") for m in modes], fontsize=7)
            ax.set_yscale("log")
            ax.set_title("%s, %s (o p50, ^ p99, a dot a repetition)" % (name, enc), fontsize=7)
            ax.grid(True, which="both", alpha=0.3)
        axes[row][0].set_ylabel("one-way latency (us)")
    fig.tight_layout()
    fig.savefig(os.path.join(d, "net_oneway_periodic.png"), dpi=100)


UNIT_US = {"ns": 1e-3, "us": 1.0, "ms": 1e3, "s": 1e6}
SOLVERS = {0: "auto", 1: "direct LDL^T", 2: "Jacobi-PCG", 3: "dense, factored once", 4: "CHOLMOD, factored once"}


def cpu_us(b):
    return b["cpu_time"] * UNIT_US[b.get("time_unit", "us")]


def tick_ratios(m):
    """The tick's target ratios (tools/bench/results/README.md), each within this one run (medians of CPU time)."""
    def t(name):
        return cpu_us(m[name]) if name in m else None

    def line(text, a, b):
        if a is not None and b is not None:
            print("%-62s %10.2f / %10.2f us = %.2fx" % (text, a, b, a / b))

    line("2945 nodes: auto (%s) / direct LDL^T" % m.get("BM_Tick/3000/0", {}).get("label", "?"), t("BM_Tick/3000/0"), t("BM_Tick/3000/1"))
    line("2945 nodes: worst case (neighbour set changing) / typical", t("BM_TickWorstCase/3000/0"), t("BM_Tick/3000/0"))
    for s in (1, 2, 3, 4):
        line("2945 nodes: %s / auto" % SOLVERS[s], t("BM_Tick/3000/%d" % s), t("BM_Tick/3000/0"))
    for s in (0, 2, 3, 4):
        line("33 nodes: %s / direct LDL^T" % SOLVERS[s], t("BM_Tick/33/%d" % s), t("BM_Tick/33/1"))
    line("33 nodes: the refactor-every-tick dense strawman / direct", t("BM_DenseRefactorEveryTick/33"), t("BM_Tick/33/1"))
    line("33 nodes: worst case / typical", t("BM_TickWorstCase/33/0"), t("BM_Tick/33/0"))
    if "BM_Tick/10000/0" in m:
        print("%-62s %10.2f us (target 1000 us)" % ("9915 nodes: auto", t("BM_Tick/10000/0")))
    for n, b in sorted(m.items()):
        if n.startswith("BM_StartupToFirstTick/"):
            print("%-62s %10.3f s CPU, %.3f s wall (target < 3 s)" % (n.split("/iter")[0], cpu_us(b) * 1e-6,
                                                                      b["real_time"] * UNIT_US[b.get("time_unit", "us")] * 1e-6))
    peak = {}
    for n, b in sorted(m.items()):
        if n.startswith("BM_StationPeakMemory/") and "station_peak_MB" in b:
            _, nodes, deg, solver = n.split("/iter")[0].split("/")
            peak[(int(deg), int(solver))] = b["station_peak_MB"]
            print("%-62s peak %7.2f MB, heap %7.2f MB" % ("peak memory, %s nodes, %s neighbours, %s" % (nodes, deg, SOLVERS[int(solver)]),
                                                            b["station_peak_MB"], b.get("station_heap_MB", float("nan"))))
    for solver in (0, 1):
        if (6, solver) in peak and (1, solver) in peak and peak[(1, solver)] > 0:
            print("%-62s %.2fx (target <= 3x)" % ("peak memory 6 / 1 neighbours, %s" % SOLVERS[solver], peak[(6, solver)] / peak[(1, solver)]))


def main(d):
    net_oneway(d)
    p = os.path.join(d, "rt_tick.json")
    if not os.path.exists(p):
        print("no rt_tick.json in", d)
        return
    m, ctx = medians(p)
    print("machine: %s CPUs, load avg %s, %s" % (ctx.get("num_cpus"), ctx.get("load_avg"), ctx.get("date")))
    for name, b in sorted(m.items()):
        unit = b.get("time_unit", "us")
        print("%-45s real %10.2f %s   cpu %10.2f %s  %s" % (name, b["real_time"], unit, b["cpu_time"], unit, b.get("label", "")))
    tick_ratios(m)
    curves = {}
    for n, b in m.items():
        parts = n.split("/")
        if parts[0] == "BM_Tick" and len(parts) == 3 and int(parts[2]) in (0, 1, 2, 4):
            curves.setdefault(int(parts[2]), []).append((int(b.get("nodes", parts[1])), cpu_us(b)))
    if curves:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6, 4))
            for s, style in ((0, "o-"), (1, "s--"), (2, "^--"), (4, "d:")):
                if s in curves:
                    pts = sorted(curves[s])
                    ax.loglog([x for x, _ in pts], [y for _, y in pts], style, label="%s (cpu, median)" % SOLVERS[s])
            ax.axhline(1000, color="r", ls=":", label="1 ms target")
            ax.axhline(2000, color="k", ls=":", label="2 ms period")
            ax.set_xlabel("scene nodes")
            ax.set_ylabel("station tick (us)")
            ax.set_title("bench-rt-tick, one run (%s)" % ctx.get("date", "")[:16], fontsize=9)
            ax.legend(fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
            fig.tight_layout()
            fig.savefig(os.path.join(d, "rt_tick_scaling.png"), dpi=100)
        except ImportError:
            print("matplotlib missing: no plot")


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    main(sys.argv[1])
