#!/usr/bin/python3
"""Checks a four-station run in which one station was SIGKILLed and restarted (tools/run4/run4.sh
--kill I:KILL_S:RESTART_S): the restarted station rejoined within --max-rejoin-s of its start, its
copy started within --adopt-m of the neighbour copy it took over (state adoption before coupling),
the copies reached consensus again by the end, and no station's device force jumped (tick to tick)
by more than the hold force around the rejoin. Also prints, without checking it, the largest
change of each device force from its value at the restart until the release (the copies that
drifted apart while the station was away are pulled together again).
Prints the figures; exit 0 when all checks hold, 1 otherwise.
Usage: rejoin_check.py OUT_DIR [--max-rejoin-s 2.0] [--consensus-m 1e-3] [--adopt-m 1e-3]"""
import argparse, csv, json, math, os, sys

ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
ap.add_argument('out')
ap.add_argument('--max-rejoin-s', type=float, default=2.0)
ap.add_argument('--consensus-m', type=float, default=1e-3)
ap.add_argument('--adopt-m', type=float, default=1e-3)
a = ap.parse_args()

restart = json.load(open(os.path.join(a.out, 'restart.json')))
who = restart['station']
js = {i: json.load(open(os.path.join(a.out, f'station-{i}.json'))) for i in range(1, 5)}
T = js[1]['dt_s']
fails = []

# 1. rejoin latency: restart (process start) -> first coupled tick, on CLOCK_MONOTONIC
life = js[who].get('lifecycle', {})
rj = life.get('rejoin')
if rj is None:
    fails.append(f'station {who} did not rejoin (no lifecycle.rejoin in station-{who}.json)')
    latency = math.nan
else:
    # Tick k of the learned epoch (the restarted station's epoch_monotonic_s, which the rejoin set)
    # is at epoch + k T on CLOCK_MONOTONIC; its first run tick is coupled_at_tick. (Not from the
    # planned epoch: a restart with a fresh epoch, --restart-fresh-epoch, planned another one.)
    coupled_mono = js[who]['epoch_monotonic_s'] + rj['coupled_at_tick'] * T
    latency = coupled_mono - restart['restart_monotonic_s']
    other = 1 if who != 1 else 2
    epoch_err_ms = (js[who]['epoch_monotonic_s'] - js[other]['epoch_monotonic_s']) * 1e3
    print(f'rejoin: station {who} restarted at run time {restart["restart_run_s"]} s, coupled {latency:.3f} s later '
          f'(epoch from station {rj["epoch_from_station"]}: {rj["epoch_shift_ms"]:+.3f} ms from its planned one, '
          f'{epoch_err_ms:+.3f} ms from station {other}\'s, +- {rj["epoch_uncertainty_ms"]:.3f} ms; '
          f'state of station {rj["state_from_station"]} tick {rj["state_tick"]})')
    if not 0 <= latency <= a.max_rejoin_s:
        fails.append(f'rejoin took {latency:.3f} s, not within [0, {a.max_rejoin_s}] s')
    if not abs(epoch_err_ms) <= 20:
        fails.append(f'learned epoch {epoch_err_ms:+.3f} ms from the session\'s (more than 20 ms)')

def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))

# 2. consensus at the end: every copy within consensus_m of the mean of the copies, last common k
states = {}
for i in range(1, 5):
    rows = read_rows(os.path.join(a.out, f'station-{i}-state.csv'))
    states[i] = {int(r['k']): [float(v) for kk, v in r.items() if kk != 'k'] for r in rows}
common = set.intersection(*(set(s) for s in states.values()))
if not common:
    fails.append('no common state row of the four stations')
