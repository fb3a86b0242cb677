#!/usr/bin/python3
"""The figures' decimation keeps what a reader sees (tools/plots/plot_run.py decimate): on a noisy
series with isolated one-sample spikes (at most one per bucket), every kept point is a sample, in time order; every bucket of equal
sample count keeps its lowest and highest sample, so no spike is lost; the first and last sample
are kept; at most two points per bucket (plus the remainder's two); a short series is drawn whole.
Exit 0 when all hold, 1 with the reasons. Usage: decimate_check.py PLOT_RUN_DIR"""
import sys

import numpy as np

sys.path.insert(0, sys.argv[1])
import plot_run  # noqa: E402

fail = []
rng = np.random.default_rng(7)
for n, buckets in ((10007, 1000), (40000, 1000), (2500, 100)):
    t = 0.002 * np.arange(1, n + 1)
    y = np.cumsum(rng.normal(size=n))
    k = n // buckets
    spikes = rng.choice(buckets, 25, replace=False) * k + rng.integers(0, k, 25)  # one per bucket, anywhere in it
    if n % buckets > 2:  # and one in the samples after the last whole bucket
        spikes[-1] = n - 2
    y[spikes] += np.where(np.arange(25) % 2, 1e3, -1e3)  # up and down, one sample wide
    td, yd = plot_run.decimate(t, y, buckets)
    idx = np.searchsorted(t, td)
    if not (np.all(np.diff(td) > 0) and np.array_equal(t[idx], td) and np.array_equal(y[idx], yd)):
        fail.append("n = %d: kept points are not samples in time order" % n)
        continue
    if len(td) > 2 * buckets + 4:
        fail.append("n = %d: %d points kept for %d buckets" % (n, len(td), buckets))
    if idx[0] != 0 or idx[-1] != n - 1:
        fail.append("n = %d: first or last sample dropped" % n)
    lost = [s for s in spikes if s not in set(idx)]
    if lost:
        fail.append("n = %d: spikes at samples %s dropped" % (n, lost[:5]))
    for b in range(buckets):
        seg = y[b * k:(b + 1) * k]
        kept = yd[(idx >= b * k) & (idx < (b + 1) * k)]
        if len(kept) == 0 or kept.min() != seg.min() or kept.max() != seg.max():
            fail.append("n = %d: bucket %d does not keep its extremes" % (n, b))
            break
short_t, short_y = np.arange(50.0), rng.normal(size=50)
if not np.array_equal(plot_run.decimate(short_t, short_y, 1000)[1], short_y):
    fail.append("a series shorter than two points per bucket is not drawn whole")
if fail:
    print("FAILED:\n  " + "\n  ".join(fail))
    sys.exit(1)
print("decimation ok: samples only, every bucket's extremes and every spike kept, <= 2 points per bucket")
