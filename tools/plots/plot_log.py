#!/usr/bin/python3
"""Fields of one or more stations' session logs on one run-time axis (`haptic-station log plot`).

usage: /usr/bin/python3 tools/plots/plot_log.py --out PNG --field NAME UNITS [--field ...] LABEL=CSV [LABEL=CSV ...]

Each CSV is `haptic-station log export LOG --field ...` of one station: a header naming each column
with its unit (t_s, force_x_N, ...), one row per tick, t_s the run time at the end of the tick. All the
stations of a run share the run clock (tick k of every station is at k T from the run's start), so
their rows are drawn on one time axis: one panel per field (its components x, y, z as solid, dashed,
dotted lines), one colour per station. The recorded rows are drawn, nothing is re-run.
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main(argv):
    out, fields, logs = None, [], []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--out":
            out = argv[i + 1]
            i += 2
        elif a == "--field":
            fields.append((argv[i + 1], argv[i + 2]))
            i += 3
        else:
            label, _, path = a.partition("=")
            logs.append((label, path))
            i += 1
    if not out or not fields or not logs:
        print(__doc__, file=sys.stderr)
        return 2
    fig, axes = plt.subplots(len(fields), 1, figsize=(9, 2.4 * len(fields) + 0.6), sharex=True, squeeze=False)
    styles = ["-", "--", ":"]
    for s, (label, path) in enumerate(logs):
        with open(path) as f:
            header = f.readline().strip().split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        t = data[:, header.index("t_s")]
        colour = "C%d" % (s % 10)
        for ax, (name, units) in zip(axes[:, 0], fields):
            cols = [j for j, c in enumerate(header) if c == name or c.startswith(name + "_")]
            for n, j in enumerate(cols):
                ax.plot(t, data[:, j], styles[n % 3], color=colour, lw=0.9, label=label if n == 0 else None)
    for ax, (name, units) in zip(axes[:, 0], fields):
        ax.set_ylabel("%s (%s)" % (name, units) if units not in ("", "1") else name)
        ax.grid(alpha=0.3)
        if any(c.startswith(name + "_x") for c in header):
            ax.set_title("x solid, y dashed, z dotted", fontsize=8, loc="left")
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=min(len(logs), 4))
    axes[-1, 0].set_xlabel("run time (s)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print("wrote %s (%d station(s), %d field(s))" % (out, len(logs), len(fields)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
