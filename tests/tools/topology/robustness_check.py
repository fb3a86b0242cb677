#!/usr/bin/python3
"""haptic-topology --robustness: every ranked graph is r-robust (checked here from the definition,
independently of firmware/model/graph.cpp), the unconstrained best is reported and is no worse in
eq. (27)'s measure, and an impossible constraint (3-robust on the paper's 4 users) fails naming it.
Usage: robustness_check.py <haptic-topology> <work dir>"""
import itertools
import json
import subprocess
import sys


def robustness(n, edges):
    nb = [set() for _ in range(n)]
    for a, b in edges:
        nb[a - 1].add(b - 1)
        nb[b - 1].add(a - 1)
    best = n
    for side in itertools.product((0, 1, 2), repeat=n):
        if 1 not in side or 2 not in side:
            continue
        reach = {1: 0, 2: 0}
        for u in range(n):
            if side[u]:
                reach[side[u]] = max(reach[side[u]], sum(1 for v in nb[u] if side[v] != side[u]))
        best = min(best, max(reach.values()))
    return best


def main():
    tool, work = sys.argv[1], sys.argv[2]
    out = f"{work}/robust6.json"
    # a listed set on 5 synthetic users: K_5, K_5 without 1-2 (both 3-robust), a star, a cycle, a wheel
    k5 = [f"{a}-{b}" for a in range(1, 6) for b in range(a + 1, 6)]
    listed = ";".join([",".join(k5), ",".join(k5[1:]), "1-2,1-3,1-4,1-5", "1-2,2-3,3-4,4-5,5-1",
                       "1-2,2-3,3-4,4-5,5-1,1-3,1-4"])
    subprocess.run([tool, "--users", "5", "--seed", "1", "--graphs", listed, "--robustness", "3", "--json", out],
                   check=True, stdout=subprocess.DEVNULL)
    with open(out) as f:
        j = json.load(f)
    assert j["robustness_required"] == 3, j.get("robustness_required")
    rows = j["ranked"]
    assert rows, "no ranked rows"
    for r in rows:
        got = robustness(5, r["edges"])
        assert got >= 3, f"ranked graph {r['edges']} is only {got}-robust"
        assert r["robustness"] == got, (r["robustness"], got)
    unc = j["unconstrained_best"]
    assert unc["lambda_next_abs"] <= rows[0]["lambda_next_abs"] + 1e-12
    assert j["unconstrained_count"] == 5 and len(rows) == 2, (j["unconstrained_count"], len(rows))
    p = subprocess.run([tool, "--paper", "--links", "6", "--robustness", "3"], capture_output=True, text=True)
    assert p.returncode == 2, p.returncode
    assert "--robustness 3: none of the 1 feasible graphs is 3-robust" in p.stderr, p.stderr
    print(f"ok: {len(rows)} of {j['unconstrained_count']} graphs 3-robust; best {rows[0]['lambda_next_abs']:.9f}"
          f" against {unc['lambda_next_abs']:.9f} without the constraint")


if __name__ == "__main__":
    main()
