#!/usr/bin/python3
"""Figures of one haptic-station run directory (in the spirit of the paper's Figs. 8-10).

usage: /usr/bin/python3 tools/plots/plot_run.py [--after-go [--expect SNAPSHOTS USERS]] RUN_DIR

Reads RUN_DIR/trace.csv, series.csv, summary.json and (if present) snapshots.json, written alike by
`haptic-station sim` and by `haptic-station merge` after a real (multi-process) run, and writes
fig_node_position.png (the traced node's displacement from rest), fig_device_force.png,
fig_energy.png, fig_consensus.png and fig_snapshots.png (the copies coloured by their distance
from the mean shape) into RUN_DIR.

Speed (tools/bench/results/README.md "Figures"): one process imports matplotlib once, reads the CSV
files with numpy's C parser, draws each time series min/max-decimated to the figure's resolution
(every drawn point is a sample; each pixel column's extremes are kept), writes PNG at compression
level 1, lays the figures out with fixed margins (no tight_layout), draws the snapshot panels as
orthographic 2D projections in one axes (one matplotlib Axes a panel cost ~30 ms) and, with a CPU
idle, draws two of the figures in a forked child while it draws the others. --after-go imports, warms up and makes
the figures' empty axes (the snapshot figure's when --expect says how many snapshots and users) first,
then waits for a line "go" on stdin before reading RUN_DIR: `haptic-station sim` starts it before
the simulation, so all that overlaps the run; end of input without "go" (the run failed) draws nothing.
"""
import json
import os
import signal
import sys

if sys.argv[1:2] == ["--after-go"]:
    # Ctrl-C in the terminal reaches the run and this script alike, even while it imports: the run
    # ends, and with it this script's input (end of input: nothing drawn, no traceback)
    signal.signal(signal.SIGINT, signal.SIG_IGN)

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import cm, colors  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402  (no pyplot: no global figure manager to import or keep)

MAX_COPIES_DRAWN = 8  # a 64-user run: the snapshot figure draws users 1-8 and says so (the mean shape uses all)
LINE_BUCKETS = 1000  # a time axis is at most 880 px wide (8 in at 110 dpi): min and max of 1000 columns per line


def load_csv(path):
    """The CSV's columns by header name, as float arrays (np.loadtxt's C parser: a fraction of
    genfromtxt's time and memory)."""
    with open(path) as f:
        names = f.readline().strip().split(",")
    a = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if a.size == 0:
        a = np.zeros((0, len(names)))
    return {n: a[:, i] for i, n in enumerate(names)}


def decimate(t, y, buckets=LINE_BUCKETS):
    """(t, y) with at most two samples per bucket of equal sample count: each bucket's lowest and
    highest, in time order, and the first and last sample. Every drawn point is a sample and every
    bucket's extremes are drawn, so at the figure's resolution the line looks the same."""
    t, y = np.asarray(t), np.asarray(y)
    n = len(y)
    if n <= 2 * buckets:
        return t, y
    k = n // buckets
    m = k * buckets
    block = y[:m].reshape(buckets, k)
    base = np.arange(buckets) * k
    idx = [base + block.argmin(axis=1), base + block.argmax(axis=1), [0, n - 1]]
    if m < n:
        idx.append([m + int(np.argmin(y[m:])), m + int(np.argmax(y[m:]))])
    keep = np.unique(np.concatenate(idx))
    return t[keep], y[keep]


def plot_line(ax, t, y, *args, **kw):
    """ax.plot of a time series, decimated (decimate())."""
    return ax.plot(*decimate(t, y), *args, **kw)


def run_title(summary):
    users = int(summary["users"])
    b = summary["damping_Ns_per_m"]
    if users > 8:  # a long title would cover the figure
        return "%s: %d users, %d links, B = %.1f..%.1f N s/m" % (summary["scenario"], users, len(summary["topology"]), min(b), max(b))
    return "%s: %s, B = (%s) N s/m" % (summary["scenario"], "topology " + " ".join("%d-%d" % tuple(l) for l in summary["topology"]),
                                       ", ".join("%.1f" % x for x in b))


