#!/usr/bin/python3
"""Prints the medians of tools/bench/results/rt_tick.json and the ratios the issues ask for,
and draws tick cost against scene size (rt_tick_scaling.png); with net_oneway_periodic.json
(bench_net --benchmark_filter=Periodic --benchmark_repetitions=N) prints the one-way latency
of our stack against minimal UDP per repetition and draws net_oneway_periodic.png.

usage: /usr/bin/python3 tools/bench/summarize.py RESULTS_DIR
"""
import json
import os
import sys


def medians(path):
    data = json.load(open(path))
    out = {}
    for b in data["benchmarks"]:
        if b.get("aggregate_name") == "median" or b.get("run_type") == "iteration" and "aggregate_name" not in b:
            name = b["run_name"] if "run_name" in b else b["name"]
            out[name] = b
    return out, data.get("context", {})


MODES = [("udp", "minimal UDP"), ("stack_wake", "stack, eventfd wake-up"), ("stack_spin", "stack, tick-synchronous TX")]


def net_oneway(d):
    p = os.path.join(d, "net_oneway_periodic.json")
    if not os.path.exists(p):
        return
    data = json.load(open(p))
    runs = [b for b in data["benchmarks"] if b.get("run_type") == "iteration" and "BM_OneWayPeriodic" in b["name"]]
    print("\none-way latency, 2 ms periodic sender (SCHED_FIFO), modes interleaved period by period (us):")
    print("%-8s %-4s | %-26s | %-26s | %-26s | spin/udp ratio p50 mean p99" % ("payload", "rep", *[m[1] for m in MODES]))
    by_enc = {}
    for b in runs:
        enc = "float32" if "f32:1" in b["name"] else "float64"
        cells = ["p50 %5.0f mean %5.0f p99 %5.0f" % (b[m + "_p50_us"], b[m + "_mean_us"], b[m + "_p99_us"]) for m, _ in MODES]
        r = (b["ratio_stack_spin_p50"], b["ratio_stack_spin_mean"], b["ratio_stack_spin_p99"])
        by_enc.setdefault(enc, []).append(b)
        print("%-8s %-4d | %s | %s | %s | %.2f %.2f %.2f" % (enc, b.get("repetition_index", 0), *cells, *r))
    for enc, bs in by_enc.items():
        med = lambda k: sorted(x[k] for x in bs)[len(bs) // 2]
        print("%s, median over %d repetitions: spin/udp p50 %.2f, mean %.2f, p99 %.2f; eventfd/udp p50 %.2f; spin caught %.0f %%"
              % (enc, len(bs), med("ratio_stack_spin_p50"), med("ratio_stack_spin_mean"), med("ratio_stack_spin_p99"),
                 med("ratio_stack_wake_p50"), 100 * med("spin_caught_fraction")))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(by_enc), figsize=(5 * len(by_enc), 4), sharey=True, squeeze=False)
        for ax, (enc, bs) in zip(axes[0], sorted(by_enc.items())):
            for i, (m, label) in enumerate(MODES):
                xs = [i + 0.12 * (j - len(bs) / 2) for j in range(len(bs))]
                ax.scatter(xs, [b[m + "_p50_us"] for b in bs], marker="o", color="C%d" % i, label=label + " p50")
                ax.scatter(xs, [b[m + "_p99_us"] for b in bs], marker="^", color="C%d" % i, alpha=0.5)
            ax.set_xticks(range(len(MODES)))
            ax.set_xticklabels([m[1] for m in MODES], fontsize=7)
            ax.set_yscale("log")
            ax.set_title("%s (o p50, ^ p99; one dot per repetition)" % enc, fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
        axes[0][0].set_ylabel("one-way latency (us)")
        fig.tight_layout()
        fig.savefig(os.path.join(d, "net_oneway_periodic.png"), dpi=100)
    except ImportError:
        print("matplotlib missing: no plot")


def main(d):
    net_oneway(d)
    p = os.path.join(d, "rt_tick.json")
    if not os.path.exists(p):
        print("no rt_tick.json in", d)
        return
    m, ctx = medians(p)
    print("machine: %s CPUs, load avg %s" % (ctx.get("num_cpus"), ctx.get("load_avg")))
    for name, b in sorted(m.items()):
        print("%-45s real %10.2f us   cpu %10.2f us" % (name, b["real_time"], b["cpu_time"]))
    s33 = m.get("BM_SparseTick/33")
    d33 = m.get("BM_DenseBaselineTick/33")
    if s33 and d33:
        print("33-node tick: sparse %.2f us, dense baseline %.2f us (cpu): dense/sparse = %.1fx" %
              (s33["cpu_time"], d33["cpu_time"], d33["cpu_time"] / s33["cpu_time"]))
    sizes = sorted((int(b.get("nodes", 0)), b["cpu_time"]) for n, b in m.items() if n.startswith("BM_SparseTick/"))
    if sizes:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(6, 4))
            ax.loglog([s for s, _ in sizes], [t for _, t in sizes], "o-", label="sparse tick (cpu, median)")
            dense = sorted((int(b.get("nodes", 0)), b["cpu_time"]) for n, b in m.items() if n.startswith("BM_DenseBaselineTick/"))
            if dense:
                ax.loglog([s for s, _ in dense], [t for _, t in dense], "s--", label="dense baseline")
            ax.axhline(1000, color="r", ls=":", label="1 ms target")
            ax.axhline(2000, color="k", ls=":", label="2 ms period")
            ax.set_xlabel("scene nodes")
            ax.set_ylabel("tick cost (us)")
            ax.legend(fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
            fig.tight_layout()
            fig.savefig(os.path.join(d, "rt_tick_scaling.png"), dpi=100)
        except ImportError:
            print("matplotlib missing: no plot")


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    main(sys.argv[1])
