#!/usr/bin/python3
"""Checks the figures plot_run.py draws for RUN_DIR against the run's own files,
then writes them (PNG) like plot_run.py does.

usage: /usr/bin/python3 tools/plots/check_figures.py RUN_DIR

- all five figures exist (a real run's merged directory as well as a simulated one);
- the node figure names the traced node and plots its x-DISPLACEMENT from rest:
  1e3 (node_x - rest_x) of trace.csv per user, not its position;
- the release and push-end lines and the consensus threshold carry text labels;
- every drawn time series of the node figure is made of samples and keeps each time slice's extremes;
- the snapshot figure says which users' copies it shows (all, or users 1-8 of N), has a scale in mm, a colour bar, and colours each surface triangle by the
  mean distance of its corners from the mean shape of ALL copies (snapshots.json's
  distance_from_mean_shape_m, written by the run), on one scale for the whole figure.
Exit 0 when all hold, 1 with every failure listed.
"""
import json
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_run  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402


def texts(fig):
    return [t.get_text() for ax in fig.axes for t in ax.texts]


def check_node(fig, summary, tr, fail):
    ax = fig.axes[0]
    node = int(summary["trace_node"])
    if ("node %d" % node) not in ax.get_ylabel() or "displacement" not in ax.get_ylabel():
        fail.append("node figure's y label %r does not name node %d's displacement" % (ax.get_ylabel(), node))
    rest_x = summary["trace_node_rest_m"][0]
    lines = [l for l in ax.get_lines() if l.get_label().startswith("user")]
    if len(lines) != int(summary["users"]):
        fail.append("node figure: %d user lines for %d users" % (len(lines), summary["users"]))
    for u, line in enumerate(lines, start=1):
        m = tr["user"] == u
        check_samples(line, tr["t_s"][m], 1e3 * (tr["node_x_m"][m] - rest_x), "node figure: user %d's line" % u, fail)


def check_samples(line, t, want, what, fail):
    """A drawn time series against its data: every drawn point is the sample at its time, and for
    each of 200 equal time slices the drawn line, within a decimation bucket of it, reaches the
    slice's lowest and highest sample (plot_run.decimate keeps each bucket's extremes)."""
    x, y = np.asarray(line.get_xdata(), dtype=float), np.asarray(line.get_ydata(), dtype=float)
    at = np.searchsorted(t, x)
    if len(x) == 0 or np.any(at >= len(t)) or not np.allclose(t[np.minimum(at, len(t) - 1)], x, rtol=0, atol=1e-12):
        fail.append("%s: drawn at times that are not sample times" % what)
        return
    if not np.allclose(y, want[at], rtol=0, atol=1e-9):
        fail.append("%s is not 1e3 (node_x - rest_x) (max diff %.3g mm)" % (what, np.max(np.abs(y - want[at]))))
        return
    edges = np.linspace(t[0], t[-1], 201)
    bucket = 1.5 * (t[-1] - t[0]) / plot_run.LINE_BUCKETS
    for a, b in zip(edges[:-1], edges[1:]):
        w = want[(t >= a) & (t < b)]
        d = y[(x >= a - bucket) & (x < b + bucket)]
        if len(w) and (len(d) == 0 or d.min() > w.min() or d.max() < w.max()):
            fail.append("%s: %.3f-%.3f s: drawn range %s misses the samples' %.6g..%.6g (an extreme left out)" % (
                what, a, b, "%.6g..%.6g" % (d.min(), d.max()) if len(d) else "empty", w.min(), w.max()))
            return


def check_labels(figs, summary, fail):
    need = {"fig_node_position.png": ["release"], "fig_consensus.png": ["release", "consensus threshold"],
            "fig_energy.png": ["passivity bound"]}
    if summary.get("push_end_s"):
        need["fig_node_position.png"].append("push ends")
    for name, words in need.items():
        t = " | ".join(texts(figs[name]))
        for w in words:
            if w not in t:
                fail.append("%s: no %r label (texts: %s)" % (name, w, t))