def script_lines(summary):
    """The script's event times drawn on every time axis: (time, label, colour)."""
    out = []
    push_end, rel = summary.get("push_end_s"), summary.get("release_time_s")
    if push_end and (not rel or push_end < rel):
        out.append((push_end, "push ends %.3g s" % push_end, "0.55"))
    if rel and rel < summary.get("simulated_s", summary.get("duration_s", rel + 1)):
        out.append((rel, "release %.3g s" % rel, "tab:purple"))
    return out


def mark_events(ax, summary, label_them=True, at="top"):
    """Vertical lines at the script's events, each labelled next to the line (at the top or bottom)."""
    for t, label, c in script_lines(summary):
        ax.axvline(t, color=c, ls="--", lw=0.9)
        if label_them:
            y, va = (0.98, "top") if at == "top" else (0.02, "bottom")
            ax.annotate(label, xy=(t, y), xycoords=("data", "axes fraction"), xytext=(3, 0), textcoords="offset points",
                        rotation=90, va=va, ha="left", fontsize=7, color=c)


def contact_owner(node, contacts):
    """Which users' contact meshes hold `node` (1-based), from snapshots.json."""
    return [u + 1 for u, c in enumerate(contacts or []) if node in c]


_PREBUILT = {}  # figure name -> (figure, axes) made while the run was still going (prebuild())


# Fixed margins (fractions of the figure) in place of tight_layout, which measures every text of
# the figure a second time: the labels are known ahead, and these leave room for them.
MARGINS = {"one": dict(left=0.11, right=0.985, bottom=0.125, top=0.865),  # 8 x 3.8 in, a two-line title
           "two": dict(left=0.1, right=0.985, bottom=0.09, top=0.945, hspace=0.07)}  # 8 x 5 in, two axes


def make_figure(name, panels=None):
    """The empty figure `name` and its axes: what no run's data changes (panels: the snapshot
    figure's (rows, columns) of view panels)."""
    if name == "fig_snapshots.png":  # one axes, its panels side by side in it (one Axes each would cost 30 ms)
        rows, cols = panels
        fig = Figure(figsize=(2.3 * cols + 1.0, 2.2 * rows + 0.5))
        ax = fig.add_axes([0.05, 0.02, 0.82, 0.88], label="snapshots")
        ax.set_axis_off()
        ax.set_aspect("equal")
        return fig, ax
    if name in ("fig_node_position.png", "fig_consensus.png"):
        fig = Figure(figsize=(8, 3.8))
        fig.subplots_adjust(**MARGINS["one"])
        return fig, fig.subplots()
    fig = Figure(figsize=(8, 5))
    fig.subplots_adjust(**MARGINS["two"])
    return fig, fig.subplots(2, 1, sharex=True)


VIEW = (30.0, -60.0)  # elevation and azimuth (deg) the snapshot panels are seen from: matplotlib's 3D default


