#!/usr/bin/python3
"""Charts of the speed-against-accuracy study (tools/study/README.md). Run with Debian's python:
    /usr/bin/python3 tools/study/plot_study.py [results_dir]
Reads accuracy.csv, energy.csv, stability.csv, consensus.csv (any that exist) and writes PNGs
next to them."""
import csv
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402

DPI = 90
INTEGRATORS = ["npmi", "explicit-euler", "semi-implicit-euler", "backward-euler", "rk4"]
COLORS = {"npmi": "tab:blue", "explicit-euler": "tab:red", "semi-implicit-euler": "tab:orange",
          "backward-euler": "tab:green", "rk4": "tab:purple", "modal": "tab:gray", "modal+sc": "tab:brown"}


def read(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def f(x):
    return float(x) if x not in ("inf", "nan") else (math.inf if x == "inf" else math.nan)


def pareto(points):
    pts = sorted([p for p in points if math.isfinite(p[1]) and p[1] > 0], key=lambda p: p[0])
    front, best = [], math.inf
    for p in pts:
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def plot_accuracy(d):
    rows = read(os.path.join(d, "accuracy.csv"))
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    for ax, key, title in [(axes[0], "force_error_self", "integration error (vs the same model's exact solution)"),
                           (axes[1], "force_error_ref", "total error (vs the finest mesh's exact solution)")]:
        pts = []
        sizes = sorted({int(r["nodes"]) for r in rows})
        for r in rows:
            e, load = f(r[key]), f(r["cpu_load"])
            if not math.isfinite(e) or e <= 0:
                continue
            kind = r["kind"] if r["kind"] != "mesh" else r["integrator"]
            ms = 3 + 2 * sizes.index(int(r["nodes"])) if r["kind"] == "mesh" else 3 + math.log2(int(r["modes"]))
            ax.scatter(load, e, s=ms * 4, c=COLORS.get(kind, "k"), alpha=0.55,
                       marker="o" if r["kind"] == "mesh" else ("s" if r["kind"] == "modal" else "D"), linewidths=0)
            pts.append((load, e, r))
        front = pareto(pts)
        ax.plot([p[0] for p in front], [p[1] for p in front], "k-", lw=1.2, label="Pareto front")
        for p in front[:: max(1, len(front) // 8)]:
            r = p[2]
            lab = (f"{r['integrator']} n{r['nodes']}" if r["kind"] == "mesh" else f"{r['kind']} r{r['modes']}") + \
                f" {1e3 * f(r['step_s']):g}ms"
            ax.annotate(lab, (p[0], p[1]), fontsize=6, xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU load at real time = cost per tick / step")
        ax.set_ylabel("max relative felt-force error")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
    for k, c in COLORS.items():
        axes[0].scatter([], [], c=c, label=k)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Speed against accuracy: push problem, meshes 33..3000 nodes (marker size), steps 0.25..8 ms, "
                 "modal r (squares; diamonds: + static correction)", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "pareto.png"), dpi=DPI)
    plt.close(fig)


def plot_energy(d):
    rows = read(os.path.join(d, "energy.csv"))
    series = defaultdict(lambda: ([], []))
    for r in rows:
        s = series[(r["integrator"], f(r["step_s"]))]
        s[0].append(f(r["t_s"]))
        s[1].append(f(r["energy_ratio"]))
    steps = sorted({k[1] for k in series}, reverse=True)
    fig, axes = plt.subplots(1, len(steps), figsize=(6 * len(steps), 4.2), squeeze=False)
    for ax, h in zip(axes[0], steps):
        for m in INTEGRATORS:
            if (m, h) in series:
                t, e = series[(m, h)]
                ax.plot(t, e, label=m, c=COLORS[m], lw=1)
        ax.set_yscale("log")
        ax.set_ylim(1e-3, 1e6)
        ax.set_xlabel("t (s)")
        ax.set_ylabel("E(t) / E(0)")
        ax.set_title(f"energy drift, free vibration, B = 0, h = {h * 1e3:g} ms", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "energy_drift.png"), dpi=DPI)
    plt.close(fig)
    # Passivity failure: explicit Euler beside NPMI on the same scene and step.
    h = 0.002 if ("npmi", 0.002) in series else steps[0]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for m in ["explicit-euler", "semi-implicit-euler", "npmi"]:
        t, e = series[(m, h)]
        axes[0].plot(t, [max(abs(x - 1), 1e-16) for x in e], c=COLORS[m], label=m)
    axes[0].set_yscale("log")
    axes[0].set_ylim(1e-17, 1e7)
    axes[0].set_xlim(0, 2.0)
    axes[0].set_xlabel("t (s)")
    axes[0].set_ylabel("|E(t) - E(0)| / E(0)  (floor 1e-16)")
    axes[0].set_title(f"passivity failure: explicit Euler generates energy; 33-node ball, h = {h * 1e3:g} ms", fontsize=9)
    axes[0].legend(fontsize=8)
    axes[0].grid(True, alpha=0.3)
    t, e = series[("npmi", h)]
    axes[1].plot(t, [x - 1 for x in e], c=COLORS["npmi"])
    axes[1].set_xlabel("t (s)")
    axes[1].set_ylabel("NPMI: E(t)/E(0) - 1")
    axes[1].set_title("NPMI over the whole run: bounded at round-off", fontsize=9)
    axes[1].grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "passivity_failure.png"), dpi=DPI)
    plt.close(fig)


