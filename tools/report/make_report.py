#!/usr/bin/python3
"""Writes OUT/report.md: the paper's experiment (Section V) next to ours.

usage: /usr/bin/python3 tools/report/make_report.py OUT
OUT holds one folder per run (paper-best, paper-worst, paper-unstable) written by
`haptic-station sim`, and optionally topology.txt / topology.json from haptic-topology.
Every number of ours in the report is read from those files; the paper's are quoted from its
Section V text (Figs. 7-10).
"""
import json
import os
import sys

PAPER = {
    "paper-best": {
        "topology": "1-2, 1-3, 1-4 (star on user 1)",
        "bound_ms": [25, 10, 7, 9],
        "damping": [26.25, 10.5, 7.5, 9.5],
        "rise_s": 3.0,
        "release_s": 12.0,
        "stable": "stable",
    },
    "paper-worst": {
        "topology": "1-2, 2-4, 4-3 (path; inferred from the eq. (18) bounds the paper gives)",
        "bound_ms": [10, 375, 330, 695],
        "damping": [10.5, 395, 346.5, 730],
        "rise_s": 29.0,
        "release_s": 64.0,
        "stable": "stable",
    },
    "paper-unstable": {
        "topology": "best topology",
        "bound_ms": [25, 10, 7, 9],
        "damping": [14, 5, 4, 5],
        "rise_s": None,
        "release_s": None,
        "stable": "unstable after a small perturbation at 2.5 s (Fig. 10)",
    },
}


def fmt_list(v, p=1):
    return "(" + ", ".join(("%." + str(p) + "f") % x for x in v) + ")"


def fmt(x, p=3, unit=""):
    if x is None:
        return "never"
    if isinstance(x, str):
        return x
    return ("%." + str(p) + "g") % x + unit


def gate_text(r):
    """What the per-edge energy gate and the edge-drop rule did (summary.json "gate"); "" when neither acted."""
    g = r.get("gate")
    if g is None:  # a summary written before the gate was reported: its trip count only
        t = r.get("edge_energy_trips") or 0
        return "%d energy-gate trips (energy removed not recorded)" % t if t else ""
    if not g["energy_gate_trips"] and not g["edge_drop_events"]:
        return ""
    port = g.get("port_energy_min_J")
    return "%d energy-gate trips (%d gated ticks), %s J removed by the gate, %d edge drops; worst port energy %s J" % (
        g["energy_gate_trips"], g["energy_gate_gated_ticks"], fmt(g["energy_gate_removed_J"]), g["edge_drop_events"],
        fmt(port) if port is not None else "n/a")


def stability_text(r):
    """The run's verdict as the report states it: a run the gate held is never plain "stable"."""
    if r["diverged"]:
        return "DIVERGED at %s s" % r["diverged_at_s"]
    verdict = r.get("verdict") or ("held_by_gate" if r.get("edge_energy_trips") else "unstable" if r.get("unstable") else "stable")
    speed = "max node speed %s m/s" % fmt(r["max_node_speed_m_per_s"])
    gate = gate_text(r)
    if verdict == "held_by_gate":
        return "HELD BY THE GATE, not shown stable by eq. (18): %s; %s" % (gate, speed)
    if verdict == "stable_with_edge_drops":
        return "stable with the edge-drop rule acting: %s; %s" % (gate, speed)
    if verdict == "unstable":
        return "unstable (growing consensus error; %s)" % speed
    if verdict == "not_passive":
        return "NOT PASSIVE: the users' ports took %s J out, beyond -d^2 = -%s J (eq. 13 broken, no gate acted); %s" % (
            fmt(r["port_energy_min_J"]), fmt(r["passivity_bound_J"]), speed)
    return "stable (%s; the energy gate never tripped, no edge dropped)" % speed


