#!/usr/bin/python3
"""Makes the ~16k-node ball scene (ball16k.msh beside this file) for `haptic-station sim --scene`.

Gmsh meshes a 50 mm sphere (ball16k.geo: OpenCASCADE, element size 3.0 mm, 16,703 nodes), then the
nodes are renumbered by reverse Cuthill-McKee (scipy) so that A's band is small (the tick's
matrix passes keep the rows a band ahead in cache, rt/README.md), and the tetrahedra are written as
Gmsh ASCII 2.2 (the orientation of each tetrahedron kept: only the node ids change).

Usage: tools/bench/scenes/make_ball.py [GEO [OUT]]   (needs gmsh and python3-scipy)
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

here = os.path.dirname(os.path.abspath(__file__))
geo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "ball16k.geo")
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(here, "ball16k.msh")


def read_msh22(path):
    nodes, tets = {}, []
    with open(path) as f:
        lines = iter(f.read().split("\n"))
    for line in lines:
        if line == "$Nodes":
            for _ in range(int(next(lines))):
                t = next(lines).split()
                nodes[int(t[0])] = [float(v) for v in t[1:4]]
        elif line == "$Elements":
            for _ in range(int(next(lines))):
                t = next(lines).split()
                if t[1] == "4":  # 4-node tetrahedron
                    ntags = int(t[2])
                    tets.append([int(v) for v in t[3 + ntags:7 + ntags]])
    return nodes, tets


with tempfile.TemporaryDirectory() as tmp:
    raw = os.path.join(tmp, "raw.msh")
    subprocess.run(["gmsh", "-3", "-format", "msh22", geo, "-o", raw], check=True, stdout=subprocess.DEVNULL, timeout=600)
    nodes, tets = read_msh22(raw)

used = sorted({v for t in tets for v in t})  # nodes of the tetrahedra only
index = {old: i for i, old in enumerate(used)}
T = np.array([[index[v] for v in t] for t in tets])
n = len(used)
rows, cols = [], []
for a in range(4):
    for b in range(4):
        if a != b:
            rows.append(T[:, a])
            cols.append(T[:, b])
G = coo_matrix((np.ones(sum(len(r) for r in rows)), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
perm = reverse_cuthill_mckee(G, symmetric_mode=True)  # new position -> old index
new_of = np.empty(n, dtype=int)
new_of[perm] = np.arange(n)
T2 = new_of[T]
band = int(np.max(np.abs(T2[:, :, None] - T2[:, None, :])))
with open(out, "w") as f:
    f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % n)
    for i in range(n):
        x, y, z = nodes[used[perm[i]]]
        f.write("%d %.9g %.9g %.9g\n" % (i + 1, x, y, z))
    f.write("$EndNodes\n$Elements\n%d\n" % len(T2))
    for e, t in enumerate(T2):
        f.write("%d 4 2 1 1 %d %d %d %d\n" % (e + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1))
    f.write("$EndElements\n")
print("%s: %d nodes, %d tetrahedra, band %d after reverse Cuthill-McKee" % (out, n, len(T2), band))
