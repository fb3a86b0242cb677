#!/usr/bin/python3
"""Chart of the tick against nodes from one bench-rt-tick JSON: ours (BM_Tick/N/0, auto), CHOLMOD
factored once (BM_Tick/N/4), Eigen's Jacobi CG (BM_Tick/N/5) and the floor (BM_TickFloor/N: one
pass reading as many bytes as the tick touches). CPU time; the median when the JSON has repetitions.

Usage: plot_tick_floor.py JSON PNG
"""
import collections
import json
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

src, out = sys.argv[1], sys.argv[2]
data = json.load(open(src))
series = collections.defaultdict(lambda: collections.defaultdict(list))
label = {"0": "ours (auto)", "4": "CHOLMOD, factored once", "5": "Eigen Jacobi CG", "floor": "floor: one read of the bytes the tick touches"}
for b in data["benchmarks"]:
    if b.get("run_type") == "aggregate" or "error_occurred" in b:
        continue
    parts = b["name"].split("/")
    scale = {"us": 1.0, "ms": 1e3, "ns": 1e-3}[b["time_unit"]]
    if parts[0] == "BM_Tick" and parts[2] in ("0", "4", "5"):
        series[parts[2]][int(b["nodes"])].append(b["cpu_time"] * scale)
    elif parts[0] == "BM_TickFloor":
        series["floor"][int(b["nodes"])].append(b["cpu_time"] * scale)
fig, ax = plt.subplots(figsize=(7, 4.5))
for key, style in (("0", "o-"), ("4", "s--"), ("5", "^--"), ("floor", "k:")):
    pts = sorted((n, statistics.median(v)) for n, v in series[key].items())
    if pts:
        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, label=label[key])
        for n, t in pts:
            print("%-6s %6d nodes %10.1f us" % (key, n, t))
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("nodes")
ax.set_ylabel("CPU time per tick (us)")
ax.axhline(1000, color="grey", lw=0.5)
ax.set_title("Station tick (3 neighbours, contact) against nodes")
ax.legend(fontsize=8)
ax.grid(True, which="both", lw=0.3)
fig.tight_layout()
fig.savefig(out, dpi=110)
