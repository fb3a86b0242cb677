#!/usr/bin/python3
"""What a station's neighbours feel when it is killed and restarted (tools/run4/run4.sh --kill
I:KILL_S:RESTART_S): per neighbour, the largest change of its user's force |F(t') - F(t)| over any
--window-s (100 ms) with t <= t' <= t + window, from the station traces (station-J-trace.csv), in
  rejoin: from the restart until 0.1 s before the release (the restarted station's first packets
  and the copies pulled together again);
  kill:   from 0.1 s before the kill until the restart (the station gone: its edge dropped);
  whole:  from 0.1 s before the kill until 0.1 s before the release (both moments, and across the
          restart);
  hold:   the same run before the kill, while holding (what the scripted users cause themselves);
and, with --clean DIR (the same run4.sh options without --kill), the same statistic over the same
rejoin window in that clean run: the baseline the users' script causes without any kill.
With --max-N X: exit 1 when a neighbour's figure over --check's window (default whole) is above X N
(exit 0 otherwise).
Usage: rejoin_jolt.py KILL_OUT [--clean CLEAN_OUT] [--window-s 0.1] [--max-N X] [--check whole|rejoin|kill] [--json FILE]"""
import argparse, csv, json, math, os, sys


def forces(out, i):
    """(t_s, (Fx, Fy, Fz)) rows of station i's trace."""
    with open(os.path.join(out, f'station-{i}-trace.csv')) as f:
        return [(float(r['t_s']), (float(r['force_x_N']), float(r['force_y_N']), float(r['force_z_N']))) for r in csv.DictReader(f)]


def change_within(F, t0, t1, dt):
    """Largest |F(t') - F(t)| over t <= t' <= t + dt, both in [t0, t1], and the (t, t') where it is."""
    win = [(t, f) for t, f in F if t0 <= t <= t1]
    best, at, j = 0.0, None, 0
    for n, (t, f) in enumerate(win):
        j = max(j, n)
        while j + 1 < len(win) and win[j + 1][0] <= t + dt:
            j += 1
        for tg, g in win[n:j + 1]:
            d = math.dist(f, g)
            if d > best:
                best, at = d, (t, tg)
    return best, at


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('out')
    ap.add_argument('--clean', help='a run with the same options and no --kill: the baseline over the same window')
    ap.add_argument('--window-s', type=float, default=0.1)
    ap.add_argument('--max-N', type=float, help='exit 1 when a neighbour\'s largest change over the --check window is above this')
    ap.add_argument('--check', choices=('whole', 'rejoin', 'kill'), default='whole',
                    help='the window --max-N checks: whole (kill - 0.1 s to release - 0.1 s, the default), rejoin or kill')
    ap.add_argument('--json', help='write the figures here')
    a = ap.parse_args()
    restart = json.load(open(os.path.join(a.out, 'restart.json')))
    who, t_kill, t_re = restart['station'], restart['kill_run_s'], restart['restart_run_s']
    s1 = json.load(open(os.path.join(a.out, f'station-{1 if who != 1 else 2}.json')))
    push_end, release = s1['push_end_s'], s1['release_time_s']
    windows = {'rejoin': (t_re, release - 0.1), 'kill': (t_kill - 0.1, t_re), 'whole': (t_kill - 0.1, release - 0.1),
               'hold': (push_end + 0.5, t_kill - 0.1)}
    when = {'whole': f'between 0.1 s before station {who}\'s kill and the release', 'rejoin': f'after station {who}\'s restart',
            'kill': f'around station {who}\'s kill'}[a.check]
    figures, fails = {}, []
    print(f'station {who} killed at {t_kill} s, restarted at {t_re} s; largest force change within {a.window_s * 1e3:.0f} ms at its neighbours:')
    for i in range(1, 5):
        if i == who:
            continue
        F = forces(a.out, i)
        fig = {}
        for name, (t0, t1) in windows.items():
            fig[name], fig[name + '_at_s'] = change_within(F, t0, t1, a.window_s)
        if a.clean:
            fig['clean'], fig['clean_at_s'] = change_within(forces(a.clean, i), *windows['rejoin'], a.window_s)
        figures[i] = fig
        at, ak = fig['rejoin_at_s'], fig['kill_at_s']
        print(f'  station {i}: rejoin {fig["rejoin"]:.4f} N' + (f' (at {at[0]:.3f}-{at[1]:.3f} s)' if at else '') +
              f'; kill {fig["kill"]:.4f} N' + (f' (at {ak[0]:.3f}-{ak[1]:.3f} s)' if ak else '') +
              f'; whole {fig["whole"]:.4f} N; hold before the kill {fig["hold"]:.4f} N' +
              (f'; clean run, same window {fig["clean"]:.4f} N' if a.clean else ''))
        if a.max_N is not None and not fig[a.check] <= a.max_N:
            fails.append(f'station {i}\'s force changed {fig[a.check]:.4f} N within {a.window_s * 1e3:.0f} ms {when} (> {a.max_N} N)')
    if a.json:
        with open(a.json, 'w') as f:
            json.dump({'killed': who, 'kill_run_s': t_kill, 'restart_run_s': t_re, 'window_s': a.window_s, 'neighbours': figures}, f, indent=1)
    for f in fails:
        print('FAIL: ' + f, file=sys.stderr)
    return 1 if fails else 0


if __name__ == '__main__':
    sys.exit(main())
