#!/usr/bin/env python3
"""Before/after on a loaded machine: run two Google Benchmark binaries ALTERNATELY, round after
round, with the same filter, and report per benchmark the median and minimum CPU time of each and
the ratio new/old of the medians, of the minima and per round (--time real: real time instead,
e.g. a latency benchmark's manual time). Keeps every raw measurement in one
JSON file (--out) so the figures can be re-derived.

  tools/bench/alternate.py --old OLD_BIN --new NEW_BIN --filter 'BM_Tick/(33|3000|10000)/0$' \
      --rounds 7 --out tools/bench/results/NAME.json [--map 'BM_SparseTick/(\\d+)$=BM_Tick/\\1/0']

--map renames the old binary's benchmarks (regex=replacement) when the names changed between
versions; --old-filter gives the old binary its own filter.
"""
import argparse
import json
import re
import statistics
import subprocess
import sys
import time


def run(binary, flt, min_time, field="cpu_time"):
    out = subprocess.run([binary, f"--benchmark_filter={flt}", f"--benchmark_min_time={min_time}",
                          "--benchmark_format=json"], check=True, capture_output=True, text=True, timeout=900)
    data = json.loads(out.stdout)
    res = {}
    for b in data["benchmarks"]:
        if b.get("error_occurred"):
            continue
        scale = {"ns": 1e-3, "us": 1.0, "ms": 1e3}[b["time_unit"]]
        res[b["name"]] = b[field] * scale
    return res, data.get("context", {})


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--filter", required=True)
    ap.add_argument("--old-filter")
    ap.add_argument("--map", action="append", default=[], help="REGEX=REPLACEMENT for the old binary's names")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--min-time", default="0.2")
    ap.add_argument("--out")
    ap.add_argument("--time", choices=["cpu", "real"], default="cpu",
                    help="which time to compare: cpu (default) or real (e.g. a benchmark's manual time, a latency)")
    a = ap.parse_args()
    if not 1 <= a.rounds <= 50:
        sys.exit("--rounds must be in [1, 50]")
    maps = [m.split("=", 1) for m in a.map]
    rounds = []
    for r in range(a.rounds):
        field = a.time + "_time"
        old, ctx = run(a.old, a.old_filter or a.filter, a.min_time, field)
        for pat, rep in maps:
            old = {re.sub(pat, rep, k): v for k, v in old.items()}
        new, _ = run(a.new, a.filter, a.min_time, field)
        with open("/proc/loadavg") as f:
            load = float(f.read().split()[0])
        rounds.append({"round": r + 1, "old_us": old, "new_us": new, "load1": load, "time": time.time()})
        print(f"round {r + 1}: load {load:.1f}", file=sys.stderr)
    summary = {}
    for name in sorted(set(rounds[0]["old_us"]) & set(rounds[0]["new_us"])):
        o = [x["old_us"][name] for x in rounds if name in x["old_us"]]
        n = [x["new_us"][name] for x in rounds if name in x["new_us"]]
        summary[name] = {
            "old_median_us": statistics.median(o), "new_median_us": statistics.median(n),
            "old_min_us": min(o), "new_min_us": min(n),
            "ratio_of_medians": statistics.median(n) / statistics.median(o),
            "ratio_of_minima": min(n) / min(o),
            "per_round_ratios": [x["new_us"][name] / x["old_us"][name] for x in rounds],
        }
        s = summary[name]
        print(f"{name:40s} old med {s['old_median_us']:9.1f} min {s['old_min_us']:9.1f} | new med {s['new_median_us']:9.1f} "
              f"min {s['new_min_us']:9.1f} | new/old med {s['ratio_of_medians']:.3f} min {s['ratio_of_minima']:.3f}")
    if a.out:
        with open(a.out, "w") as f:
            json.dump({"command": sys.argv, "context": ctx, "rounds": rounds, "summary": summary}, f, indent=1)


if __name__ == "__main__":
    main()