def damping_side_by_side(out, runs, w):
    """B_i with the paper's loss allowance (L = 1, OUT/<run>-L1/summary.json from `sim --loss-allowance 1`) next to the
    default's (the loss model's L) and the paper's, and why they differ."""
    rows = []
    for name in ("paper-best", "paper-worst"):
        l1_path = os.path.join(out, name + "-L1", "summary.json")
        if name in runs and os.path.exists(l1_path):
            rows.append((name, json.load(open(l1_path)), runs[name]))
    if not rows:
        return
    w("## B_i with the paper's loss allowance and with ours")
    w("")
    w("| run | paper B_i (N s/m) | ours, L = 1 (the paper's: one lost packet) | ours, default L (loss model) |"
      " sum_j (Nbar_ij+Nbar_ji) T/2 (ms): paper / L = 1 / default |")
    w("|---|---|---|---|---|")
    for name, l1, d in rows:
        w("| %s | %s | %s | %s, L = %s | %s / %s / %s |" % (
            name, fmt_list(PAPER[name]["damping"], 2), fmt_list(l1["damping_Ns_per_m"], 2), fmt_list(d["damping_Ns_per_m"], 2),
            d.get("loss_allowance_ticks"), fmt_list(PAPER[name]["bound_ms"], 0), fmt_list(l1["round_trip_half_sum_ms"], 0),
            fmt_list(d["round_trip_half_sum_ms"], 0)))
    w("")
    ds = [d for _, _, d in rows]
    w("Why they differ. Eq. (18) is the same in both columns; only Nbar differs. Nbar_ij = ceil(max delay / T) + L, with the"
      " delay model's support (max delay = 1.5 x the mean). The paper allows one lost packet per direction. Our default takes L"
      " from the loss model instead: the smallest L for which a run (here %s s, %s ticks) with the scenario's 5 %% i.i.d. loss on"
      " its %s directed links has at most a 1 %% chance of any over-bound event (ticks x links x p^(L+1) <= 0.01,"
      " firmware/model/delay_model.hpp): L = %s. Each tick of L adds one tick to every Nbar_ij and Nbar_ji, so eq. (18)'s P term"
      " (Nbar_ij + Nbar_ji)/2 T P_ij grows by T P_ij per link and tick of L (2 N s/m with the paper's lambda_max(P_ij) = 1000 N/m),"
      " on every link of a station: that is the gap between the columns (the 5 %% margin on top). With L = 1 the bound is the"
      " paper's kind of bound and B_i comes close to the paper's; the difference left is the paper's measured bounds against our"
      " delay model. The price of L = 1 is over-bound events under 5 %% loss, each acted on passively by the edge-drop rule (the"
      " L = 1 runs' verdicts: %s)%s." % (
          " / ".join(fmt(d["duration_s"]) for d in ds), " / ".join("%d" % round(d["duration_s"] / d["dt_s"]) for d in ds),
          " / ".join("%d" % (2 * len(d["topology"])) for d in ds), " / ".join(str(d.get("loss_allowance_ticks")) for d in ds),
          " / ".join(str(l1.get("verdict")) for _, l1, _ in rows), l1_drops(rows)))
    w("")


def where_eq18_binds(out, w):
    """The closed loop in which eq. (18) binds (OUT/eq18-binds-F/summary.json from `sim --scenario eq18-binds --damping B,B`)."""
    rows = []
    for d in sorted(os.listdir(out)):
        path = os.path.join(out, d, "summary.json")
        if d.startswith("eq18-binds-") and os.path.exists(path):
            r = json.load(open(path))
            rows.append((r["damping_Ns_per_m"][0] / r["damping_min_Ns_per_m"][0], r))
    if not rows:
        return
    w("## Where eq. (18) binds")
    w("")
    w("Two users on one link, a heavy object (1 kg nodes), constant 9.9 ms delays, no loss, D_ij = 0, no energy gate"
      " (`haptic-station sim --scenario eq18-binds --damping B,B`; rt/README.md, \"Where eq. (18) binds\", says why the paper's"
      " star needs much less). Eq. (18) asks %s N s/m of each station." % fmt(rows[0][1]["damping_min_Ns_per_m"][0]))
    w("")
    w("| B_i / eq. (18) | verdict | max controller energy (14) | min port energy (13) vs -d^2 |")
    w("|---|---|---|---|")
    for f, r in sorted(rows, key=lambda x: x[0]):
        w("| %s | %s | %s J | %s J vs -%s J |" % (fmt(f, 2), stability_text(r), fmt(r["controller_energy_max_J"]),
                                               fmt(r["port_energy_min_J"]), fmt(r["passivity_bound_J"])))
    w("")


