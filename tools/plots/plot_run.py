#!/usr/bin/python3
"""Figures of one haptic-station run directory (in the spirit of the paper's Figs. 8-10).

usage: /usr/bin/python3 tools/plots/plot_run.py RUN_DIR

Reads RUN_DIR/trace.csv, series.csv, summary.json and (if present) snapshots.json and writes
fig_node_position.png, fig_device_force.png, fig_energy.png, fig_consensus.png and
fig_snapshots.png into RUN_DIR.
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load_csv(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    return data


def main(run):
    summary = json.load(open(os.path.join(run, "summary.json")))
    tr = load_csv(os.path.join(run, "trace.csv"))
    se = load_csv(os.path.join(run, "series.csv"))
    users = int(summary["users"])
    title = "%s: %s, B = (%s) N s/m" % (
        summary["scenario"],
        "topology " + " ".join("%d-%d" % tuple(l) for l in summary["topology"]),
        ", ".join("%.1f" % b for b in summary["damping_Ns_per_m"]),
    )
    if users > 8:  # a long title would cover the figure
        b = summary["damping_Ns_per_m"]
        title = "%s: %d users, %d links, B = %.1f..%.1f N s/m" % (summary["scenario"], users, len(summary["topology"]), min(b), max(b))
    rel = summary.get("release_time_s", None)

    def mark(ax):
        if rel:
            ax.axvline(rel, color="0.6", ls="--", lw=0.8)

    # Node position per user (Fig. 8/9 middle, Fig. 10)
    fig, ax = plt.subplots(figsize=(8, 3.6))
    for u in range(1, users + 1):
        m = tr["user"] == u
        ax.plot(tr["t_s"][m], 1e3 * tr["node_x_m"][m], lw=1, label="user %d" % u)
    mark(ax)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("node x-position (mm)")
    ax.set_title(title, fontsize=9)
    if users <= 8:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig_node_position.png"), dpi=110)
    plt.close(fig)

    # Device force per user and their sum (x-axis), and |sum|
    fig, axs = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for u in range(1, users + 1):
        m = tr["user"] == u
        axs[0].plot(tr["t_s"][m], tr["force_x_N"][m], lw=1, label="u_x user %d" % u)
    axs[0].plot(se["t_s"], se["force_sum_x_N"], "k", lw=1.2, label="sum u_x")
    axs[0].set_ylabel("device force x (N)")
    axs[0].legend(fontsize=7, ncol=3) if users <= 8 else None
    axs[0].set_title(title, fontsize=9)
    axs[1].plot(se["t_s"], se["force_sum_norm_N"], "k", lw=1)
    axs[1].set_ylabel("|sum_i u_i| (N)")
    axs[1].set_xlabel("time (s)")
    for a in axs:
        mark(a)
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig_device_force.png"), dpi=110)
    plt.close(fig)

    # Energies: port (13) and controller (14)
    fig, axs = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for u in range(1, users + 1):
        m = tr["user"] == u
        axs[0].plot(tr["t_s"][m], 1e3 * tr["port_energy_J"][m], lw=1, label="user %d" % u)
    axs[0].plot(se["t_s"], 1e3 * se["port_energy_total_J"], "k", lw=1.4, label="total")
    axs[0].axhline(-1e3 * summary["passivity_bound_J"], color="r", ls=":", lw=1, label="-d^2 (eq. 13)")
    axs[0].set_ylabel("port energy sum v^T f T (mJ)")
    axs[0].legend(fontsize=7, ncol=3) if users <= 8 else None
    axs[0].set_title(title, fontsize=9)
    axs[1].plot(se["t_s"], 1e3 * se["controller_energy_total_J"], "k", lw=1.2, label="consensus controller (eq. 14)")
    axs[1].set_ylabel("controller energy (mJ)")
    axs[1].set_xlabel("time (s)")
    axs[1].legend(fontsize=7)
    for a in axs:
        mark(a)
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig_energy.png"), dpi=110)
    plt.close(fig)

    # Consensus error and deformation
    fig, ax = plt.subplots(figsize=(8, 3.6))
    err = np.maximum(se["consensus_error_m"], 1e-15)
    ax.semilogy(se["t_s"], 1e3 * err, lw=1, label="consensus error max |x_i - x_j| (mm)")
    ax.semilogy(se["t_s"], 1e3 * np.maximum(se["deformation_m"], 1e-15), lw=1, label="shape deformation, rms (mm)")
    ax.axhline(1.0, color="0.5", ls=":", lw=0.8)
    mark(ax)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig_consensus.png"), dpi=110)
    plt.close(fig)

    snap_path = os.path.join(run, "snapshots.json")
    if os.path.exists(snap_path):
        sn = json.load(open(snap_path))
        snaps = sn["snapshots"]
        surf = np.array(sn["surface"])
        contacts = sn["contact_nodes"]
        if snaps:
            x0 = np.array(snaps[0]["x_m"][0]).reshape(-1, 3)
            rows, cols = len(snaps), min(users, 8)  # at most 8 copies drawn (a 64-user run: users 1-8)
            fig = plt.figure(figsize=(2.2 * cols, 2.1 * rows))
            for r, s in enumerate(snaps):
                for u in range(cols):
                    ax = fig.add_subplot(rows, cols, r * cols + u + 1, projection="3d")
                    x = np.array(s["x_m"][u]).reshape(-1, 3)
                    c = x.mean(axis=0)
                    xe = c + (x0 - x0.mean(axis=0)) + 10.0 * ((x - c) - (x0 - x0.mean(axis=0)))  # deformation x3
                    ax.plot_trisurf(xe[:, 0], xe[:, 1], xe[:, 2], triangles=surf, color="0.85", edgecolor="0.4", lw=0.2, alpha=0.8)
                    cn = contacts[u]
                    ax.scatter(xe[cn, 0], xe[cn, 1], xe[cn, 2], color="k", s=6)
                    vp = np.array(s["vp_m"][u])
                    vpe = c + (vp - c)
                    ax.scatter([vpe[0]], [vpe[1]], [vpe[2]], color="r", s=10)
                    ax.set_axis_off()
                    if r == 0:
                        ax.set_title("user %d" % (u + 1), fontsize=8)
                    if u == 0:
                        ax.text2D(-0.1, 0.5, "t=%.1f s" % s["t_s"], transform=ax.transAxes, fontsize=8, rotation=90)
            fig.suptitle(title + " (deformation x10, VP red, contact nodes black)", fontsize=8)
            fig.tight_layout()
            fig.savefig(os.path.join(run, "fig_snapshots.png"), dpi=100)
            plt.close(fig)


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    main(sys.argv[1])