CLASSES = ["stable", "bounded", "dissipative", "grows", "blows-up"]
CLASS_COLORS = ["#4caf50", "#a5d6a7", "#90caf9", "#ffb74d", "#e53935"]


def plot_stability(d):
    rows = read(os.path.join(d, "stability.csv"))
    axes_names = ["stiffness_scale", "nodes"]
    fig, axes = plt.subplots(2, 5, figsize=(16, 6.5), squeeze=False)
    cmap = ListedColormap(CLASS_COLORS)
    for i, axis in enumerate(axes_names):
        sub = [r for r in rows if r["axis"] == axis]
        values = sorted({f(r["value"]) for r in sub})
        steps = sorted({f(r["step_s"]) for r in sub})
        for j, m in enumerate(INTEGRATORS):
            ax = axes[i][j]
            grid = [[math.nan] * len(steps) for _ in values]
            for r in sub:
                if r["integrator"] == m:
                    grid[values.index(f(r["value"]))][steps.index(f(r["step_s"]))] = CLASSES.index(r["class"])
            ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=len(CLASSES) - 0.5, origin="lower", aspect="auto")
            ax.set_xticks(range(len(steps)), [f"{s * 1e3:g}" for s in steps], fontsize=7)
            ax.set_yticks(range(len(values)), [f"{v:g}" for v in values], fontsize=7)
            if i == 1:
                ax.set_xlabel("step (ms)", fontsize=8)
            if j == 0:
                ax.set_ylabel("edge stiffness x" if axis == "stiffness_scale" else "scene nodes", fontsize=8)
            ax.set_title(m, fontsize=9)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in CLASS_COLORS]
    fig.legend(handles, CLASSES, loc="lower center", ncol=5, fontsize=8)
    fig.suptitle("Where each method blows up: free vibration from the static push deformation, B = 0, 2 s", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(os.path.join(d, "stability_map.png"), dpi=DPI)
    plt.close(fig)


CON_CLASSES = ["stable", "energy-generated", "diverged"]


def plot_consensus(d):
    rows = read(os.path.join(d, "consensus.csv"))
    gains = sorted({(f(r["p_gain"]), f(r["d_gain"])) for r in rows})
    losses = sorted({f(r["loss"]) for r in rows})
    fig, axes = plt.subplots(len(gains), len(losses), figsize=(4.6 * len(losses), 3.8 * len(gains)), squeeze=False)
    cmap = ListedColormap(["#4caf50", "#ffb74d", "#e53935"])
    for i, g in enumerate(gains):
        for j, loss in enumerate(losses):
            sub = [r for r in rows if (f(r["p_gain"]), f(r["d_gain"])) == g and f(r["loss"]) == loss]
            ds = sorted({f(r["delay_scale"]) for r in sub})
            bs = sorted({f(r["damping_scale"]) for r in sub})
            grid = [[math.nan] * len(ds) for _ in bs]
            for r in sub:
                grid[bs.index(f(r["damping_scale"]))][ds.index(f(r["delay_scale"]))] = CON_CLASSES.index(r["class"])
            ax = axes[i][j]
            ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=2.5, origin="lower", aspect="auto")
            ax.set_xticks(range(len(ds)), [f"{x:g}" for x in ds], fontsize=7)
            ax.set_yticks(range(len(bs)), [f"{x:g}" for x in bs], fontsize=7)
            if 1.0 in bs:
                y = bs.index(1.0)
                ax.axhline(y, color="k", lw=1.5, ls="--")
                ax.text(len(ds) - 0.5, y + 0.1, "eq. (18)", ha="right", va="bottom", fontsize=7)
            ax.set_title(f"P = {g[0]:g} N/m, D = {g[1]:g} Ns/m, loss {loss * 100:g}%", fontsize=9)
            ax.set_xlabel("delay scale (x paper matrix)", fontsize=8)
            ax.set_ylabel("B_i / eq. (18) value", fontsize=8)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in ["#4caf50", "#ffb74d", "#e53935"]]
    fig.legend(handles, CON_CLASSES, loc="lower center", ncol=3, fontsize=8)
    fig.suptitle("4-user consensus (paper topology, random passive users): stability over damping and delay", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(os.path.join(d, "consensus_map.png"), dpi=DPI)
    plt.close(fig)


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
    for name, fn in [("accuracy.csv", plot_accuracy), ("energy.csv", plot_energy), ("stability.csv", plot_stability),
                     ("consensus.csv", plot_consensus)]:
        if os.path.exists(os.path.join(d, name)):
            fn(d)
            print("plotted", name)
        else:
            print("skipped", name, "(not found)")


if __name__ == "__main__":
    main()