else:
    def spread_at(ids, k):
        xs = [states[i][k] for i in ids]
        out = 0.0
        for p in range(len(xs[0]) // 3):
            mean = [sum(x[3 * p + d] for x in xs) / len(xs) for d in range(3)]
            out = max(out, max(math.dist(mean, x[3 * p:3 * p + 3]) for x in xs))
        return out
    others = [i for i in range(1, 5) if i != who]
    before = [k for k in set.intersection(*(set(states[i]) for i in others)) if (k + 1) * T <= restart['restart_run_s']]
    if before:
        kb = max(before)
        print(f'before the restart (run time {(kb + 1) * T:.2f} s): the other three copies are {spread_at(others, kb) * 1e3:.4f} mm apart')
    # The rejoined copy's first state row against the copy it took over, same k.
    src = (rj or {}).get('state_from_station')
    if src in states:
        k1 = next((k for k in sorted(states[who]) if k in states[src]), None)
        if k1 is not None:
            a0, b0 = states[who][k1], states[src][k1]
            d = max(math.dist(a0[3 * p:3 * p + 3], b0[3 * p:3 * p + 3]) for p in range(len(a0) // 3))
            print(f'adoption: station {who}\'s first state row (run time {(k1 + 1) * T:.3f} s) is {d * 1e3:.4f} mm from station {src}\'s copy')
            if not d <= a.adopt_m:
                fails.append(f'the rejoined copy started {d * 1e3:.3f} mm from the copy it took over (> {a.adopt_m * 1e3} mm)')
    k_end = max(common)
    spread = spread_at(range(1, 5), k_end)
    print(f'consensus at run time {(k_end + 1) * T:.2f} s: largest node distance from the mean of the copies {spread * 1e3:.4f} mm')
    if not spread <= a.consensus_m:
        fails.append(f'copies {spread * 1e3:.3f} mm apart at the end (> {a.consensus_m * 1e3} mm)')

# 3. device force jumps around the rejoin vs the hold force (mean |F| while holding, the others)
push_end, release = js[1]['push_end_s'], js[1]['release_time_s']
t_re = restart['restart_run_s']
hold = []
jumps, base, drift = {}, {}, {}
for i in range(1, 5):
    rows = read_rows(os.path.join(a.out, f'station-{i}-trace.csv'))
    F = [(float(r['t_s']), (float(r['force_x_N']), float(r['force_y_N']), float(r['force_z_N']))) for r in rows]
    h = [math.hypot(*f) for t, f in F if push_end + 0.5 <= t <= release - 0.1]
    if h:
        hold.append(sum(h) / len(h))
    def largest_change(t0, t1):
        win = [(t, f) for t, f in F if t0 <= t <= t1]
        return max((math.dist(f1, f0) for (_, f0), (_, f1) in zip(win, win[1:])), default=0.0)
    jumps[i] = largest_change(t_re, t_re + a.max_rejoin_s + 1.0)
    at_restart = [f for t, f in F if t <= t_re]
    drift[i] = max((math.dist(f, at_restart[-1]) for t, f in F if t_re <= t <= release - 0.1), default=0.0) if at_restart else math.nan
    # Baseline: the same statistic over an undisturbed stretch of the hold (before the kill).
    base[i] = largest_change(push_end + 0.5, min(release, restart['kill_run_s']) - 0.1) if i != who else math.nan
hold_N = min(hold) if hold else math.nan
print('hold force (smallest station mean |F| while holding): %.3f N' % hold_N)
for i in range(1, 5):
    print(f'  station {i}: largest tick-to-tick force change in run time [{t_re}, {t_re + a.max_rejoin_s + 1.0}] s: {jumps[i]:.4f} N '
          f'(undisturbed hold before the kill: {base[i]:.4f} N); largest |F - F(restart)| until the release: {drift[i]:.4f} N')
    if not jumps[i] <= hold_N:
        fails.append(f'station {i} force jumped {jumps[i]:.3f} N > hold force {hold_N:.3f} N')

# 4. the neighbours logged the silence and the return
for i in range(1, 5):
    if i == who:
        continue
    ev = js[i].get('lifecycle', {}).get('neighbour_events', [])
    mine = [e for e in ev if e.startswith(f'neighbour {who} ')]
    if mine:
        print(f'station {i}: ' + ' | '.join(mine))

for f in fails:
    print('FAIL: ' + f, file=sys.stderr)
sys.exit(1 if fails else 0)
