#!/usr/bin/env python3
"""Checks two headless-Chromium screenshots of the live view and the status text the page reported
back to its server (tests/firmware/view/view_check.sh): the 3D canvas is not blank in either, the mesh
and the plots changed between the two, the status names every expected neighbour, and it counts
PROXIES proxy markers drawn in the 3D view (the page counts its visible markers); fewer than the
run's users must come with a status saying the others' proxies are not known to the station.
Exit 0 when all hold, 1 with the reasons otherwise.
Usage: check_view.py A.png B.png STATUS.txt NEIGHBOUR[,NEIGHBOUR...] PROXIES"""
import re
import sys

import matplotlib.image as mpimg
import numpy as np

a, b = mpimg.imread(sys.argv[1])[..., :3], mpimg.imread(sys.argv[2])[..., :3]
status = open(sys.argv[3], encoding="utf-8", errors="replace").read()
neighbours = [n for n in sys.argv[4].split(",") if n]
proxies = int(sys.argv[5])
fail = []
canvas = (slice(10, 446), slice(10, 566))  # #view3d: 560 x 440 CSS px at (8, 8), window 1400 x 900
plots = (slice(515, 890), slice(10, 1390))  # the six plots under the canvas and timeline
nonwhite = min(float(np.mean(np.any(x[canvas] < 0.95, axis=2))) for x in (a, b))
if nonwhite < 0.03:
    fail.append("3D canvas blank: %.2f %% non-white pixels" % (100 * nonwhite))
for name, x in (("first", a), ("second", b)):  # drawn: the renderer's white background around the object (an undrawn WebGL canvas is black)
    white = float(np.mean(np.all(x[canvas] >= 0.95, axis=2)))
    if white < 0.3:
        fail.append("3D canvas of the %s screenshot not drawn: %.1f %% white background" % (name, 100 * white))
changed_canvas = int(np.sum(np.any(np.abs(a[canvas] - b[canvas]) > 0.02, axis=2)))


def grey(x):  # this copy's shading and edges: grey, not white; the markers and the neighbours' copies are coloured
    return (x.max(axis=2) - x.min(axis=2) < 0.04) & (x.max(axis=2) < 0.93) & (x.max(axis=2) > 0.15)


# the mesh itself moved: pixels grey in both screenshots that changed (the proxy, device and the
# neighbours' copies moving over a frozen mesh change coloured pixels, not these)
changed_mesh = int(np.sum(grey(a[canvas]) & grey(b[canvas]) & np.any(np.abs(a[canvas] - b[canvas]) > 0.02, axis=2)))
changed_plots = int(np.sum(np.any(np.abs(a[plots] - b[plots]) > 0.02, axis=2)))
if changed_mesh < 100:
    fail.append("mesh did not change between the screenshots (%d grey pixels of this copy changed, %d canvas pixels)" % (changed_mesh, changed_canvas))
# curves drawn: coloured pixels of the plots in the later screenshot (the legends' boxes alone are ~800;
# six plots with their curves ~6000)
curves = int(np.sum((b[plots].max(axis=2) - b[plots].min(axis=2)) > 0.3))
if curves < 2500:
    fail.append("the plots hold no curves (%d coloured pixels)" % curves)
if changed_plots < 100:
    fail.append("plots did not change between the screenshots (%d pixels)" % changed_plots)
for n in neighbours:
    if not re.search(r"neighbour %s: (up|DOWN) since" % n, status):
        fail.append("status does not show neighbour %s: %r" % (n, status[:300]))
drawn = re.search(r"proxies drawn: (\d+) of (\d+) users", status)
if not drawn or int(drawn.group(1)) != proxies:
    fail.append("status does not count %d proxies drawn: %r" % (proxies, drawn.group(0) if drawn else status[:300]))
elif int(drawn.group(1)) < int(drawn.group(2)) and "not known to this station" not in status:
    fail.append("status draws %s of %s proxies without saying the others are not known to it: %r" % (drawn.group(1), drawn.group(2), status[:300]))
if not re.search(r"(^|\|)gate: (not acted|HELD BY THE GATE|EDGES DROPPED)", status, re.M):  # never a run the gate held shown as plain stable
    fail.append("status does not say what the gate did: %r" % status[:300])
if not re.search(r"(^|\|)host: (STARVING|keeps its)", status, re.M):  # a starving host is said, never left out
    fail.append("status does not say whether the host keeps its period: %r" % status[:300])
print("view check: canvas %.1f %% non-white, %d mesh pixels (%d canvas pixels) and %d plot pixels changed (%d coloured); status: %s" % (
    100 * nonwhite, changed_mesh, changed_canvas, changed_plots, curves, " | ".join(status.splitlines()[:6])))
if fail:
    print("FAILED: " + "; ".join(fail))
    sys.exit(1)