def view_basis(elev=VIEW[0], azim=VIEW[1]):
    """Rows: the screen's right and up directions and the direction toward the viewer, in the
    object's x, y, z (an orthographic camera at `elev` above the x-y plane, `azim` from +x)."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([[-np.sin(a), np.cos(a), 0.0],
                     [-np.sin(e) * np.cos(a), -np.sin(e) * np.sin(a), np.cos(e)],
                     [np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]])


def project(points, basis):
    """Screen (right, up) and depth toward the viewer of `points` (n x 3)."""
    q = points @ basis.T
    return q[:, :2], q[:, 2]


def new_figure(name, panels=None):
    """make_figure(name, panels), or the one prebuild() made for it when it has these panels."""
    made = _PREBUILT.pop((name, panels), None)
    return made if made is not None else make_figure(name, panels)


def prebuild(panels):
    """Makes every figure's empty axes ahead of the data (the snapshot figure's when its panels,
    (snapshots, copies drawn), are known)."""
    for name in FIGURES:
        if name != "fig_snapshots.png":
            _PREBUILT[(name, None)] = make_figure(name)
        elif panels:
            _PREBUILT[(name, panels)] = make_figure(name, panels)


def fig_node(summary, tr, contacts):
    users = int(summary["users"])
    node = int(summary.get("trace_node", 0))
    rest = summary.get("trace_node_rest_m")
    fig, ax = new_figure("fig_node_position.png")
    for u in range(1, users + 1):
        m = tr["user"] == u
        x = tr["node_x_m"][m]
        x0 = rest[0] if rest is not None else (x[0] if len(x) else 0.0)
        plot_line(ax, tr["t_s"][m], 1e3 * (x - x0), lw=1, label="user %d's copy" % u)
    ax.axhline(0, color="0.8", lw=0.6)
    mark_events(ax, summary)
    owners = contact_owner(node, contacts)
    where = ", on the contact mesh of user %s" % ", ".join(map(str, owners)) if owners else ""
    ref = "rest" if rest is not None else "its first sample"
    ax.set_xlabel("time (s)")
    ax.set_ylabel("x-displacement of node %d\nfrom %s (mm)" % (node, ref))
    ax.set_title("%s\nnode %d (0-based index%s): x-displacement from %s, every user's copy" % (run_title(summary), node, where, ref), fontsize=9)
    if users <= 8:
        ax.legend(fontsize=7, loc="lower right")
    return fig


def fig_force(summary, tr, se):
    users = int(summary["users"])
    fig, axs = new_figure("fig_device_force.png")
    for u in range(1, users + 1):
        m = tr["user"] == u
        plot_line(axs[0], tr["t_s"][m], tr["force_x_N"][m], lw=1, label="u_x user %d" % u)
    plot_line(axs[0], se["t_s"], se["force_sum_x_N"], "k", lw=1.2, label="sum u_x")
    axs[0].set_ylabel("device force x (N)")
    if users <= 8:
        axs[0].legend(fontsize=7, ncol=3, loc="lower right")
    axs[0].set_title(run_title(summary), fontsize=9)
    plot_line(axs[1], se["t_s"], se["force_sum_norm_N"], "k", lw=1)
    axs[1].set_ylabel("|sum_i u_i| (N)")
    axs[1].set_xlabel("time (s)")
    mark_events(axs[0], summary)
    mark_events(axs[1], summary, label_them=False)
    return fig


def fig_energy(summary, tr, se):
    users = int(summary["users"])
    fig, axs = new_figure("fig_energy.png")
    for u in range(1, users + 1):
        m = tr["user"] == u
        plot_line(axs[0], tr["t_s"][m], 1e3 * tr["port_energy_J"][m], lw=1, label="user %d" % u)
    plot_line(axs[0], se["t_s"], 1e3 * se["port_energy_total_J"], "k", lw=1.4, label="total")
    bound = -1e3 * summary["passivity_bound_J"]
    axs[0].axhline(bound, color="r", ls=":", lw=1, label="-d^2 (eq. 13)")
    axs[0].annotate("passivity bound -d^2 = %.3g mJ (eq. 13)" % bound, xy=(0.01, bound), xycoords=("axes fraction", "data"),
                    xytext=(0, 3), textcoords="offset points", fontsize=7, color="r")
    axs[0].set_ylabel("port energy sum v^T f T (mJ)")
    if users <= 8:
        axs[0].legend(fontsize=7, ncol=3, loc="lower right")
    axs[0].set_title(run_title(summary), fontsize=9)
    plot_line(axs[1], se["t_s"], 1e3 * se["controller_energy_total_J"], "k", lw=1.2, label="consensus controller (eq. 14)")
    axs[1].set_ylabel("controller energy (mJ)")
    axs[1].set_xlabel("time (s)")
    axs[1].legend(fontsize=7)
    mark_events(axs[0], summary)
    mark_events(axs[1], summary, label_them=False)
    return fig


def threshold_lines(summary):
    """Horizontal lines of the consensus metrics (m): (value, label, colour, style)."""
    w = summary.get("metrics_windows", {})
    out = [(w.get("consensus_threshold_m", 1e-3), "consensus threshold %.3g mm", "0.35", ":")]
    at_rel = summary.get("consensus_error_at_release_m")
    if at_rel:
        out.append((0.1 * at_rel, "10 %% of the error at release: %.3g mm", "tab:green", "-."))
        out.append((0.01 * at_rel, "1 %% of the error at release: %.3g mm", "tab:olive", "-."))
    return out


def fig_consensus(summary, se):
    fig, ax = new_figure("fig_consensus.png")
    floor = 1e-15
    plot_line(ax, se["t_s"], 1e3 * np.maximum(se["consensus_error_m"], floor), lw=1, label="consensus error max |x_i - x_j|")
    plot_line(ax, se["t_s"], 1e3 * np.maximum(se["deformation_m"], floor), lw=1, label="shape deformation, rms")
    ax.set_yscale("log")
    for v, label, c, ls in threshold_lines(summary):
        ax.axhline(1e3 * v, color=c, ls=ls, lw=0.9)
        ax.annotate(label % (1e3 * v), xy=(0.99, 1e3 * v), xycoords=("axes fraction", "data"), xytext=(0, 2), textcoords="offset points",
                    fontsize=7, color=c, ha="right")
    mark_events(ax, summary, at="bottom")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.set_title(run_title(summary), fontsize=9)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(0.005, 0.35))
    return fig


def mean_shape_distance_mm(snapshot):
    """Per copy and node: distance (mm) from the mean shape of all copies, as the run wrote it
    (snapshots.json distance_from_mean_shape_m, firmware/model/metrics.hpp)."""
    return 1e3 * np.asarray(snapshot["distance_from_mean_shape_m"], dtype=float)


def nice_factor(v):
    """The smallest of 1, 2, 5 x 10^k at or above v (at least 1)."""
    if v <= 1:
        return 1
    e = 10 ** np.floor(np.log10(v))
    return int(next(f * e for f in (1, 2, 5, 10) if f * e >= v - 1e-9))


def snapshot_geometry(sn):
    """Drawn positions (mm): the start shape plus each copy's deformation (its shape relative to its
    centroid, minus the start shape's) scaled by an exaggeration factor shown in the title."""
    snaps = sn["snapshots"]
    ref = np.array(snaps[0]["x_m"][0]).reshape(-1, 3)
    ref_c = ref - ref.mean(axis=0)
    radius = np.linalg.norm(ref_c, axis=1).max()
    defo = [[(np.array(x).reshape(-1, 3) - np.array(x).reshape(-1, 3).mean(axis=0)) - ref_c for x in s["x_m"]] for s in snaps]
    biggest = max(np.linalg.norm(d, axis=1).max() for ds in defo for d in ds)
    factor = nice_factor(0.15 * radius / biggest) if biggest > 0 else 1
    return ref_c, radius, defo, factor


