#!/usr/bin/env python3
"""`haptic-station sim` with and without its figures, for two builds ALTERNATELY, round after round
(the order flips every round): wall time, CPU time (user + sys of the process and its children)
and peak memory (the largest resident set of the process or of a child it waited for) of each,
the ratio with/without figures per build, and trace.csv's size. Every raw measurement goes to one
JSON file (--out), with the load average at each.

  tools/bench/figures_time.py --old /work/wt-int3/build/bin/haptic-station --new build/bin/haptic-station \
      --rounds 7 --work /tmp/figtime --out tools/bench/results/figures_time.json [--users 4] [-- SIM OPTIONS]

Each build's figure script is its own (share/haptic/tools next to the binary). Not a unit test.
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import time


def one(binary, out, users, extra, plots):
    """One `sim` run: (wall s, cpu s, peak RSS MB, trace.csv MB)."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [binary, "sim", "--scenario", "paper-best", "--users", str(users), "--out", out, "--quiet"] + extra + ([] if plots else ["--no-plots"])
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.monotonic() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit("failed: %s" % " ".join(cmd))
    pngs = [f for f in os.listdir(out) if f.endswith(".png")]
    if plots and len(pngs) != 5:
        raise SystemExit("%s drew %d figures, not 5" % (" ".join(cmd), len(pngs)))
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "peak_rss_MB": ru.ru_maxrss / 1024.0,
            "trace_MB": os.path.getsize(os.path.join(out, "trace.csv")) / 1e6, "load1": os.getloadavg()[0], "command": " ".join(cmd)}


def med(rows, key):
    return statistics.median(r[key] for r in rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--users", type=int, default=4)
    ap.add_argument("--work", default="/tmp/figtime")
    ap.add_argument("--out", required=True)
    ap.add_argument("extra", nargs="*", help="more sim options (after --)")
    a = ap.parse_args()
    cases = [("old", a.old, True), ("old", a.old, False), ("new", a.new, True), ("new", a.new, False)]
    raw = {"%s_%s" % (b, "figures" if p else "no_plots"): [] for b, _, p in cases}
    for r in range(a.rounds):
        for build, binary, plots in (cases if r % 2 == 0 else cases[::-1]):
            key = "%s_%s" % (build, "figures" if plots else "no_plots")
            raw[key].append(one(binary, os.path.join(a.work, key), a.users, a.extra, plots))
            print("round %d %-16s wall %.2f s cpu %.2f s peak %.0f MB trace %.1f MB load %.1f" % (
                r + 1, key, *(raw[key][-1][k] for k in ("wall_s", "cpu_s", "peak_rss_MB", "trace_MB", "load1"))), flush=True)
    summary = {}
    for build in ("old", "new"):
        w, n = raw[build + "_figures"], raw[build + "_no_plots"]
        summary[build] = {"wall_s_figures_median": med(w, "wall_s"), "wall_s_no_plots_median": med(n, "wall_s"),
                          "cpu_s_figures_median": med(w, "cpu_s"), "cpu_s_no_plots_median": med(n, "cpu_s"),
                          "ratio_wall_figures_over_no_plots": med(w, "wall_s") / med(n, "wall_s"),
                          "ratio_wall_per_round_median": statistics.median(x["wall_s"] / y["wall_s"] for x, y in zip(w, n)),
                          "ratio_cpu_figures_over_no_plots": med(w, "cpu_s") / med(n, "cpu_s"),
                          "peak_rss_MB_figures_max": max(x["peak_rss_MB"] for x in w), "peak_rss_MB_no_plots_max": max(x["peak_rss_MB"] for x in n),
                          "trace_MB": w[0]["trace_MB"]}
    summary["new_over_old_wall_figures"] = summary["new"]["wall_s_figures_median"] / summary["old"]["wall_s_figures_median"]
    doc = {"tool": "tools/bench/figures_time.py", "command": " ".join(["tools/bench/figures_time.py", "--old", a.old, "--new", a.new, "--rounds",
                                                                      str(a.rounds), "--users", str(a.users), "--out", a.out] + (["--"] + a.extra if a.extra else [])),
           "cpus": len(os.sched_getaffinity(0)), "summary": summary, "raw": raw}
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    json.dump(doc, open(a.out, "w"), indent=1)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
