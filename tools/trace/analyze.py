#!/usr/bin/python3
"""Timing analysis of an LTTng trace of provider 'haptic' (recorded with tools/trace/record.sh).

Per traced process (station), from the events of platform/trace_provider.h:
  wake-up latency   tick_begin.wake_latency_ns (actual wake - absolute deadline)
  tick execution    tick_end.exec_ns (the loop's own measurement) and tick_end - tick_begin timestamps
  stage breakdown   stage_end - stage_begin per stage id (solve, rx_drain, ...)
  deadline misses   overrun events (ticks that ended after the next deadline) and missed cycles
  period jitter     (tick_begin[k] - tick_begin[k-1]) - (scheduled[k] - scheduled[k-1])
Prints tables, optionally writes JSON (--json) and histogram PNGs (--plots DIR).
Run with Debian's /usr/bin/python3 (python3-bt2, python3-numpy, python3-matplotlib).
"""
import argparse
import collections
import json
import os
import sys

try:
    import bt2
except ImportError:  # pragma: no cover
    sys.exit("analyze.py: python3-bt2 is missing (apt install python3-bt2) or this is not /usr/bin/python3")
import numpy as np

# Same ids as haptic::platform::trace::Stage (platform/trace.hpp).
STAGES = {1: "device_read", 2: "rx_drain", 3: "solve", 4: "publish", 5: "tx", 6: "monitor", 7: "telemetry", 8: "workload"}


class Station:
    def __init__(self, vpid, procname):
        self.vpid = vpid
        self.procname = procname
        self.wake_latency_ns = []
        self.exec_ns = []            # tick_end.exec_ns
        self.exec_ts_ns = []         # tick_end ts - tick_begin ts
        self.begin_ts = []           # tick_begin timestamps
        self.scheduled = []          # tick_begin.scheduled_ns
        self.ticks_seen = set()
        self.overruns = 0
        self.missed_cycles = 0
        self.overrun_late_ns = []
        self.stage_ns = collections.defaultdict(list)
        self.open_stage = {}         # (vtid, stage) -> ts
        self.open_tick = {}          # vtid -> (tick, ts)
        self.counts = collections.Counter()


def stats(values_ns):
    a = np.asarray(values_ns, dtype=np.float64) / 1e3
    if a.size == 0:
        return {"n": 0}
    return {"n": int(a.size), "min": float(a.min()), "avg": float(a.mean()), "std": float(a.std()),
            "p99": float(np.percentile(a, 99)), "p999": float(np.percentile(a, 99.9)),
            "p9999": float(np.percentile(a, 99.99)), "max": float(a.max())}


def field(ev, name):
    return int(ev.payload_field[name])


def read_trace(path):
    stations = {}
    discarded = 0
    for msg in bt2.TraceCollectionMessageIterator(path):
        if type(msg) is bt2._DiscardedEventsMessageConst:
            discarded += msg.count or 0
            continue
        if type(msg) is not bt2._EventMessageConst:
            continue
        ev = msg.event
        if not ev.name.startswith("haptic:"):
            continue
        name = ev.name[len("haptic:"):]
        ctx = ev.common_context_field
        vpid = int(ctx["vpid"]) if ctx is not None and "vpid" in ctx else 0
        vtid = int(ctx["vtid"]) if ctx is not None and "vtid" in ctx else 0
        procname = str(ctx["procname"]) if ctx is not None and "procname" in ctx else "?"
        st = stations.get(vpid)
        if st is None:
            st = stations[vpid] = Station(vpid, procname)
        ts = msg.default_clock_snapshot.ns_from_origin
        st.counts[name] += 1
        if name == "tick_begin":
            st.ticks_seen.add(field(ev, "tick"))
            st.wake_latency_ns.append(field(ev, "wake_latency_ns"))
            st.begin_ts.append(ts)
            st.scheduled.append(field(ev, "scheduled_ns"))
            st.open_tick[vtid] = (field(ev, "tick"), ts)
        elif name == "tick_end":
            st.exec_ns.append(field(ev, "exec_ns"))
            tick_ts = st.open_tick.pop(vtid, None)
            if tick_ts is not None and tick_ts[0] == field(ev, "tick"):
                st.exec_ts_ns.append(ts - tick_ts[1])
        elif name == "overrun":
            st.overruns += 1
            st.missed_cycles += field(ev, "missed_cycles")
            st.overrun_late_ns.append(field(ev, "late_ns"))
        elif name == "stage_begin":
            st.open_stage[(vtid, field(ev, "stage"))] = ts
        elif name == "stage_end":
            stage = field(ev, "stage")
            t0 = st.open_stage.pop((vtid, stage), None)
            if t0 is not None:
                st.stage_ns[stage].append(ts - t0)
    return stations, discarded


def analyze_station(st):
    sched = np.asarray(st.scheduled, dtype=np.int64)
    begin = np.asarray(st.begin_ts, dtype=np.int64)
    period_ns = int(np.min(np.diff(sched))) if sched.size > 1 else 0
    jitter = (np.diff(begin) - np.diff(sched)) if sched.size > 1 else np.asarray([])
    duration_s = float(begin[-1] - begin[0]) / 1e9 if begin.size > 1 else 0.0
    exec_us = stats(st.exec_ns)
    return {
        "vpid": st.vpid, "procname": st.procname, "period_us": period_ns / 1e3, "duration_s": duration_s,
        "ticks": len(st.wake_latency_ns), "tick_ends": len(st.exec_ns),
        "overruns": st.overruns, "missed_cycles": st.missed_cycles,
        "deadline_misses": st.overruns,
        "ticks_over_period": int(sum(1 for e in st.exec_ns if period_ns and e > period_ns)),
        "wake_latency_us": stats(st.wake_latency_ns), "exec_us": exec_us, "exec_ts_us": stats(st.exec_ts_ns),
        "period_jitter_us": stats(jitter),
        "stages": {STAGES.get(k, "stage%d" % k): stats(v) for k, v in sorted(st.stage_ns.items())},
        "stage_share_of_exec": {STAGES.get(k, "stage%d" % k): (float(np.sum(v)) / float(np.sum(st.exec_ns)) if st.exec_ns else 0.0)
                                for k, v in sorted(st.stage_ns.items())},
        "events": dict(st.counts),
        "_jitter_ns": jitter,
    }