def fig_snapshots(summary, sn):
    snaps, surf, contacts = sn["snapshots"], np.array(sn["surface"]), sn["contact_nodes"]
    users = int(summary["users"])
    ref_c, radius, defo, factor = snapshot_geometry(sn)
    dist = [mean_shape_distance_mm(s) for s in snaps]
    vmax = max(max(d.max() for d in dist), 1e-12)
    norm = colors.Normalize(0, vmax)
    cmap = matplotlib.colormaps["viridis"]
    rows, cols = len(snaps), min(users, MAX_COPIES_DRAWN)
    fig, ax = new_figure("fig_snapshots.png", (rows, cols))
    lim = 1e3 * radius * 1.15  # half a panel's side (mm)
    basis = view_basis()
    for r, s in enumerate(snaps):
        for u in range(cols):
            at = panel_centre(r, u, lim)
            x = 1e3 * (ref_c + factor * defo[r][u])
            c = np.array(s["x_m"][u]).reshape(-1, 3).mean(axis=0)
            draw_copy(ax, basis, x, surf, cmap(norm(dist[r][u][surf].mean(axis=1)), alpha=0.85),
                      contacts[u] if u < len(contacts) else [], 1e3 * (np.array(s["vp_m"][u]) - c), at, "snapshot %d %d" % (r, u))
            if r == 0:
                ax.text(at[0], at[1] + lim, "user %d's copy" % (u + 1), fontsize=8, ha="center", va="bottom")
        at = panel_centre(r, 0, lim)
        ax.text(at[0] - lim, at[1], "t = %.2f s\nmax %.2g mm" % (s["t_s"], dist[r].max()), fontsize=7, rotation=90,
                ha="right", va="center")
    ax.set_xlim(-lim, (2 * cols - 1) * lim), ax.set_ylim(-(2 * rows - 1) * lim, lim)
    draw_scale(ax, basis, panel_centre(rows - 1, 0, lim), lim, radius)
    cax = fig.add_axes([0.89, 0.15, 0.02, 0.7])
    cb = fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), cax=cax)
    cb.set_label("distance from the mean shape\n(of the %d copies), mm" % users, fontsize=7)
    cb.ax.tick_params(labelsize=6)
    fig.suptitle("%s\n%s about their centroids (mm), deformation x%d; colour: distance from the mean shape;"
                 " VP red, contact nodes black" % (run_title(summary), copies_shown(users, cols), factor), fontsize=8)
    return fig


