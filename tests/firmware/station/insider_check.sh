#!/usr/bin/env bash
# An authenticated insider (rt/edge_monitor.hpp, "the neighbour state check"): four `haptic-station
# run` processes over UDP on loopback (tools/run4/run4.sh, paper-best star, 6 s run) whose hub,
# station 1, is haptic-insider (a TEST-ONLY build of the station, tests/firmware/station/insider_main.cpp)
# lying from run time 1 s: a constant +2 cm offset, a 1 cm oscillation at the object's lowest elastic
# mode in its shape, a 2 mm/s ramp. Then the same run with an honest hub. Checks:
#  - clean: no station isolates anyone (state_check isolations 0, no exit 13);
#  - each lie: every leaf isolates station 1 for its states being inconsistent with its own velocities,
#    names it in its log and station-<id>.json "isolation", exits 13 with "neighbour_isolated"; the
#    hub never isolates an honest leaf;
#  - offset: every leaf isolates the hub at its first lying packet (within 0.1 s: the one-way delay),
#    so the lie is never applied; that run is the reference of the others (isolation itself ends the
#    consensus the clean run keeps);
#  - bound: the lie's damage to each leaf's copy, the largest node distance between its displacement
#    from the lie's start and the offset run's (same tick), up to DAMAGE_WINDOW_S after the later of
#    the two isolations, is below BOUND_MM: the stated bound (rt/README.md "The neighbour state check":
#    d_K = 0.2 mm for the oscillation, 1.25 (rho t_d + c_l rho t_d^2 / 2) = 0.48 mm for the 2 mm/s ramp)
#    plus ALLOWANCE_MM = 0.5 mm for what two real-time runs differ in besides the lie: their timing
#    (~0.06 mm in the window, quiet host) and the hub's honest coupling, which the offset run lost at
#    1 s and the ramp run keeps until its isolation (~0.1 s later). The window keeps the first small: the
#    users push on through the hold, and two runs' copies (each leaf alone after the isolation, its
#    simulated hand on its own clock) drift apart by up to ~6 % of the push's ~10 mm by the release,
#    which a measure over the whole run would mix into the damage; the lie's
#    damage itself is done by the isolation and stays (the ramp's shows in full 0.1 s after it).
#    A run whose stations could not keep their period (station-<id>.json "host": starving; 4-15 % of
#    the periods skipped on a loaded 2-core host) moves the copies beyond the allowance by itself:
#    its bound is reported, not binding, and the test exits 77 (skipped in part) if nothing else failed.
# Bounded: run4.sh stops every station after its planned time + 20 s. No root.
# Usage: insider_check.sh BIN_DIR WORK_DIR   (BIN_DIR holds haptic-station, haptic-insider, haptic-lab's tools)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
bindir="$(cd "$1" && pwd)"; work="$2"
source "$here/insider_bin.sh"  # the wrapper that makes station 1 the insider
insider_skip_unless_built "$bindir"
source "$(dirname "$0")/../../support/quiet_host.sh"  # a measured "host too loaded" skip, and the host after a failure
quiet_host_or_skip "$bindir" "$work"
rm -rf "$work"
insider_bin "$bindir" "$work"  # station 1 runs as haptic-insider when INSIDER_LIE is set
run_case() {  # NAME LIE AMPLITUDE
  echo "--- $1"
  INSIDER_LIE="$2" INSIDER_AMPLITUDE="$3" "$repo/tools/run4/run4.sh" --transport udp --bin "$work/bin/haptic-station" --out "$work/$1" \
      --duration 6 --push-end 2 --release 4 --no-plots > "$work/$1.log" 2>&1 || true  # a lie's leaves exit 13: run4.sh exits 1
  tail -n 4 "$work/$1.log"
}
run_case clean "" 0
run_case offset offset 0.02
run_case mode mode 0.01
run_case ramp ramp 0.002
/usr/bin/python3 - "$work" <<'PY'
import csv, glob, json, sys
work = sys.argv[1]
ALLOWANCE_MM = 0.5
BOUND_MM = {"mode": 0.2 + ALLOWANCE_MM, "ramp": 0.48 + ALLOWANCE_MM}
LIE_FROM_S, T, DAMAGE_WINDOW_S = 1.0, 0.002, 0.25
fail, not_binding = [], []

def station(case, i):
    return json.load(open("%s/%s/station-%d.json" % (work, case, i)))

def states(case, i):
    """station i's copy by tick: {k: [x0, x1, ...]} (the state CSV's rows)"""
    return {int(r[0]): [float(v) for v in r[1:]] for r in list(csv.reader(open("%s/%s/station-%d-state.csv" % (work, case, i))))[1:]}

