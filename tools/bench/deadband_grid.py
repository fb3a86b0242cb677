#!/usr/bin/env python3
"""Transmission deadband on paper-best, like with like: every deadband run is compared
with the full-rate run of the SAME passivity method and seed (eq. 18's B_i, or the set-position
modulation with E0 = 1 mJ, the station default). Writes one JSON with each run's command, metrics
and its differences from its baseline; prints a table.

  tools/bench/deadband_grid.py [--bin build/bin/haptic-station] [--out tools/bench/results/deadband_paper_best.json]
                               [--seeds 1,2,3,4,5]
  tools/bench/deadband_grid.py --runs FULL_DIR DEADBAND_DIR --out JSON   # two merged four-process runs
                                                                          # (tools/run4/run4.sh / haptic-lab)

Families (seed 1 for the grids, every seed of --seeds for the recommended point and its baselines):
  eq18   full rate; plain deadband, band 0.005-0.05 mm x max interval 2-6 and 8 (Nbar_ij grows by (L + 1)(interval - 1))
  pspm   full rate; full rate with receiver prediction only (a control); plain deadband 0.001 mm / 20 and
         0.01 mm / 8; predictive deadband (--tx-predict) band 0.001-0.01 mm x interval 10, 20, 100
  pspm-worst  the same on paper-worst (long jittered delays), first seed: full rate, plain 0.001 mm / 20,
         the recommended predictive point
"Fewer" compares states per second in each window (hold window; from the run's own consensus time to
the end), so runs with different consensus times are compared fairly.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

PSPM = ["--consensus-passivity", "pspm", "--pspm-reservoir-J", "0.001"]
RECOMMENDED = ["--tx-deadband-mm", "0.001", "--tx-max-interval", "20", "--tx-predict"]


def run(binary, args, tmp, scenario="paper-best"):
    out = os.path.join(tmp, "run")
    cmd = [binary, "sim", "--scenario", scenario, "--out", out, "--no-plots", "--quiet"] + args
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    p, h = s["packets"], s["hold_window_s"]
    return {
        "args": " ".join(args),
        "consensus_time_s": s["consensus_time_s"],
        "consensus_time_10pct_s": s["consensus_time_10pct_s"],
        "consensus_time_1pct_s": s["consensus_time_1pct_s"],
        "hold_force_sum_N": s["hold_force_sum_N"],
        "hold_force_mean_N": s["hold_force_mean_N"],
        "hold_force_balance_ratio": s["hold_force_balance_ratio"],
        "B_i_Ns_per_m": s["damping_Ns_per_m"],
        "bound_violations": sum(l["bound_violations"] for l in s["link_stats"]),
        "packets_per_s_per_link": [l["packets_per_s"] for l in s["link_stats"]],
        "bytes_per_s_per_link": [l["bytes_per_s"] for l in s["link_stats"]],
        "rate_total_per_s": p["sent"] / s["simulated_s"],
        "rate_hold_per_s": p["sent_in_hold_window"] / (h[1] - h[0]),
        "rate_after_consensus_per_s": p["sent_after_consensus"] / p["after_consensus_s"] if p["after_consensus_s"] > 0 else None,
    }


def compare(base, r):
    def rel(a, b):
        return None if a is None or b is None or b == 0 else a / b - 1

    r["vs_full_rate"] = {
        "consensus_time": rel(r["consensus_time_s"], base["consensus_time_s"]),
        "consensus_time_1pct": rel(r["consensus_time_1pct_s"], base["consensus_time_1pct_s"]),
        "hold_force_sum": rel(r["hold_force_sum_N"], base["hold_force_sum_N"]),
        "fewer_states_total": -rel(r["rate_total_per_s"], base["rate_total_per_s"]),
        "fewer_states_hold": -rel(r["rate_hold_per_s"], base["rate_hold_per_s"]),
        "fewer_states_after_consensus": -rel(r["rate_after_consensus_per_s"], base["rate_after_consensus_per_s"]),
    }
    v = r["vs_full_rate"]
    r["meets_target"] = None if r is base else (v["fewer_states_hold"] >= 0.8 and v["fewer_states_after_consensus"] >= 0.8 and
                         abs(v["consensus_time"]) <= 0.05 and abs(v["hold_force_sum"]) <= 0.05)
    return r


def merged_run(d):
    with open(os.path.join(d, "summary.json")) as f:
        s = json.load(f)
    p, h = s["packets"], s["hold_window_s"]
    after = p.get("sent_after_consensus")
    r = {"dir": d, "mode": s["mode"], "tx_deadband": s.get("tx_deadband"), "consensus_passivity": s.get("consensus_passivity"),
         "consensus_time_s": s["consensus_time_s"], "consensus_time_10pct_s": s["consensus_time_10pct_s"],
         "consensus_time_1pct_s": s["consensus_time_1pct_s"], "hold_force_sum_N": s["hold_force_sum_N"],
         "hold_force_mean_N": s["hold_force_mean_N"], "hold_force_balance_ratio": s["hold_force_balance_ratio"],
         "B_i_Ns_per_m": s["damping_Ns_per_m"], "stations": s["stations"],
         "links": [{k: l.get(k) for k in ("from", "to", "packets_per_s", "bytes_per_s", "sent", "sent_in_hold_window", "sent_after_consensus",
                                          "loss_rate", "max_index_delay_ticks", "bound_violations")} for l in s["link_stats"]],
         "rate_total_per_s": p["sent"] / s["simulated_s"],
         "rate_hold_per_s": p["sent_in_hold_window"] / (h[1] - h[0]),
         "rate_after_consensus_per_s": after / p["after_consensus_s"] if after is not None and p["after_consensus_s"] > 0 else None}
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default="build/bin/haptic-station")
    ap.add_argument("--out", default="tools/bench/results/deadband_paper_best.json")
    ap.add_argument("--seeds", default="1,2,3,4,5")
    ap.add_argument("--runs", nargs=2, metavar=("FULL_DIR", "DEADBAND_DIR"), help="compare two merged four-process runs instead")
    a = ap.parse_args()
    if a.runs:
        base, r = merged_run(a.runs[0]), merged_run(a.runs[1])
        out = {"command": "tools/bench/deadband_grid.py --runs " + " ".join(a.runs) + " --out " + a.out,
               "full_rate": compare(base, base), "deadband": compare(base, r)}
        with open(a.out, "w") as f:
            json.dump(out, f, indent=1)
        for name, x in (("full rate", base), ("deadband", r)):
            print(name, "consensus %.3f s, hold |sum u| %.4f N," % (x["consensus_time_s"], x["hold_force_sum_N"]),
                  ", ".join("%d->%d %.1f packets/s %.0f B/s" % (l["from"], l["to"], l["packets_per_s"], l["bytes_per_s"]) for l in x["links"]))
        print("vs full rate:", json.dumps(r["vs_full_rate"]), "meets target:", r["meets_target"])
        return 0
    seeds = [int(s) for s in a.seeds.split(",")]
    variants = {"eq18": [], "pspm": [["--tx-predict"], ["--tx-deadband-mm", "0.001", "--tx-max-interval", "20"],
                                     ["--tx-deadband-mm", "0.01", "--tx-max-interval", "8"]]}
    for b in ("0.005", "0.01", "0.02", "0.05"):
        for i in ("2", "3", "4", "5", "6", "8"):
            variants["eq18"].append(["--tx-deadband-mm", b, "--tx-max-interval", i])
    for b in ("0.001", "0.002", "0.005", "0.01"):
        for i in ("10", "20", "100"):
            variants["pspm"].append(["--tx-deadband-mm", b, "--tx-max-interval", i, "--tx-predict"])
    result = {"command": "tools/bench/deadband_grid.py --bin " + a.bin + " --out " + a.out + " --seeds " + a.seeds,
              "sim": a.bin + " sim --scenario paper-best --out DIR --no-plots --quiet [family args] [variant args] [--seed S]",
              "families": {"eq18": "", "pspm": " ".join(PSPM)}, "recommended": " ".join(PSPM + RECOMMENDED), "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        for fam, fam_args in (("eq18", []), ("pspm", PSPM)):
            for seed in seeds:
                sa = ["--seed", str(seed)]
                base = run(a.bin, fam_args + sa, tmp)
                base.update(family=fam, seed=seed, variant="full rate")
                result["runs"].append(compare(base, base))
                todo = variants[fam] if seed == seeds[0] else []
                if fam == "pspm" and seed != seeds[0]:
                    todo = [["--tx-predict"], RECOMMENDED]
                for v in todo:
                    r = run(a.bin, fam_args + v + sa, tmp)
                    r.update(family=fam, seed=seed, variant=" ".join(v))
                    result["runs"].append(compare(base, r))
        sa = ["--seed", str(seeds[0])]
        base = run(a.bin, PSPM + sa, tmp, "paper-worst")
        base.update(family="pspm-worst", seed=seeds[0], variant="full rate")
        result["runs"].append(compare(base, base))
        for v in (["--tx-deadband-mm", "0.001", "--tx-max-interval", "20"], RECOMMENDED):
            r = run(a.bin, PSPM + v + sa, tmp, "paper-worst")
            r.update(family="pspm-worst", seed=seeds[0], variant=" ".join(v))
            result["runs"].append(compare(base, r))
    with open(a.out, "w") as f:
        json.dump(result, f, indent=1)
    print("%-10s %-4s %-62s %8s %8s %8s %8s %8s %s" % ("fam", "seed", "variant", "ct_s", "dct", "d|Su|", "fewer_h", "fewer_a", "target"))
    for r in result["runs"]:
        v = r["vs_full_rate"]
        print("%-10s %-4d %-62s %8.3f %+8.3f %+8.3f %8.3f %8.3f %s" % (r["family"], r["seed"], r["variant"], r["consensus_time_s"],
              v["consensus_time"], v["hold_force_sum"], v["fewer_states_hold"], v["fewer_states_after_consensus"], r["meets_target"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
