#!/usr/bin/python3
"""Screenshot of a page once it has drawn what a test needs, not after a fixed time.

`chromium --screenshot --timeout=MS` takes its picture when the page's load event fires; MS is only
an upper bound. A page that draws from a WebSocket after its load (the live view) was then taken
blank on a loaded host, however long the timeout. This drives headless Chromium over the DevTools
protocol on a pipe (--remote-debugging-pipe: fd 3 in, fd 4 out, NUL-terminated JSON): it opens the
page, evaluates --ready (a JavaScript expression) until it is true and at least --min-ms have passed,
waits two animation frames so the drawing reached the screen, and writes the PNG.

Exit 0: written. Exit 1: the page was not ready in --max-ms (the screenshot is written anyway, for
the test's message) or Chromium failed; the reason is printed.
"""
import argparse
import base64
import json
import os
import select
import subprocess
import sys
import time


class Browser:
    def __init__(self, chrome, profile, width, height, log):
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()

        def fds():  # the child's fd 3 reads commands, fd 4 writes replies
            r, w = os.dup(to_chrome_r), os.dup(from_chrome_w)
            os.dup2(r, 3)
            os.dup2(w, 4)

        self.proc = subprocess.Popen(
            [chrome, "--headless=new", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
             "--use-angle=swiftshader", "--hide-scrollbars", "--no-first-run", "--disable-extensions",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--remote-debugging-pipe", "--user-data-dir=" + profile, "--window-size=%d,%d" % (width, height),
             "about:blank"],
            stdin=subprocess.DEVNULL, stdout=log, stderr=log, preexec_fn=fds, pass_fds=(3, 4))
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.next_id = 0
        self.buf = b""

    def call(self, method, params=None, session=None, deadline=None):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.to_chrome, json.dumps(msg).encode() + b"\0")
        while True:  # replies and events interleave: skip to this call's reply
            while b"\0" not in self.buf:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                if not select.select([self.from_chrome], [], [], left)[0]:
                    raise TimeoutError("no reply to %s from chromium" % method)
                chunk = os.read(self.from_chrome, 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed its DevTools pipe (it exited with %s)" % self.proc.poll())
                self.buf += chunk
            raw, self.buf = self.buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError("%s: %s" % (method, reply["error"].get("message")))
                return reply.get("result", {})

    def close(self):
        try:
            self.call("Browser.close", deadline=time.monotonic() + 5)
        except (OSError, RuntimeError, TimeoutError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--chrome", required=True, help="the chromium binary")
    p.add_argument("--url", required=True)
    p.add_argument("--out", required=True, help="the PNG to write")
    p.add_argument("--profile", required=True, help="a fresh --user-data-dir")
    p.add_argument("--ready", default="true", help="JavaScript expression: true once the page drew what is needed")
    p.add_argument("--min-ms", type=int, default=0, help="page life before the screenshot, at least")
    p.add_argument("--max-ms", type=int, default=90000, help="give up waiting for --ready after this")
    p.add_argument("--width", type=int, default=1400)
    p.add_argument("--height", type=int, default=900)
    p.add_argument("--log", help="chromium's own output goes here (default: discarded)")
    a = p.parse_args()
    log = open(a.log, "w") if a.log else subprocess.DEVNULL
    t0 = time.monotonic()
    b = Browser(a.chrome, a.profile, a.width, a.height, log)
    try:
        start = time.monotonic() + 60  # chromium's own start-up on a loaded host
        target = b.call("Target.createTarget", {"url": "about:blank"}, deadline=start)["targetId"]
        s = b.call("Target.attachToTarget", {"targetId": target, "flatten": True}, deadline=start)["sessionId"]
        b.call("Emulation.setDeviceMetricsOverride",
               {"width": a.width, "height": a.height, "deviceScaleFactor": 1, "mobile": False}, s, start)
        opened = time.monotonic()
        b.call("Page.navigate", {"url": a.url}, s, opened + 30)
        deadline = opened + a.max_ms / 1000
        ready = False
        while time.monotonic() < deadline:
            r = b.call("Runtime.evaluate", {"expression": "Boolean(%s)" % a.ready, "returnByValue": True}, s, deadline + 5)
            ready = r.get("result", {}).get("value") is True
            if ready and time.monotonic() - opened >= a.min_ms / 1000:
                break
            time.sleep(0.2)
        b.call("Runtime.evaluate", {"expression": "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(1))))",
                                    "awaitPromise": True}, s, time.monotonic() + 30)
        png = b.call("Page.captureScreenshot", {"format": "png"}, s, time.monotonic() + 60)["data"]
        with open(a.out, "wb") as f:
            f.write(base64.b64decode(png))
        waited = time.monotonic() - opened
        if not ready:
            print("chrome_shot: %s not ready after %.1f s (--ready %s); wrote %s anyway" % (a.url, waited, a.ready, a.out))
            return 1
        print("chrome_shot: %s ready; screenshot after %.1f s of page life (%.1f s with chromium's start-up) -> %s" %
              (a.url, waited, time.monotonic() - t0, a.out))
        return 0
    except (OSError, RuntimeError, TimeoutError, KeyError) as e:
        print("chrome_shot: %s: %s (load %s)" % (a.url, e, " ".join(open("/proc/loadavg").read().split()[:3])))
        return 1
    finally:
        b.close()


if __name__ == "__main__":
    sys.exit(main())
