#!/usr/bin/env python3
"""Session-log size per minute, from files: each case runs
`haptic-station sim ... --record` for 1 s and for 2 s and takes (size(2 s) - size(1 s)) x 60 per
station log, so the header (the core's configuration, ~0.1-4 MB) is not counted as a rate; the
header is reported separately. Cases: the paper's 33-node scene and a ~3000-node ball, as recorded
(float64 packet values in the simulator; a station on the default float32 wire stores float32,
half the packet bytes), with `--record-deflate 1` (HDF5 shuffle + deflate, lossless), and with the
predictive transmission deadband (packets not sent are not recorded). Every log is replayed and must
be bit-exact. Writes JSON with each command.
Usage: log_size.py --bin build/bin/haptic-station --out DIR --json FILE [--cases 33,33z,3000,3000z,3000db]"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

CASES = {
    "33": ("33 nodes (paper-best), float64 packets", []),
    "33z": ("33 nodes, --record-deflate 1", ["--record-deflate", "1"]),
    "3000": ("2945 nodes (--nodes 3000), float64 packets", ["--nodes", "3000"]),
    "3000z": ("2945 nodes, --record-deflate 1", ["--nodes", "3000", "--record-deflate", "1"]),
    "3000db": ("2945 nodes, predictive deadband 0.001 mm, max interval 20 (pspm)",
               ["--nodes", "3000", "--consensus-passivity", "pspm", "--pspm-reservoir-J", "0.001", "--tx-deadband-mm", "0.001",
                "--tx-max-interval", "20", "--tx-predict"]),
}


def sim(a, extra, duration, out):
    shutil.rmtree(out, ignore_errors=True)
    cmd = [a.bin, "sim", "--scenario", "paper-best", "--duration", str(duration), "--push-end", "0.6", "--release", "0.8", "--record",
           "--no-plots", "--quiet", "--out", out] + extra
    t0 = time.time()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    sizes = [os.path.getsize("%s/station-%d.h5" % (out, i)) for i in range(1, 5)]
    return cmd, time.time() - t0, sizes


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--json", required=True)
    ap.add_argument("--cases", default="33,33z,3000,3000z,3000db")
    a = ap.parse_args()
    rows = []
    for c in a.cases.split(","):
        label, extra = CASES[c]
        cmd1, t1, s1 = sim(a, extra, 1, "%s/%s-1" % (a.out, c))
        cmd2, t2, s2 = sim(a, extra, 2, "%s/%s-2" % (a.out, c))
        replay = subprocess.run([a.bin, "replay", "%s/%s-2/station-1.h5" % (a.out, c)], capture_output=True, text=True)
        per_min = [(b - s) * 60 for s, b in zip(s1, s2)]
        r = {"case": c, "label": label, "commands": [" ".join(cmd1), " ".join(cmd2)], "bytes_1s": s1, "bytes_2s": s2,
             "MB_per_min": [round(x / 1e6, 1) for x in per_min], "header_MB_estimate": [round((2 * s - b) / 1e6, 2) for s, b in zip(s1, s2)],
             "sim_wall_s": [round(t1, 1), round(t2, 1)], "replay_station_1": replay.stdout.strip(), "replay_exit": replay.returncode}
        rows.append(r)
        print("%-7s hub %8.1f MB/min, leaves %s MB/min (header ~%.2f MB); sim %.0f/%.0f s; replay exit %d: %s" % (
            c, r["MB_per_min"][0], r["MB_per_min"][1:], r["header_MB_estimate"][0], t1, t2, replay.returncode, r["replay_station_1"]), flush=True)
        shutil.rmtree("%s/%s-1" % (a.out, c), ignore_errors=True)
        shutil.rmtree("%s/%s-2" % (a.out, c), ignore_errors=True)
    json.dump({"tool": "tools/bench/log_size.py", "command": " ".join(sys.argv), "cases": rows}, open(a.json, "w"), indent=1)
    return 0 if all(r["replay_exit"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