def starving(case):
    """the stations of CASE that could not keep their period (their own "host" verdict)"""
    return [i for i in range(1, 5) if (station(case, i).get("host") or {}).get("starving")]

def isolated_at(case, i):
    return station(case, i)["state_check"]["neighbours"][0].get("last_isolated_run_s")

def damage_mm(case, i):
    """max over ticks in [lie start, later isolation + DAMAGE_WINDOW_S] and nodes of the distance between
    station i's displacement from the lie's start in CASE and in the offset run, mm"""
    a, o = states(case, i), states("offset", i)
    t_a, t_o = isolated_at(case, i), isolated_at("offset", i)
    if t_a is None or t_o is None: return float("nan")
    k0 = min((k for k in a if k * T >= LIE_FROM_S and k in o), default=None)
    if k0 is None: return float("nan")
    worst = 0.0
    for k in sorted(a):
        if k < k0 or k * T > max(t_a, t_o) + DAMAGE_WINDOW_S or k not in o: continue
        for p in range(len(a[k]) // 3):
            worst = max(worst, sum(((a[k][3 * p + d] - a[k0][3 * p + d]) - (o[k][3 * p + d] - o[k0][3 * p + d])) ** 2 for d in range(3)) ** 0.5)
    return 1e3 * worst

for i in range(1, 5):
    s = station("clean", i)
    if s["exit_code"] == 13 or s["state_check"]["isolations"] != 0:
        fail.append("clean run: station %d isolated a neighbour: %s" % (i, s.get("isolation")))
    print("clean station %d: exit %s, peaks kinematic %s mm, disagreement %s mm" % (i, s["exit_code"],
          [round(1e3 * n["peak_kinematic_m"], 3) for n in s["state_check"]["neighbours"]],
          [None if n["peak_disagreement_m"] is None else round(1e3 * n["peak_disagreement_m"], 3) for n in s["state_check"]["neighbours"]]))
for case in ("offset", "mode", "ramp"):
    hub = station(case, 1)
    if hub["state_check"]["isolations"] != 0:
        fail.append("%s: the insider hub isolated an honest leaf: %s" % (case, hub.get("isolation")))
    for i in (2, 3, 4):
        s = station(case, i)
        n = s["state_check"]["neighbours"][0]
        log = open("%s/%s/station-%d.log" % (work, case, i)).read()
        dmg = damage_mm(case, i)
        t_iso = n.get("last_isolated_run_s")
        print("%s station %d: exit %s, isolated station %s %s time(s) at %s s (%s, %.3f mm at node %s), damage %.3f mm against the offset run" % (
              case, i, s["exit_code"], n["station"], n["isolations"], t_iso, n.get("reason"), 1e3 * n.get("trip_value_m", 0), n.get("trip_node"), dmg))
        if s["exit_code"] != 13 or "neighbour_isolated" not in s["conditions"]:
            fail.append("%s: station %d exit %s, conditions %s (want 13, neighbour_isolated)" % (case, i, s["exit_code"], s["conditions"]))
        if n["station"] != 1 or n["isolations"] < 1 or n.get("reason") != "inconsistent_with_its_velocities":
            fail.append("%s: station %d did not isolate station 1 as inconsistent: %s" % (case, i, n))
        if not any("station 1 isolated" in line for line in s["isolation"]) or "station 1 isolated" not in log:
            fail.append("%s: station %d's json/log do not name station 1 as isolated" % (case, i))
        if case == "offset" and not (t_iso is not None and t_iso - LIE_FROM_S < 0.1):
            fail.append("offset: station %d isolated the hub at %s s, not at its first lying packet" % (i, t_iso))
        if case in BOUND_MM and not dmg < BOUND_MM[case]:  # NaN (no isolation, no rows) fails too
            why = "%s: the lie moved station %d's copy %.3f mm from the offset run's (bound %.2f mm)" % (case, i, dmg, BOUND_MM[case])
            hungry = sorted(set(starving(case) + starving("offset")))
            if hungry and dmg == dmg:  # a starving run: its skipped periods move the copies beyond ALLOWANCE_MM
                not_binding.append("%s (stations %s of the two runs could not keep their period)" % (why, hungry))
            else:
                fail.append(why)
for m in fail: print("FAIL: " + m)
for m in not_binding: print("NOT BINDING: " + m)
if not fail and not not_binding: print("ok: the lying hub is isolated and named by every leaf, honest copies within the bound, the clean run isolates no one")
if fail: sys.exit(1)
if not_binding:
    print("SKIPPED (in part): the damage bound was not checked where a run's host starved; the isolations, names, exit codes "
          "and the clean run were, and passed")
    sys.exit(77)
sys.exit(0)
PY