def row(label, s):
    if s.get("n", 0) == 0:
        return "  %-22s %8s" % (label, "-")
    return "  %-22s %8d %9.1f %9.1f %9.1f %9.1f %9.1f %9.1f" % (label, s["n"], s["min"], s["avg"], s["p99"], s["p999"], s["max"], s["std"])


def print_tables(results, discarded, out):
    header = "  %-22s %8s %9s %9s %9s %9s %9s %9s" % ("(microseconds)", "n", "min", "avg", "P99", "P99.9", "max", "std")
    for r in results:
        print("station vpid %d (%s): period %.0f us, %.1f s, %d ticks, %d deadline misses (overruns), %d missed cycles, "
              "%d ticks longer than a period" % (r["vpid"], r["procname"], r["period_us"], r["duration_s"], r["ticks"],
                                                r["overruns"], r["missed_cycles"], r["ticks_over_period"]), file=out)
        print(header, file=out)
        print(row("wake-up latency", r["wake_latency_us"]), file=out)
        print(row("tick execution", r["exec_us"]), file=out)
        print(row("period jitter", r["period_jitter_us"]), file=out)
        for name, s in r["stages"].items():
            print(row("stage " + name, s) + "   %5.1f%% of exec" % (100.0 * r["stage_share_of_exec"][name]), file=out)
        other = {k: v for k, v in r["events"].items() if k in ("packet_rx", "packet_tx", "device_read", "device_write")}
        if other:
            print("  events: " + ", ".join("%s %d" % kv for kv in sorted(other.items())), file=out)
        print(file=out)
    if discarded:
        print("WARNING: %d events were discarded by the tracer: counts above are lower bounds" % discarded, file=out)


def plot(results, outdir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(outdir, exist_ok=True)
    written = []
    for r in results:
        st = r["_station"]
        fig, axes = plt.subplots(2, 2, figsize=(11, 7))
        fig.suptitle("%s (vpid %d), period %.0f us, %d ticks, %d overruns" % (r["procname"], r["vpid"], r["period_us"], r["ticks"], r["overruns"]))
        for ax, data, title in ((axes[0][0], st.wake_latency_ns, "wake-up latency"), (axes[0][1], st.exec_ns, "tick execution time"),
                                (axes[1][0], r["_jitter_ns"], "period jitter")):
            a = np.asarray(data, dtype=np.float64) / 1e3
            if a.size:
                ax.hist(a, bins=200, log=True)
            ax.set_title(title)
            ax.set_xlabel("us")
            ax.set_ylabel("ticks (log)")
        ax = axes[1][1]
        names = list(r["stages"].keys())
        if names:
            ax.barh(names, [r["stages"][n]["avg"] for n in names], xerr=None, label="avg")
            ax.barh(names, [r["stages"][n]["p99"] for n in names], alpha=0.4, label="P99")
            ax.legend()
        ax.set_title("per-stage time (us)")
        fig.tight_layout()
        path = os.path.join(outdir, "timing-%s-%d.png" % (r["procname"], r["vpid"]))
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    return written


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trace", help="trace directory written by tools/trace/record.sh")
    ap.add_argument("--json", help="write the results as JSON to this file ('-' = stdout)")
    ap.add_argument("--plots", help="write histogram PNGs into this directory")
    ap.add_argument("--procname", help="only analyse processes with this name")
    ap.add_argument("--vpids", help="only analyse these processes: comma-separated PIDs, or @FILE with one PID a line "
                    "(tools/run4/run4.sh writes station-pids.txt), so other programs traced meanwhile do not count")
    args = ap.parse_args()
    only = None
    if args.vpids:
        text = open(args.vpids[1:]).read() if args.vpids.startswith("@") else args.vpids
        only = {int(t) for t in text.replace(",", " ").split()}

    stations, discarded = read_trace(args.trace)
    results = []
    for vpid in sorted(stations):
        st = stations[vpid]
        if args.procname and st.procname != args.procname:
            continue
        if only is not None and vpid not in only:
            continue
        r = analyze_station(st)
        r["_station"] = st
        results.append(r)
    if not results:
        sys.exit("analyze.py: no haptic:* events in %s (was the program built with HAPTIC_WITH_LTTNG and traced?)" % args.trace)
    print_tables(results, discarded, sys.stdout if args.json != "-" else sys.stderr)
    if args.plots:
        for p in plot(results, args.plots):
            print("plot: %s" % p, file=sys.stderr)
    if args.json:
        doc = {"trace": os.path.abspath(args.trace), "discarded_events": discarded,
               "stations": [{k: v for k, v in r.items() if not k.startswith("_")} for r in results]}
        text = json.dumps(doc, indent=2)
        if args.json == "-":
            print(text)
        else:
            with open(args.json, "w") as f:
                f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