def expected_face_colours(sn, users, cols):
    import matplotlib
    from matplotlib import colors
    surf = np.array(sn["surface"])
    dist = [plot_run.mean_shape_distance_mm(s) for s in sn["snapshots"]]  # the run's own values (C++)
    norm = colors.Normalize(0, max(max(d.max() for d in dist), 1e-12))
    cmap = matplotlib.colormaps["viridis"]
    return [[cmap(norm(d[u][surf].mean(axis=1)), alpha=0.85) for u in range(cols)] for d in dist]


def check_snapshots(fig, summary, sn, fail):
    users = int(summary["users"])
    cols = min(users, plot_run.MAX_COPIES_DRAWN)
    ax = next((a for a in fig.axes if a.get_label() == "snapshots"), None)
    panels = {c.get_gid(): c for c in (ax.collections if ax else []) if isinstance(c, PolyCollection) and c.get_gid()}
    if len(panels) != cols * len(sn["snapshots"]):
        fail.append("snapshot figure: %d panels for %d snapshots x %d copies" % (len(panels), len(sn["snapshots"]), cols))
        return
    if not any(re.match(r"\d+ mm; view", t.get_text()) for t in ax.texts):  # plot_run.draw_scale's bar label
        fail.append("snapshot figure: no scale in mm")
    bars = [a for a in fig.axes if a is not ax and "mean shape" in a.get_ylabel()]
    if not bars:
        fail.append("snapshot figure: no colour bar labelled with the distance from the mean shape")
    title = fig._suptitle.get_text() if fig._suptitle else ""
    says = ("users 1-%d's copies (of %d users" % (cols, users)) if cols < users else ("all %d copies" % users)
    if says not in title:
        fail.append("snapshot figure: the title does not say which copies it shows (%r not in %r)" % (says, title))
    want = expected_face_colours(sn, users, cols)
    for r in range(len(sn["snapshots"])):
        for u in range(cols):
            poly = panels.get("snapshot %d %d" % (r, u))
            got = np.asarray(poly.get_facecolor()) if poly is not None else np.zeros((0, 4))
            exp = np.asarray(want[r][u])
            # the drawn order is by depth: compare the colours as sorted sets
            if got.shape != exp.shape or not np.allclose(np.array(sorted(map(tuple, got))), np.array(sorted(map(tuple, exp))), atol=1e-6):
                fail.append("snapshot figure: t = %.2f s user %d: face colours are not the distance from the mean shape" % (
                    sn["snapshots"][r]["t_s"], u + 1))


def main(run):
    figs = plot_run.figures(run)
    summary = json.load(open(os.path.join(run, "summary.json")))
    tr = plot_run.load_csv(os.path.join(run, "trace.csv"))
    fail = []
    for name in ("fig_node_position.png", "fig_device_force.png", "fig_energy.png", "fig_consensus.png", "fig_snapshots.png"):
        if name not in figs:
            fail.append("%s not drawn (snapshots.json missing?)" % name)
    if not fail:
        check_node(figs["fig_node_position.png"], summary, tr, fail)
        check_labels(figs, summary, fail)
        check_snapshots(figs["fig_snapshots.png"], summary, json.load(open(os.path.join(run, "snapshots.json"))), fail)
    for name, fig in figs.items():
        fig.savefig(os.path.join(run, name), dpi=100 if name == "fig_snapshots.png" else 110)
    if fail:
        print("FAILED (%s):\n  %s" % (run, "\n  ".join(fail)))
        return 1
    print("figures ok (%s): %s; node %d displacement, labelled events, snapshot colours = distance from the mean shape" % (
        summary.get("mode", "sim"), ", ".join(sorted(figs)), summary["trace_node"]))
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    sys.exit(main(sys.argv[1]))
