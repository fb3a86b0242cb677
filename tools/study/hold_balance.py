#!/usr/bin/python3
"""Hold-force balance (eq. 20) of a `haptic-station sim` run folder (summary.json, trace.csv; pass
--trace-every 50 or so to keep trace.csv small).

Eq. (20): if every v_i -> 0, sum_i f_i -> K (xbar - x_d), whose net force is 0 (1^T K_int = 0): the
users' forces balance once the object has stopped. With asymmetric pushes the floating object must
first drift to where the hands' springs balance; while it drifts, every damping that acts on the
absolute node velocities drags it: eq. (18)'s B_i on every node of every copy (n x sum_i B_i) and
the delayed P coupling (about p/2 per node per directed link x its one-way delay). So during the hold
    sum_i u_i = -C v_drift,
and |sum u| decays with the drift, with time constant C / (the hands' stiffness on the object).
This prints, over the hold [push_end + 1 s, release): |sum u| / mean |u_i| at push_end + 2 s and in
the last 1 s, an exponential fit of |sum u| (time constant), and the drag check: |sum u| against
the drift speed of the object (the trace node, averaged over the copies) -> C and the angle between
-sum u and v (0 deg: the residual force is the drag on the drift), next to n x sum_i B_i.
Usage: hold_balance.py RUN_DIR [--json]"""
import csv
import json
import math
import sys


def main():
    if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(sys.argv) >= 2 else 2
    run = sys.argv[1]
    s = json.load(open(f"{run}/summary.json"))
    push_end, release = s["push_end_s"], s["release_time_s"]
    rows = {}
    with open(f"{run}/trace.csv") as f:
        for r in csv.DictReader(f):
            rows.setdefault(float(r["t_s"]), []).append(r)
    ts = sorted(t for t in rows if push_end + 1.0 <= t < release and len(rows[t]) == s["users"])
    if len(ts) < 4:
        print(f"{run}: fewer than 4 trace samples in the hold [{push_end + 1}, {release}) s", file=sys.stderr)
        return 1
    vec = lambda rs, keys: [sum(float(r[k]) for r in rs) for k in keys]
    norm = lambda v: math.sqrt(sum(c * c for c in v))
    F, P = ("force_x_N", "force_y_N", "force_z_N"), ("node_x_m", "node_y_m", "node_z_m")
    pts = []  # t, |sum u|, mean |u_i|, mean trace-node position over the copies
    for t in ts:
        rs = rows[t]
        mean_u = sum(norm([float(r[k]) for k in F]) for r in rs) / len(rs)
        pts.append((t, norm(vec(rs, F)), mean_u, [c / len(rs) for c in vec(rs, P)], vec(rs, F)))
    at = lambda T: min(pts, key=lambda p: abs(p[0] - T))
    end = [p for p in pts if p[0] >= release - 1.0]
    ratio_end = sum(p[1] for p in end) / sum(p[2] for p in end)
    fit = [(p[0], math.log(p[1])) for p in pts if p[1] > 1e-12]
    mt = sum(t for t, _ in fit) / len(fit)
    my = sum(y for _, y in fit) / len(fit)
    slope = sum((t - mt) * (y - my) for t, y in fit) / sum((t - mt) ** 2 for t, _ in fit)
    drag = []  # over the second half of the hold: C = |sum u| / |v|, angle(-sum u, v)
    half = [p for p in pts if p[0] >= push_end + 0.5 * (release - push_end)]
    for a, b in zip(half, half[1:]):
        v = [(q - p) / (b[0] - a[0]) for p, q in zip(a[3], b[3])]
        if norm(v) > 0 and b[1] > 0:
            cos = -sum(x * y for x, y in zip(v, b[4])) / (norm(v) * b[1])
            drag.append((b[1] / norm(v), cos))
    drag.sort()
    c_med = drag[len(drag) // 2][0] if drag else None
    cos_med = sorted(c for _, c in drag)[len(drag) // 2] if drag else None
    nB = s["scene_nodes"] * sum(s["damping_Ns_per_m"])
    out = {"run": run, "users": s["users"], "consensus_passivity": s["consensus_passivity"],
           "push_imbalance_ratio": round(s["push_imbalance_ratio"], 3), "push_end_s": push_end, "release_s": release,
           "ratio_at_push_end_plus_2s": round(at(push_end + 2)[1] / at(push_end + 2)[2], 3),
           "ratio_last_1s_of_hold": round(ratio_end, 4),
           "sum_u_last_1s_N": round(sum(p[1] for p in end) / len(end), 4),
           "mean_u_last_1s_N": round(sum(p[2] for p in end) / len(end), 3),
           "time_constant_s": round(-1 / slope, 2) if slope < 0 else None,
           "drag_Ns_per_m": round(c_med) if c_med else None,
           "drag_angle_deg": round(math.degrees(math.acos(max(-1, min(1, cos_med)))), 1) if cos_med is not None else None,
           "n_sum_B_i_Ns_per_m": round(nB),
           "consensus_time_s": s["consensus_time_s"], "passivity_condition_met": s["passivity_condition_met"],
           "unstable": s.get("unstable"), "wall_time_s": round(s["wall_time_s"], 2), "simulated_s": s["simulated_s"]}
    if "--json" in sys.argv:
        print(json.dumps(out))
    else:
        print(f"{run}: {s['users']} users, hold {push_end}-{release} s: |sum u|/mean |u_i| {out['ratio_at_push_end_plus_2s']} at "
              f"push end + 2 s, {out['ratio_last_1s_of_hold']} in the last 1 s ({out['sum_u_last_1s_N']} N vs {out['mean_u_last_1s_N']} N); "
              f"time constant {out['time_constant_s']} s; drag |sum u|/v {out['drag_Ns_per_m']} N s/m at "
              f"{out['drag_angle_deg']} deg from -v (n x sum B_i = {out['n_sum_B_i_Ns_per_m']} N s/m)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
