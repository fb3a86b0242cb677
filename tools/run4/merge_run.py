#!/usr/bin/python3
"""Merge the outputs of N `haptic-station run` processes into the simulator's files.

Usage: /usr/bin/python3 tools/run4/merge_run.py RUN_DIR

Reads RUN_DIR/station-<i>.json, station-<i>-trace.csv, station-<i>-state.csv (i = 1..N) and
writes RUN_DIR/summary.json (the contract of write_summary_json in firmware/simulator.cpp, plus
per-link measured delay and loss and the measured bounds), trace.csv and series.csv (the
simulator's columns, on the common tick index k of the run, so tools/plots/plot_run.py draws the
same figures). Quantities needing every copy at once (consensus error, deformation, the
consensus time) use the ticks where all stations recorded their state (station.state_every).
"""
import csv
import glob
import json
import math
import os
import sys

import numpy as np


def load_csv(path):
    with open(path) as f:
        r = csv.reader(f)
        head = next(r)
        rows = [list(map(float, row)) for row in r if row]
    return head, np.array(rows, dtype=float).reshape(-1, len(head))


def main(run):
    files = sorted(glob.glob(os.path.join(run, "station-*.json")), key=lambda p: int(os.path.basename(p)[8:-5]))
    if not files:
        sys.exit("merge_run.py: no station-*.json in " + run)
    st = [json.load(open(p)) for p in files]
    ids = [s["station"] for s in st]
    N = st[0]["users"]
    if sorted(ids) != list(range(1, N + 1)):
        sys.exit("merge_run.py: need station-1..%d.json, found %s" % (N, ids))
    st.sort(key=lambda s: s["station"])
    T = st[0]["dt_s"]
    errors = [s["station"] for s in st if s.get("error")]
    if errors:
        sys.exit("merge_run.py: station(s) %s reported an error: %s" % (errors, [s["error"] for s in st if s.get("error")]))

    traces, states = [], []
    for s in st:
        i = s["station"]
        h, a = load_csv(os.path.join(run, "station-%d-trace.csv" % i))
        traces.append((h, a))
        h2, b = load_csv(os.path.join(run, "station-%d-state.csv" % i))
        states.append(b)
    col = {n: j for j, n in enumerate(traces[0][0])}

    # Common ticks.
    tk = [dict((int(r[0]), r) for r in a) for _, a in traces]
    common_trace = sorted(set.intersection(*[set(d) for d in tk]))
    sk = [dict((int(r[0]), r[1:]) for r in b) for b in states]
    common_state = sorted(set.intersection(*[set(d) for d in sk]))
    if not common_trace or not common_state:
        sys.exit("merge_run.py: the stations share no recorded tick")

    x_d = np.array(st[0]["x_d"])
    n = len(x_d) // 3
    release = st[0]["release_time_s"]
    push_end = st[0]["push_end_s"]
    hold0, hold1 = push_end + 0.5 * (release - push_end), release

    # series at the state ticks
    series = []
    last_violation, any_violation = None, False
    max_err = 0.0
    for k in common_state:
        xs = [sk[i][k].reshape(n, 3) for i in range(N)]
        err = 0.0
        for a in range(N):
            for b in range(a + 1, N):
                err = max(err, float(np.max(np.linalg.norm(xs[a] - xs[b], axis=1))))
        if not math.isfinite(err):
            err = float("inf")
        max_err = max(max_err, err)
        xbar = sum(xs) / N - x_d.reshape(n, 3)
        md = xbar.mean(axis=0)
        deformation = float(np.sqrt(np.mean(np.sum((xbar - md) ** 2, axis=1))))
        t_next = (k + 1) * T
        if t_next > release and not (err < 1e-3):
            last_violation, any_violation = t_next, True
        row = [tk[i].get(k) for i in range(N)]
        if all(r is not None for r in row):
            port = sum(r[col["port_energy_J"]] for r in row)
            ctrl = sum(r[col["controller_energy_J"]] for r in row)
            f = np.sum([[r[col["force_x_N"]], r[col["force_y_N"]], r[col["force_z_N"]]] for r in row], axis=0)
        else:
            port = ctrl = float("nan")
            f = np.array([float("nan")] * 3)
        series.append((t_next, err, deformation, port, ctrl, f[0], float(np.linalg.norm(f))))
    final_err = series[-1][1]

    # hold force, energies over every common trace tick
    hold_sum = hold_mean = 0.0
    hold_n = 0
    port_min = 0.0
    for k in common_trace:
        rows = [tk[i][k] for i in range(N)]
        t = k * T
        F = np.array([[r[col["force_x_N"]], r[col["force_y_N"]], r[col["force_z_N"]]] for r in rows])
        port_min = min(port_min, float(sum(r[col["port_energy_J"]] for r in rows)))
        if hold0 <= t < hold1:
            hold_sum += float(np.linalg.norm(F.sum(axis=0)))
            hold_mean += float(np.mean(np.linalg.norm(F, axis=1)))
            hold_n += 1
    k_first = common_trace[0]
    d2 = float(sum(tk[i][k_first][col["vo_energy_J"]] for i in range(N)))

    diverged = any(s["diverged"] for s in st)
    simulated = (common_state[-1] + 1) * T
    consensus_time = None
    if not diverged and final_err < 1e-3 and simulated > release:
        consensus_time = max(0.0, last_violation - release) if any_violation else 0.0

    # links: directed (to <- from)
    by_id = {s["station"]: s for s in st}
    links = []
    tot = dict(sent=0, delivered=0, lost=0, duplicated=0, reordered=0)
    for s in st:
        for l in s["links"]:
            to, frm = s["station"], l["peer"]
            tx = next(m for m in by_id[frm]["links"] if m["peer"] == to)
            sent = tx["tx_packets_run"]
            lost = tx["tx_impair_lost_run"]
            dup = tx["tx_impair_duplicated_run"]
            deliv = l["rx_packets_run"]
            reord = l.get("rx_stale_reordered", 0)
            tot["sent"] += sent
            tot["delivered"] += deliv
            tot["lost"] += lost
            tot["duplicated"] += dup
            tot["reordered"] += reord
            links.append({
                "to": to, "from": frm, "sent": sent, "delivered": deliv, "lost": lost, "duplicated": dup, "reordered": reord,
                "mean_delay_ms": l["one_way_mean_ms"], "max_delay_ms": l["one_way_max_ms"],
                "loss_rate": (lost / sent) if sent else 0.0,
                "measured_loss_rate": l["rx_loss_fraction_measured"],
                "measured_mean_delay_ms": l["one_way_mean_ms"], "measured_max_delay_ms": l["one_way_max_ms"],
                "rtt_mean_ms": l["rtt_mean_ms"], "rtt_max_ms": l["rtt_max_ms"], "rtt_samples": l["rtt_samples"],
                "rtt_over_bound_events": l["rtt_over_bound_events"],
                "round_trip_bound_ticks": l.get("round_trip_bound_ticks"),
                "max_index_delay_ticks": l.get("max_index_delay_ticks", 0),
                "bound_violations": l.get("bound_violations", 0),
                "index_delay_bound_ticks": l.get("index_delay_bound_ticks"),
                "model_index_delay_bound_ticks": l["model_index_delay_bound_ticks"],
            })
    links.sort(key=lambda l: (l["to"], l["from"]))
    # Eq. (18) at station i assumed Nbar_ij + Nbar_ji = 2 ceil(R_i / 2) (its own measured round
    # trip); the guards actually enforced are Nbar_ij (at i) + Nbar_ji (at j). Report whether the
    # enforced sum stays within what BOTH ends assumed (it does when both measured the same R).
    guard = {(l["to"], l["from"]): l["index_delay_bound_ticks"] for l in links}
    assumed = {}
    for s_ in st:
        for l in s_["links"]:
            if l.get("assumed_round_trip_ticks") is not None:
                assumed[(s_["station"], l["peer"])] = l["assumed_round_trip_ticks"]
    consistent_all = True
    for l in links:
        key, rkey = (l["to"], l["from"]), (l["from"], l["to"])
        if None in (guard.get(key), guard.get(rkey), assumed.get(key), assumed.get(rkey)):
            consistent_all = False
            continue
        l["enforced_round_trip_ticks"] = guard[key] + guard[rkey]
        l["assumed_round_trip_ticks_at_receiver"] = assumed[key]
        l["bounds_consistent"] = guard[key] + guard[rkey] <= min(assumed[key], assumed[rkey])
        consistent_all = consistent_all and l["bounds_consistent"]

    speeds = [s["max_node_speed_m_per_s"] for s in st]
    out = {
        "scenario": st[0]["scenario"],
        "mode": "run (%d processes, %s)" % (N, st[0]["transport"]),
        "users": N,
        "dt_s": T,
        "duration_s": st[0]["duration_s"],
        "simulated_s": simulated,
        "seed": st[0]["seed"],
        "topology": st[0]["topology"],
        "scene_nodes": st[0]["scene_nodes"],
        "damping_Ns_per_m": [s["damping_Ns_per_m"] for s in st],
        "damping_min_Ns_per_m": [s["damping_min_Ns_per_m"] for s in st],
        "damping_model_Ns_per_m": [s["damping_model_Ns_per_m"] for s in st],
        "damping_margin": st[0]["damping_margin"],
        "loss_allowance_ticks": st[0]["loss_allowance_ticks"],
        # eq. (18) holds at every station for the bounds enforced at both ends of every link
        "passivity_condition_met": all(s["passivity_condition_met"] for s in st) and consistent_all,
        "damping_condition_met_per_station": [s["passivity_condition_met"] for s in st],
        "bounds_consistent_all_links": consistent_all,
        "release_time_s": release,
        "consensus_error_m": final_err,
        "max_consensus_error_m": max_err,
        "consensus_time_s": consensus_time,
        "consensus_time_resolution_s": (common_state[1] - common_state[0]) * T if len(common_state) > 1 else T,
        "hold_window_s": [hold0, hold1],
        "hold_force_sum_N": hold_sum / hold_n if hold_n else 0.0,
        "hold_force_mean_N": hold_mean / hold_n if hold_n else 0.0,
        "hold_force_balance_ratio": (hold_sum / hold_mean) if hold_mean > 0 else 0.0,
        "port_energy_min_J": port_min,
        "passivity_bound_J": d2,
        "port_energy_final_J": [s.get("port_energy_final_J") for s in st],
        "controller_energy_final_J": [s.get("controller_energy_final_J") for s in st],
        "diverged": diverged,
        "diverged_at_s": min([s["diverged_at_s"] for s in st if s["diverged"]], default=None),
        "max_node_speed_m_per_s": "inf" if any(isinstance(v, str) for v in speeds) else max(speeds),
        "packets": tot,
        "link_stats": links,
        "stations": [{
            "station": s["station"], "ticks_run": s["ticks_run"], "overruns": s["loop"]["overruns"],
            "missed_cycles": s["loop"]["missed_cycles"], "edge_drop_events": s.get("edge_drop_events", 0),
            "fully_real_time": s["rt"]["fully_real_time"], "rt_warnings": s["rt"]["warnings"],
            "stopped_by_signal": s["stopped_by_signal"], "device": s["device"], "wall_time_s": s["wall_time_s"],
        } for s in st],
    }
    json.dump(out, open(os.path.join(run, "summary.json"), "w"), indent=2)

    with open(os.path.join(run, "trace.csv"), "w") as f:
        f.write("t_s,user,node_x_m,node_y_m,node_z_m,force_x_N,force_y_N,force_z_N,vp_x_m,vp_y_m,vp_z_m,"
                "device_x_m,device_y_m,device_z_m,port_energy_J,controller_energy_J,vo_energy_J,contact\n")
        names = ["node_x_m", "node_y_m", "node_z_m", "force_x_N", "force_y_N", "force_z_N", "vp_x_m", "vp_y_m", "vp_z_m",
                 "device_x_m", "device_y_m", "device_z_m", "port_energy_J", "controller_energy_J", "vo_energy_J"]
        for k in common_trace:
            for i in range(N):
                r = tk[i][k]
                f.write("%.4f,%d,%s,%d\n" % ((k + 1) * T, i + 1, ",".join("%.7g" % r[col[c]] for c in names), int(r[col["contact"]])))
    with open(os.path.join(run, "series.csv"), "w") as f:
        f.write("t_s,consensus_error_m,deformation_m,port_energy_total_J,controller_energy_total_J,force_sum_x_N,force_sum_norm_N\n")
        for row in series:
            f.write("%.4f,%.7g,%.7g,%.7g,%.7g,%.6g,%.6g\n" % row)
    ct = "never" if consensus_time is None else "%.3f s" % consensus_time
    print("merge_run.py: %s: %s, consensus error at end %.4f mm, consensus time after release %s, hold |sum u| %.4f N vs mean |u_i| %.4f N, "
          "min port energy %.6f J (bound -%.6f J), packets sent %d delivered %d; wrote summary.json, trace.csv, series.csv"
          % (out["scenario"], "DIVERGED" if diverged else "stable", final_err * 1e3, ct, out["hold_force_sum_N"], out["hold_force_mean_N"],
             port_min, d2, tot["sent"], tot["delivered"]))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