def panel_centre(r, u, lim):
    """Centre (mm, in the snapshot figure's one axes) of the panel of snapshot r, copy u."""
    return np.array([2 * lim * u, -2 * lim * r])


def draw_copy(ax, basis, x, surf, face_colours, contact, vp, at, gid):
    """One copy in its panel (centred at `at`): the surface triangles painted far to near
    (orthographic view along `basis`), the contact nodes black and the virtual proxy red on top."""
    xy, depth = project(x, basis)
    xy = xy + at
    order = np.argsort(depth[surf].mean(axis=1), kind="stable")  # farthest first
    ax.add_collection(PolyCollection(xy[surf[order]], facecolors=np.asarray(face_colours)[order], edgecolors="0.25",
                                     linewidths=0.15, zorder=1, gid=gid))
    vp_xy = project(vp.reshape(1, 3), basis)[0] + at
    pts = np.vstack([xy[list(contact)], vp_xy])
    ax.scatter(pts[:, 0], pts[:, 1], c=["k"] * len(contact) + ["r"], s=[5] * len(contact) + [12], zorder=3)


def draw_scale(ax, basis, centre, lim, radius):
    """Below the bottom-left panel: a bar of the radius (rounded, mm; every panel has this scale),
    and the object's x, y, z directions as every panel sees them, from VIEW."""
    bar = max(1, round(radius * 1e3))
    y = centre[1] - 0.93 * lim
    ax.plot([centre[0] - 0.5 * bar, centre[0] + 0.5 * bar], [y, y], color="k", lw=1.2)
    ax.text(centre[0], y - 0.02 * lim, "%d mm; view: elevation %g, azimuth %g deg" % ((bar,) + VIEW), fontsize=6,
            ha="center", va="top")
    o = centre + np.array([-0.92 * lim, -0.7 * lim])
    for k, name in enumerate("xyz"):
        d = 0.2 * lim * basis[:2, k]
        ax.annotate("", xy=o + d, xytext=o, arrowprops=dict(arrowstyle="->", lw=0.6, color="0.3"))
        ax.text(*(o + 1.3 * d), name, fontsize=5, color="0.3", ha="center", va="center")


def copies_shown(users, cols):
    """Which copies a snapshot figure of `cols` columns shows, said in its title."""
    if cols >= users:
        return "all %d copies" % users
    return "users 1-%d's copies (of %d users; the mean shape and the colour scale use all %d)" % (cols, users, users)


FIGURES = ("fig_snapshots.png", "fig_node_position.png", "fig_device_force.png", "fig_energy.png", "fig_consensus.png")  # slowest first
FORKED = ("fig_snapshots.png", "fig_consensus.png")  # what a forked child draws with a CPU idle: about half the time


def load_run(run):
    """A run directory's files: (summary, trace columns, series columns, snapshots or None)."""
    summary = json.load(open(os.path.join(run, "summary.json")))
    tr = load_csv(os.path.join(run, "trace.csv"))
    se = load_csv(os.path.join(run, "series.csv"))
    snap_path = os.path.join(run, "snapshots.json")
    sn = json.load(open(snap_path)) if os.path.exists(snap_path) else None
    return summary, tr, se, sn


def figure(name, data):
    """One figure of FIGURES from load_run()'s data, None when the run has nothing for it."""
    summary, tr, se, sn = data
    if name == "fig_snapshots.png":
        return fig_snapshots(summary, sn) if sn and sn["snapshots"] else None
    if name == "fig_node_position.png":
        return fig_node(summary, tr, sn["contact_nodes"] if sn else None)
    if name == "fig_device_force.png":
        return fig_force(summary, tr, se)
    if name == "fig_energy.png":
        return fig_energy(summary, tr, se)
    return fig_consensus(summary, se)


