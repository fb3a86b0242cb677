#!/usr/bin/env python3
"""The recording's view draws every user's proxy: `replay station-1.h5 --view-port` of a simulated run
finds the other users' logs next to it and sends their proxies with each frame, read here over the
view's WebSocket (no browser): the scene names stations 2, 3, 4, and every frame's proxy of station j
is station j's logged /ticks/vp at the frame's tick. A log of another run put next to it (another
simulation's station-2.h5) is not drawn, and the view says why. Exit 0 pass, 1 fail, 77 skipped
(no h5py). Usage: view_proxies_check.py BIN REPO OUT"""
import json
import os
import re
import shutil
import subprocess
import sys
import time

try:
    import h5py
except ImportError:
    print("SKIPPED: h5py is not installed (apt-get install python3-h5py)")
    sys.exit(77)

binary, repo, out = sys.argv[1], sys.argv[2], sys.argv[3]
sys.path.insert(0, os.path.join(repo, "tools", "view"))
import ws_rate  # noqa: E402  (the view's WebSocket client)

shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
fail = []


def sim(name, duration):
    d = os.path.join(out, name)
    subprocess.run([binary, "sim", "--scenario", "paper-best", "--out", d, "--duration", str(duration), "--push-end", "1", "--record",
                    "--no-plots", "--quiet"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=300)
    return d


def served(log, port):
    """The scene and up to 40 frames the view of `log` serves, and what replay said on stderr."""
    err = open(os.path.join(out, "replay-%d.log" % port), "w+")
    p = subprocess.Popen([binary, "replay", log, "--view-port", str(port), "--view-for", "120"], stdout=subprocess.DEVNULL, stderr=err)
    try:
        for _ in range(600):  # the replay runs first, then the view listens
            try:
                s = ws_rate.connect(port)
                break
            except OSError:
                time.sleep(0.1)
        else:
            raise SystemExit("FAILED: the view of %s never listened on port %d" % (log, port))
        scene, frames = None, []
        for m in ws_rate.messages(s):
            j = json.loads(m)
            if j.get("type") == "scene":
                scene = j
            elif j.get("type") == "frame":
                frames.append(j)
            if len(frames) >= 40:
                break
        s.close()
    finally:
        p.terminate()
        p.wait(timeout=60)
    err.seek(0)
    return scene, frames, err.read()


def logged_vp(path):
    with h5py.File(path, "r") as f:
        return {int(k): v for k, v in zip(f["ticks/k"][:], f["ticks/vp"][:])}


a = sim("a", 2)
b = sim("b", 1)  # another simulation (another command line)
port = 46800 + (os.getpid() % 40) * 2
scene, frames, err = served(os.path.join(a, "station-1.h5"), port)
if scene is None or scene.get("proxies_from", {}).get("stations") != [2, 3, 4]:
    fail.append("the scene does not name stations 2, 3, 4 as the proxies drawn from their logs: %r" % (scene or {}).get("proxies_from"))
vp = {j: logged_vp(os.path.join(a, "station-%d.h5" % j)) for j in (2, 3, 4)}
compared = 0
for f in frames:
    got = {p["station"]: p["vp"] for p in f.get("proxies", [])}
    if sorted(got) != [2, 3, 4]:
        fail.append("frame at tick %d carries the proxies of stations %s, not 2, 3, 4" % (f["k"], sorted(got)))
        break
    for j, v in got.items():
        want = [float(x) for x in vp[j][f["k"]]]
        if v != want:
            fail.append("frame at tick %d: station %d's proxy %s, its log says %s" % (f["k"], j, v, want))
        compared += 1
if "proxies from their logs: stations 2, 3, 4" not in err:
    fail.append("replay does not say whose proxies it draws: %r" % err[-300:])

mix = os.path.join(out, "mix")  # station 2's log from the other simulation
os.makedirs(mix)
for j in (1, 3, 4):
    shutil.copy(os.path.join(a, "station-%d.h5" % j), mix)
shutil.copy(os.path.join(b, "station-2.h5"), mix)
scene_m, frames_m, err_m = served(os.path.join(mix, "station-1.h5"), port + 1)
if scene_m is None or scene_m.get("proxies_from", {}).get("stations") != [3, 4]:
    fail.append("with another simulation's station-2.h5 next to it, the scene names %r, not [3, 4]" % (scene_m or {}).get("proxies_from"))
if any(p["station"] == 2 for f in frames_m for p in f.get("proxies", [])):
    fail.append("another simulation's station-2.h5 was drawn")
if not re.search(r"not drawing the proxy of \S*station-2\.h5: another simulation", err_m):
    fail.append("replay does not say why it leaves out the other simulation's station-2.h5: %r" % err_m[-400:])
print("view proxies check: %d frames, %d proxies compared with the logs; with another run's station-2.h5 next to it: %r" % (
    len(frames), compared, (scene_m or {}).get("proxies_from", {}).get("stations")))
if compared == 0:
    fail.append("no proxy compared")
if fail:
    print("FAILED: " + "; ".join(fail))
    sys.exit(1)