def l1_drops(rows):
    """The L = 1 runs' over-bound events (edge drops), when they ran long enough to count them."""
    parts = []
    for name, l1, _ in rows:
        if l1["simulated_s"] >= 1.0 and l1.get("gate") is not None:
            parts.append("%s: %d edge drops in %s s with L = 1" % (name, l1["gate"]["edge_drop_events"], fmt(l1["simulated_s"])))
    return (": " + "; ".join(parts)) if parts else ""


def main(out):
    runs = {}
    for name in PAPER:
        p = os.path.join(out, name, "summary.json")
        if os.path.exists(p):
            runs[name] = json.load(open(p))
    lines = []
    w = lines.append
    w("# The paper's 4-user experiment, reproduced")
    w("")
    w("Huang & Lee, IEEE T-RO 2013, Section V. Scene: 33-node floating ball (our mesh: 60 tetrahedra, the paper's 87),"
      " M = 0.04 I, K_rs = 100 I3 per edge, T = 2 ms, VP 1 g, k_c = 200, K_vc = 200, b_v = 2, P_ij = 1000[I/2 + K_int/(2 lambda_max)],"
      " D_ij = 5 I; per-packet delay uniform in 50-150 % of the link mean, 5 % loss, 1 % duplication. Simulated users: passive"
      " device (50 g, b_d = 0.5 N s/m) held by a hand spring-damper (300 N/m, 5 N s/m) towards a scripted goal; the four users"
      " push symmetric faces (tetrahedral directions) 3 cm, hold, and release. Generated by `tools/main-job.sh`.")
    w("")
    topo = os.path.join(out, "topology.txt")
    if os.path.exists(topo):
        w("## Topology choice (eq. 27)")
        w("")
        w("```")
        w(open(topo).read().rstrip()[:6000])
        w("```")
        w("")
    w("## Ours next to the paper's")
    w("")
    w("| quantity | run | paper | ours |")
    w("|---|---|---|---|")
    for name, pr in PAPER.items():
        r = runs.get(name)
        if r is None:
            w("| (run missing) | %s | | |" % name)
            continue
        topo_ours = ", ".join("%d-%d" % tuple(l) for l in r["topology"])
        w("| topology | %s | %s | %s |" % (name, pr["topology"], topo_ours))
        w("| sum_j (Nbar_ij+Nbar_ji) T/2 (ms) | %s | %s | %s |" % (name, fmt_list(pr["bound_ms"], 0), fmt_list(r["round_trip_half_sum_ms"], 0)))
        w("| B_i used (N s/m) | %s | %s | %s |" % (name, fmt_list(pr["damping"], 2), fmt_list(r["damping_Ns_per_m"], 2)))
        w("| eq. (18) minimum (N s/m) | %s | | %s, condition %s |" % (name, fmt_list(r["damping_min_Ns_per_m"], 2), "met" if r["passivity_condition_met"] else "VIOLATED"))
        if pr["rise_s"] is not None:
            w("| time to similar deformation (90 %% of hold) | %s | %s s | %s |" % (name, pr["rise_s"], fmt(r.get("deformation_rise_time_s"), 3, " s")))
            w("| release | %s | %s s | %s s |" % (name, pr["release_s"], r["release_time_s"]))
            w("| consensus after release (error < 1 mm) | %s | reached | %s after release; error at end %s m |" % (name, fmt(r.get("consensus_time_s"), 3, " s"), fmt(r["consensus_error_m"])))
            left = "not within the %s s after release" % fmt(r["simulated_s"] - r["release_time_s"], 3)
            ct = lambda k: fmt(r.get(k), 3, " s") if r.get(k) is not None else left
            w("| consensus after release to 10 %% / 1 %% of the error at release (%s mm) | %s | | %s / %s |" % (
                fmt(1e3 * r["consensus_error_at_release_m"]) if r.get("consensus_error_at_release_m") is not None else "n/a", name,
                ct("consensus_time_10pct_s"), ct("consensus_time_1pct_s")))
            w("| force balance in the hold: mean abs(sum u_i) / mean abs(u_i) | %s | sum u_x = 0 | %s / %s N = %s |" % (
                name, fmt(r["hold_force_sum_N"]), fmt(r["hold_force_mean_N"]), fmt(r.get("hold_force_balance_ratio"))))
        w("| stability | %s | %s | %s |" % (name, pr["stable"], stability_text(r)))
        bound = r.get("edge_energy_bound_J")
        w("| per-edge energy gate (bound %s) and edge-drop rule | %s | none | %s |" % (
            "%s J" % fmt(bound) if bound is not None else "off", name, gate_text(r) or "never acted"))
        w("| N-port passivity (13): min of cumulative port energy vs -d^2 | %s | | %s J vs -d^2 = -%s J |" % (name, fmt(r["port_energy_min_J"]), fmt(abs(r["passivity_bound_J"]))))
        pk = r["packets"]
        w("| packets sent / lost / duplicated / reordered | %s | | %d / %d / %d / %d |" % (name, pk["sent"], pk["lost"], pk["duplicated"], pk["reordered"]))
    w("")
    allowance = sorted({r.get("loss_allowance_ticks") for r in runs.values() if r.get("loss_allowance_ticks") is not None})
    w("Notes. Our bound Nbar_ij = ceil(1.5 x mean delay / T) + a loss allowance L of %s tick(s) is computed from the network"
      " model (the paper measured its bounds); the next section compares B_i with the paper's allowance and ours. The margin over"
      " eq. (18) is 5 %%. Where the paper's outcome and ours differ (see paper-unstable) we report ours as measured; eq. (18) is a"
      " sufficient condition, and the stability maps in tools/study/ show where the system does lose stability." % "/".join(str(a) for a in allowance))
    w("")
    damping_side_by_side(out, runs, w)
    where_eq18_binds(out, w)
    nd = os.path.join(out, "no-damping", "summary.json")
    if os.path.exists(nd):
        r = json.load(open(nd))
        w("## Beyond the paper: where it does fail")
        w("")
        w("With Fig. 10's damping (14, 5, 4, 5) N s/m our simulated system stayed stable: eq. (18) is sufficient, not necessary,"
          " and the undelayed local half of each D_ij coupling damps the copies too. Removing the local damping entirely and"
          " weakening D_ij to %s I (`haptic-station sim --scenario paper-unstable --damping 0,0,0,0 --d-gain 1`) gives: %s;"
          " minimum cumulative port energy %s J against the bound -%s J%s." % (
              "1", stability_text(r),
              fmt(r["port_energy_min_J"]), fmt(r["passivity_bound_J"]),
              " (energy was generated: N-port passivity (13) broken)" if r.get("eq13_broken") else ""))
        w("")
        off = os.path.join(out, "no-damping-gate-off", "summary.json")
        if os.path.exists(off):
            r_off = json.load(open(off))
            w("The same run with the per-edge energy gate off (`--edge-energy-bound 0`, eq. (18)'s law alone): %s; minimum"
              " cumulative port energy %s J. %s" % (stability_text(r_off), fmt(r_off["port_energy_min_J"]),
                                                    "So the run above was kept bounded by the gate, not by the consensus law."
                                                    if (r_off["diverged"] or r_off.get("unstable")) and r.get("verdict") == "held_by_gate" else ""))
            w("")
        for fig in ("fig_node_position.png", "fig_energy.png"):
            if os.path.exists(os.path.join(out, "no-damping", fig)):
                w("![no-damping: %s](no-damping/%s)" % (fig, fig))
                w("")
    for name in PAPER:
        if name not in runs:
            continue
        w("## %s" % name)
        w("")
        for fig, cap in (("fig_node_position.png", "the traced node's x-displacement from rest in every copy (paper Figs. 8-10, middle)"),
                         ("fig_device_force.png", "device force per user and their sum"),
                         ("fig_energy.png", "port energy (13) and controller energy (14)"),
                         ("fig_consensus.png", "consensus error and deformation"),
                         ("fig_snapshots.png", "the four copies at key times, coloured by distance from the consensus shape")):
            if os.path.exists(os.path.join(out, name, fig)):
                w("![%s: %s](%s/%s)" % (name, cap, name, fig))
                w("")
    open(os.path.join(out, "report.md"), "w").write("\n".join(lines) + "\n")


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    main(sys.argv[1])
