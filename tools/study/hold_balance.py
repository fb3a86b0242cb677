#!/usr/bin/python3
"""Hold-force balance (eq. 20) of a `haptic-station sim` run folder (summary.json, series.csv; pass
--trace-every 50 or so to keep the files small). It computes no model quantity: the balance, the
sums over stations and the mean copy come from the run's files (firmware/model/metrics.hpp).

Eq. (20): if every v_i -> 0, sum_i f_i -> K (xbar - x_d), whose net force is 0 (1^T K_int = 0): the
users' forces balance once the object has stopped. With asymmetric pushes the floating object must
first drift to where the hands' springs balance; while it drifts, every damping that acts on the
absolute node velocities drags it: eq. (18)'s B_i on every node of every copy (n x sum_i B_i) and
the delayed P coupling (about p/2 per node per directed link x its one-way delay). So during the hold
    sum_i u_i = -C v_drift,
and |sum u| decays with the drift, with time constant C / (the hands' stiffness on the object).
This prints, over the hold [push_end + 1 s, release): series.csv's force_balance_ratio
(|sum u| / mean |u_i|) at push_end + 2 s and at the last sample before the release, summary.json's
hold_force_balance_ratio (over its hold_window_s), an exponential fit of force_sum_norm_N (time
constant), and the drag check: |sum u| against the drift speed of the mean copy's traced node ->
C and the angle between -sum u and v (0 deg: the residual force is the drag on the drift), next to
n x sum_i B_i.
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
    with open(f"{run}/series.csv") as f:
        rows = [r for r in csv.DictReader(f) if push_end + 1.0 <= float(r["t_s"]) < release]
    num = lambda r, k: float(r[k])
    pts = [r for r in rows if not math.isnan(num(r, "force_balance_ratio"))]
    if len(pts) < 4:
        print(f"{run}: fewer than 4 series samples with forces in the hold [{push_end + 1}, {release}) s", file=sys.stderr)
        return 1
    t_of = lambda r: num(r, "t_s")
    norm = lambda v: math.sqrt(sum(c * c for c in v))
    at = lambda T: min(pts, key=lambda r: abs(t_of(r) - T))
    fit = [(t_of(r), math.log(num(r, "force_sum_norm_N"))) for r in pts if num(r, "force_sum_norm_N") > 1e-12]
    mt = sum(t for t, _ in fit) / len(fit)
    my = sum(y for _, y in fit) / len(fit)
    slope = sum((t - mt) * (y - my) for t, y in fit) / sum((t - mt) ** 2 for t, _ in fit)
    drag = []  # over the second half of the hold: C = |sum u| / |v|, angle(-sum u, v)
    half = [r for r in pts if t_of(r) >= push_end + 0.5 * (release - push_end)]
    P = ("trace_node_mean_x_m", "trace_node_mean_y_m", "trace_node_mean_z_m")
    F = ("force_sum_x_N", "force_sum_y_N", "force_sum_z_N")
    for a, b in zip(half, half[1:]):
        v = [(num(b, k) - num(a, k)) / (t_of(b) - t_of(a)) for k in P]
        u = [num(b, k) for k in F]
        if norm(v) > 0 and num(b, "force_sum_norm_N") > 0:
            cos = -sum(x * y for x, y in zip(v, u)) / (norm(v) * num(b, "force_sum_norm_N"))
            drag.append((num(b, "force_sum_norm_N") / norm(v), cos))
    drag.sort()
    c_med = drag[len(drag) // 2][0] if drag else None
    cos_med = sorted(c for _, c in drag)[len(drag) // 2] if drag else None
    nB = s["scene_nodes"] * sum(s["damping_Ns_per_m"])
    out = {"run": run, "users": s["users"], "consensus_passivity": s["consensus_passivity"],
           "push_imbalance_ratio": round(s["push_imbalance_ratio"], 3), "push_end_s": push_end, "release_s": release,
           "ratio_at_push_end_plus_2s": round(num(at(push_end + 2), "force_balance_ratio"), 3),
           "ratio_at_end_of_hold": round(num(pts[-1], "force_balance_ratio"), 4),
           "hold_force_balance_ratio": s["hold_force_balance_ratio"], "hold_window_s": s["hold_window_s"],
           "hold_force_sum_N": s["hold_force_sum_N"], "hold_force_mean_N": s["hold_force_mean_N"],
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
              f"push end + 2 s, {out['ratio_at_end_of_hold']} at the end of the hold; hold_force_balance_ratio "
              f"{out['hold_force_balance_ratio']} over {out['hold_window_s']} s ({out['hold_force_sum_N']} N vs {out['hold_force_mean_N']} N); "
              f"time constant {out['time_constant_s']} s; drag |sum u|/v {out['drag_Ns_per_m']} N s/m at "
              f"{out['drag_angle_deg']} deg from -v (n x sum B_i = {out['n_sum_B_i_Ns_per_m']} N s/m)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
