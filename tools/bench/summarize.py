#!/usr/bin/python3
"""Prints the medians of tools/bench/results/rt_tick.json and the ratios the issues ask for,
and draws tick cost against scene size (rt_tick_scaling.png).

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


def main(d):
    p = os.path.join(d, "rt_tick.json")
    if not os.path.exists(p):
        print("no rt_tick.json in", d)
        return
    m, ctx = medians(p)
    print("machine: %s CPUs, load avg %s" % (ctx.get("num_cpus"), ctx.get("load_avg")))
    for name, b in sorted(m.items()):
        print("%-45s real %10.2f us   cpu %10.2f us" % (name, b["real_time"], b["cpu_time"]))
    s33 = m.get("BM_SparseTick/33")
    d33 = m.get("BM_DenseBaselineTick/33")
    if s33 and d33:
        print("33-node tick: sparse %.2f us, dense baseline %.2f us (cpu): dense/sparse = %.1fx" %
              (s33["cpu_time"], d33["cpu_time"], d33["cpu_time"] / s33["cpu_time"]))
    sizes = sorted((int(b.get("nodes", 0)), b["cpu_time"]) for n, b in m.items() if n.startswith("BM_SparseTick/"))
    if sizes:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6, 4))
            ax.loglog([s for s, _ in sizes], [t for _, t in sizes], "o-", label="sparse tick (cpu, median)")
            dense = sorted((int(b.get("nodes", 0)), b["cpu_time"]) for n, b in m.items() if n.startswith("BM_DenseBaselineTick/"))
            if dense:
                ax.loglog([s for s, _ in dense], [t for _, t in dense], "s--", label="dense baseline")
            ax.axhline(1000, color="r", ls=":", label="1 ms target")
            ax.axhline(2000, color="k", ls=":", label="2 ms period")
            ax.set_xlabel("scene nodes")
            ax.set_ylabel("tick cost (us)")
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
