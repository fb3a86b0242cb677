#!/usr/bin/python3
"""Checks a four-station run in which one station was SIGKILLed and restarted (tools/run4/run4.sh
--kill I:KILL_S:RESTART_S): the restarted station rejoined within --max-rejoin-s of its start, its
copy started within --adopt-m of the neighbour copy it took over (state adoption before coupling),
the copies reached consensus again by the end (the consensus error of `haptic-station merge`, the
simulator's definition: the largest distance between two copies of a node), and no user's device force jumped by more than the
hold force: neither tick to tick nor within any 100 ms (a jolt a hand feels), from just before the
kill until the release, nor (the other stations) away from its value at the restart until the
release (the copies that drifted apart while the station was away are pulled together again). Also printed, not checked:
how far each force moved from its value at the kill while the station was away (the outage itself).
Prints the figures; exit 0 when all checks hold, 1 otherwise.
Usage: rejoin_check.py OUT_DIR [--station BIN] [--max-rejoin-s 2.0] [--consensus-m 1e-3] [--adopt-m 1e-3]"""
import argparse, csv, json, math, os, subprocess, sys

ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
ap.add_argument('out')
ap.add_argument('--station', default='haptic-station', help='the haptic-station binary (its merge computes the consensus error)')
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

# 2. consensus at the end: the merged run's consensus error (merge reads the station files from the
# first tick all four recorded, i.e. from the restart on), and the rejoined copy against the copy it took over.
merged = subprocess.run([a.station, 'merge', a.out], capture_output=True, text=True)
if merged.returncode != 0:
    fails.append(f'haptic-station merge failed ({merged.returncode}): {merged.stderr.strip()}')
else:
    summary = json.load(open(os.path.join(a.out, 'summary.json')))
    err = summary.get('consensus_error_m')
    print(f'consensus at the end of the merged run: consensus error {err * 1e3:.4f} mm' if err is not None else 'consensus: no copies sample')
    if err is None or not err <= a.consensus_m:
        fails.append(f'consensus error at the end {err} m (> {a.consensus_m} m)')

states = {}
for i in (who, (rj or {}).get('state_from_station')):
    if i in js:
        with open(os.path.join(a.out, f'station-{i}-state.csv')) as f:
            states[i] = {int(r['k']): [float(v) for kk, v in r.items() if kk != 'k'] for r in csv.DictReader(f)}
# The rejoined copy's first state row equals the copy it took over, same k, within adopt_m on every node.
src = (rj or {}).get('state_from_station')
if src in states and src != who:
    k1 = next((k for k in sorted(states[who]) if k in states[src]), None)
    if k1 is not None:
        a0, b0 = states[who][k1], states[src][k1]
        d = max(math.dist(a0[3 * p:3 * p + 3], b0[3 * p:3 * p + 3]) for p in range(len(a0) // 3))
        print(f'adoption: station {who}\'s first state row (run time {(k1 + 1) * T:.3f} s) is {d * 1e3:.4f} mm from station {src}\'s copy')
        if not d <= a.adopt_m:
            fails.append(f'the rejoined copy started {d * 1e3:.3f} mm from the copy it took over (> {a.adopt_m * 1e3} mm)')

def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))

# 3. device force jumps around the rejoin vs the hold force (mean |F| while holding, the others)
push_end, release = js[1]['push_end_s'], js[1]['release_time_s']
t_re = restart['restart_run_s']
hold = []
jumps, base, drift, jolts, outage = {}, {}, {}, {}, {}
for i in range(1, 5):
    rows = read_rows(os.path.join(a.out, f'station-{i}-trace.csv'))
    F = [(float(r['t_s']), (float(r['force_x_N']), float(r['force_y_N']), float(r['force_z_N']))) for r in rows]
    # the hold force: while holding, undisturbed (before the kill; the restarted station's new trace has no such rows)
    h = [math.hypot(*f) for t, f in F if push_end + 0.5 <= t <= min(release, restart['kill_run_s']) - 0.1]
    if h:
        hold.append(sum(h) / len(h))
    def largest_change(t0, t1):
        win = [(t, f) for t, f in F if t0 <= t <= t1]
        return max((math.dist(f1, f0) for (_, f0), (_, f1) in zip(win, win[1:])), default=0.0)
    t_kill = restart['kill_run_s']
    jumps[i] = largest_change(t_kill - 0.1, release - 0.1)
    def change_within(t0, t1, dt):  # largest |F(t') - F(t)| over t <= t' <= t + dt in [t0, t1]
        win = [(t, f) for t, f in F if t0 <= t <= t1]
        out, j = 0.0, 0
        for n, (t, f) in enumerate(win):
            j = max(j, n)
            while j + 1 < len(win) and win[j + 1][0] <= t + dt:
                j += 1
            out = max(out, max(math.dist(f, g) for _, g in win[n:j + 1]))
        return out
    jolts[i] = change_within(t_kill - 0.1, release - 0.1, 0.1)
    def drift_from(t0, t1):  # largest |F(t) - F(t0)| over [t0, t1]; from the first row at or after t0
        win = [f for t, f in F if t0 <= t <= t1]
        return max((math.dist(f, win[0]) for f in win), default=0.0)
    # from the restart (the restarted station: its first run tick) until the release
    drift[i] = drift_from(t_re, release - 0.1)
    outage[i] = drift_from(t_kill, t_re) if i != who else math.nan
    # Baseline: the same statistic over an undisturbed stretch of the hold (before the kill).
    base[i] = largest_change(push_end + 0.5, min(release, restart['kill_run_s']) - 0.1) if i != who else math.nan
hold_N = min(hold) if hold else math.nan
print('hold force (smallest station mean |F| while holding, before the kill): %.3f N' % hold_N)
for i in range(1, 5):
    print(f'  station {i}: largest force change from the kill to the release: tick to tick {jumps[i]:.4f} N '
          f'(undisturbed hold before the kill: {base[i]:.4f} N), within 100 ms {jolts[i]:.4f} N; '
          f'largest |F - F(restart)| until the release {drift[i]:.4f} N; '
          f'(not checked) largest |F - F(kill)| while station {who} was away {outage[i]:.4f} N')
    # (the restarted station's own force starts at 0 and returns to its hold force: not a change
    # away from its value at the restart; its ramp-in, device.ramp_in_s, bounds its 100 ms change)
    checked = [('tick to tick', jumps[i]), ('within 100 ms', jolts[i])] + ([('from its value at the restart', drift[i])] if i != who else [])
    for what, v in checked:
        if not v <= hold_N:
            fails.append(f'station {i} force changed {v:.3f} N {what} > hold force {hold_N:.3f} N')

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
