#!/usr/bin/env python3
"""Speed against accuracy of the iterative step solve (bench-rt-tick's BM_TickTolerance):
left, tick CPU time against the CG tolerance; right, tick CPU time against the solver residual's
energy per tick relative to the controller port's (eq. 14), one curve per scene size.

  build/bin/bench-rt-tick --benchmark_filter=BM_TickTolerance --benchmark_min_time=0.2 \
      --benchmark_out=tools/bench/results/rt_tick_tolerance.json --benchmark_out_format=json
  tools/bench/plot_tolerance.py tools/bench/results/rt_tick_tolerance.json tools/bench/results/rt_tick_tolerance.png
"""
import json
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        data = json.load(f)
    rows = defaultdict(list)
    for b in data["benchmarks"]:
        if not b["name"].startswith("BM_TickTolerance/") or b.get("error_occurred") or b.get("run_type") == "aggregate":
            continue
        scale = {"ns": 1e-3, "us": 1.0, "ms": 1e3}[b["time_unit"]]
        rows[int(b["nodes"])].append((b["tolerance"], b["cpu_time"] * scale, b["residual_over_controller"], b["iterations_mean"]))
    if not rows:
        sys.exit("no BM_TickTolerance results in " + sys.argv[1])
    fig, (a, c) = plt.subplots(1, 2, figsize=(11, 4.2))
    for nodes in sorted(rows):
        r = sorted(rows[nodes])
        tol = [x[0] for x in r]
        us = [x[1] for x in r]
        rel = [max(x[2], 1e-18) for x in r]
        a.plot(tol, us, "o-", label=f"{nodes} nodes")
        for t, u, it in zip(tol, us, [x[3] for x in r]):
            a.annotate(f"{it:.1f} it", (t, u), textcoords="offset points", xytext=(3, 4), fontsize=7)
        c.plot(rel, us, "o-", label=f"{nodes} nodes")
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel("CG tolerance  |b - A v|/|b|")
    a.set_ylabel("tick CPU time (us)")
    a.set_title("tick time vs tolerance (labels: CG iterations per tick)")
    a.invert_xaxis()
    a.axhline(1000, color="grey", ls="--", lw=0.8)
    c.set_xscale("log")
    c.set_yscale("log")
    c.set_xlabel("|residual energy| / |controller energy| per tick")
    c.set_ylabel("tick CPU time (us)")
    c.set_title("tick time vs accuracy")
    c.invert_xaxis()
    c.axhline(1000, color="grey", ls="--", lw=0.8)
    for ax in (a, c):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
