#!/usr/bin/python3
"""Draw the best and worst graphs of a haptic-topology JSON (like the paper's Fig. 7).

Usage: /usr/bin/python3 plot_topology.py ranked.json out.png
Edge labels: mean round-trip delay (mean_ij + mean_ji, ms) of the link; title: |lambda_{n+1}|.
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def layout(data):
    n = data["users"]
    if "positions_km" in data:
        return [tuple(p) for p in data["positions_km"]]
    # users on a circle, user 1 at the top left like Fig. 7's square
    return [(math.cos(math.pi * 0.75 - 2 * math.pi * i / n), math.sin(math.pi * 0.75 - 2 * math.pi * i / n))
            for i in range(n)]


def draw(ax, data, row, pos):
    d = data["mean_delay_ms"]
    n = data["users"]
    small = n <= 12
    for a, b in row["edges"]:
        (x1, y1), (x2, y2) = pos[a - 1], pos[b - 1]
        ax.plot([x1, x2], [y1, y2], "-", color="tab:blue", lw=2 if small else 1, zorder=1)
        rt = (d[a - 1][b - 1] or 0) + (d[b - 1][a - 1] or 0)
        if small or n <= 32:
            ax.text((x1 + x2) / 2, (y1 + y2) / 2, f"{rt:.0f}", fontsize=10 if small else 6,
                    ha="center", va="center", bbox=dict(fc="white", ec="none", alpha=0.8, pad=0.5), zorder=3)
    xs, ys = zip(*pos)
    ax.scatter(xs, ys, s=500 if small else 60, color="tab:orange", zorder=2, edgecolors="k")
    for i, (x, y) in enumerate(pos):
        ax.text(x, y, str(i + 1), ha="center", va="center", fontsize=12 if small else 6, zorder=4)
    ax.set_title(f"{row['label'] or 'rank ' + str(row['rank'])}: |lambda_n+1| = {row['lambda_next_abs']:.6f}\n"
                 f"eq.(18) sums (ms): {', '.join(f'{v:.0f}' for v in row['eq18_round_trip_sum_ms'])}"
                 if small else f"{row['label']}: |lambda_n+1| = {row['lambda_next_abs']:.6f}", fontsize=9)
    ax.set_aspect("equal")
    ax.margins(0.15)
    ax.set_xticks([])
    ax.set_yticks([])


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        data = json.load(f)
    rows = data["ranked"]
    pos = layout(data)
    pick = [rows[0]] + ([rows[-1]] if len(rows) > 1 else [])
    fig, axes = plt.subplots(1, len(pick), figsize=(5.5 * len(pick), 5.2))
    if len(pick) == 1:
        axes = [axes]
    for ax, row in zip(axes, pick):
        draw(ax, data, row, pos)
    fig.suptitle(f"haptic-topology: {data['users']} users, T = {data['period_ms']} ms, "
                 f"{data['delay_source']}\nlabels: mean round-trip delay of the link (ms)", fontsize=9)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
