#!/usr/bin/env python3
"""The station's real tick with two browsers on its live view against none.

tools/bench/view_record_bench.cpp times the tick back to back on an ordinary thread, where two
software-rendering browsers on the same 2 vCPUs simply take CPU from it. This measures what a lab
station does: four `haptic-station run` processes (tools/run4/run4.sh, UDP on loopback, the tick at
SCHED_FIFO when permitted) with station 1 serving its live view and recording its session
(station.record = true: the log's /ticks/exec_ns and wake_latency_ns are every tick's execution time
and wake-up latency). Rounds alternate "none" and "two browsers" (two headless Chromium pages on
station 1's view for the whole run). Per run: station 1's tick execution time (median, P99, max) and
wake-up latency (P99, max) over the run's ticks, overruns, frames the view sent. Writes JSON.
Run it under /tmp/haptic-multiproc.lock (several processes, fixed ports).
Usage: view_browsers_run4.py --bin build/bin/haptic-station --out DIR --json FILE [--rounds 2] [--duration 15]
       [--port 46050] [--nodes N]"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.request

import h5py
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
run4 = os.path.join(here, "..", "run4", "run4.sh")


def wait_page(port, seconds):
    end = time.time() + seconds
    while time.time() < end:
        try:
            if b"view.js" in urllib.request.urlopen("http://127.0.0.1:%d/" % port, timeout=1).read():
                return True
        except OSError:
            pass
        time.sleep(0.1)
    return False


def one_run(a, mode, out):
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cmd = [run4, "--transport", "udp", "--bin", a.bin, "--out", out + "/run4", "--duration", str(a.duration), "--push-end", "2",
           "--release", str(a.duration / 2), "--probe", "1.0", "--seed", "2", "--no-plots", "--view-port", str(a.port),
           "--station", "record=true", "--station", "max_no_neighbour_fraction=1.0"]
    if a.nodes:
        cmd += ["--nodes", str(a.nodes)]
    log = open(out + "/run4.log", "w")
    r = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    pages = []
    if mode == "two_browsers":
        if not wait_page(a.port, 60):
            r.terminate()
            raise SystemExit("station 1's view never listened on %d" % a.port)
        for p in range(2):
            prof = "%s/profile-%d" % (out, p)
            pages.append(subprocess.Popen(["chromium", "--headless=new", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                                           "--use-angle=swiftshader", "--user-data-dir=" + prof, "--window-size=1400,900",
                                           "--timeout=%d" % int(1000 * (a.duration + 20)), "--screenshot=%s/page-%d.png" % (out, p),
                                           "http://127.0.0.1:%d/" % a.port], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    rc = r.wait(timeout=a.duration + 120)
    for p in pages:
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=20)
    st = json.load(open(out + "/run4/station-1.json"))
    with h5py.File(out + "/run4/station-1.h5", "r") as f:
        ex = f["ticks/exec_ns"][:] * 1e-3
        wk = f["ticks/wake_latency_ns"][:] * 1e-3
    view = st["recording"].get("view", {})
    return {"mode": mode, "exit": rc, "ticks": int(ex.size), "overruns": st["loop"]["overruns"], "missed_cycles": st["loop"]["missed_cycles"],
            "exec_us": {"median": float(np.median(ex)), "p99": float(np.percentile(ex, 99)), "max": float(ex.max())},
            "wake_us": {"median": float(np.median(wk)), "p99": float(np.percentile(wk, 99)), "max": float(wk.max())},
            "view_browsers": view.get("browsers"), "view_frames_sent": view.get("frames_sent"),
            "scheduling": st["rt"]["summary"].splitlines()[1] if "rt" in st else ""}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--json", required=True)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--duration", type=float, default=15)
    ap.add_argument("--port", type=int, default=46050)
    ap.add_argument("--nodes", type=int, default=0)
    a = ap.parse_args()
    if not shutil.which("chromium"):
        print("SKIPPED: chromium is not installed")
        return 77
    runs = []
    for k in range(a.rounds):
        order = ("none", "two_browsers") if k % 2 == 0 else ("two_browsers", "none")
        for mode in order:
            r = one_run(a, mode, "%s/%d-%s" % (a.out, k, mode))
            runs.append(r)
            print("%-12s exit %d, %d ticks, exec median %.1f p99 %.1f max %.0f us, wake p99 %.0f max %.0f us, overruns %d, browsers %s, frames sent %s" % (
                mode, r["exit"], r["ticks"], r["exec_us"]["median"], r["exec_us"]["p99"], r["exec_us"]["max"], r["wake_us"]["p99"], r["wake_us"]["max"],
                r["overruns"], r["view_browsers"], r["view_frames_sent"]), flush=True)
    summary = {}
    for mode in ("none", "two_browsers"):
        rr = [r for r in runs if r["mode"] == mode]
        summary[mode] = {k: float(np.median([r[g][s] for r in rr])) for g in ("exec_us", "wake_us") for s in ("median", "p99", "max") for k in ["%s_%s" % (g, s)]}
    summary["ratio_two_browsers_over_none"] = {k: summary["two_browsers"][k] / summary["none"][k] for k in summary["none"]}
    json.dump({"tool": "tools/bench/view_browsers_run4.py", "command": " ".join(sys.argv), "runs": runs, "median_over_rounds": summary},
              open(a.json, "w"), indent=1)
    print(json.dumps(summary["ratio_two_browsers_over_none"]))
    return 0 if all(r["exit"] == 0 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