def figures(run):
    """The run's figures as {file name: matplotlib Figure} (tests inspect them)."""
    data = load_run(run)
    out = {name: figure(name, data) for name in FIGURES}
    return {name: fig for name, fig in out.items() if fig is not None}


def save(fig, run, name):
    """The figure as RUN/NAME, PNG compression level 1 (the same pixels as the default level 6,
    ~10 % larger, a fraction of the encoding time)."""
    fig.savefig(os.path.join(run, name), dpi=100 if name == "fig_snapshots.png" else 110, pil_kwargs={"compress_level": 1})


def draw(run, data, names):
    """Draws and saves the figures `names` of load_run()'s data; returns how many failed."""
    failed = 0
    for name in names:
        try:
            fig = figure(name, data)
            if fig is not None:
                save(fig, run, name)
        except Exception as e:  # the other figures still get drawn; the exit status says it
            print("plot_run.py: %s: %s: %s" % (name, type(e).__name__, e), file=sys.stderr)
            failed += 1
    return failed


def idle_cpus():
    """CPUs this process may use minus the 1-minute load average: what a second process would get."""
    return len(os.sched_getaffinity(0)) - os.getloadavg()[0]


def main(run):
    """Draws every figure of `run` from its files read once. With a CPU idle, a forked child draws
    FORKED (about half the drawing time) while this process draws the others; on a busy machine a
    second process would only add its own cost, so one process draws them all.
    Returns the exit status: 0 when every figure was drawn."""
    data = load_run(run)
    if idle_cpus() < 1:
        return 1 if draw(run, data, FIGURES) else 0
    sys.stdout.flush(), sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        os._exit(1 if draw(run, data, FORKED) else 0)
    failed = draw(run, data, [n for n in FIGURES if n not in FORKED])
    _, status = os.waitpid(pid, 0)
    return 1 if failed or os.waitstatus_to_exitcode(status) != 0 else 0


def warm_up():
    """What every figure needs and no run's data changes, done while the run is still going: the
    fonts, the mathtext parser of a log axis's labels, a polygon collection and the PNG writer (the
    forked workers inherit it all)."""
    import io
    fig = Figure(figsize=(2, 2))
    ax = fig.add_subplot(1, 2, 1)
    ax.semilogy([0, 1], [1e-3, 1e-1])
    ax.set_title("warm-up x (mm)", fontsize=8)
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.add_collection(PolyCollection([[(0, 0), (1, 0), (0, 1)]]))
    ax2.set_ylabel("t = 0 s", fontsize=7)
    fig.savefig(io.BytesIO(), format="png", dpi=20)


def wait_for_go():
    """True when stdin says "go" (the run's files are written); False at end of input (no run).
    Anything else is a caller's mistake: exit 2 saying so."""
    line = sys.stdin.readline()
    if line and line.strip() != "go":
        print("plot_run.py --after-go: expected 'go' on stdin, got %r" % line.strip(), file=sys.stderr)
        sys.exit(2)
    return line.strip() == "go"


def parse_args(args):
    """(run dir, after_go, snapshot panels or None) from [--after-go [--expect SNAPSHOTS USERS]] RUN_DIR."""
    after_go = bool(args) and args[0] == "--after-go"
    args = args[1:] if after_go else args
    panels = None
    if after_go and len(args) >= 3 and args[0] == "--expect":
        panels, args = (int(args[1]), min(int(args[2]), MAX_COPIES_DRAWN)), args[3:]
    if len(args) != 1 or args[0] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(args) == 1 else 2)
    return args[0], after_go, panels


if __name__ == "__main__":
    run_dir, after_go, panels = parse_args(sys.argv[1:])
    if after_go:
        if idle_cpus() >= 1:  # else it would only add to a busy machine's load (drawing warms up anyway)
            warm_up()
        prebuild(panels)
        if not wait_for_go():
            sys.exit(0)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.exit(main(run_dir))
