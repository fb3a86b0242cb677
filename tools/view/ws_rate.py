#!/usr/bin/env python3
"""What a station's live view streams, measured by a client that is not the bottleneck: a minimal
WebSocket client (RFC 6455, standard library only) on the "haptic-view" protocol reads the scene
message and then every frame for S seconds, and prints JSON: frames per second received, ticks
between frames, how many frames changed the object's shape (x_um) against the previous one, the
largest node displacement seen, and the station's and server's own drop counters. A browser shows
at most this rate; a software-rendered page on a loaded machine takes fewer (the server then skips
frames for it and counts them). Usage: ws_rate.py PORT [SECONDS] [HOST]"""
import base64
import json
import os
import socket
import sys
import time


def recv_exact(s, n):
    b = b""
    while len(b) < n:
        c = s.recv(n - len(b))
        if not c:
            raise EOFError("connection closed")
        b += c
    return b


def messages(s):
    buf = b""
    while True:
        h = recv_exact(s, 2)
        fin, op, n = h[0] & 0x80, h[0] & 0x0F, h[1] & 0x7F
        if n == 126:
            n = int.from_bytes(recv_exact(s, 2), "big")
        elif n == 127:
            n = int.from_bytes(recv_exact(s, 8), "big")
        payload = recv_exact(s, n)  # server frames are not masked
        if op == 8:
            return
        if op in (0, 1):
            buf += payload
            if fin:
                yield buf.decode("utf-8")
                buf = b""


def connect(port, host="127.0.0.1"):
    """A WebSocket on the "haptic-view" protocol to the view at host:port (then messages(s) reads it)."""
    s = socket.create_connection((host, port), timeout=10)
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall(("GET / HTTP/1.1\r\nHost: %s:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: %s\r\n"
               "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: haptic-view\r\n\r\n" % (host, port, key)).encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += recv_exact(s, 1)
    if b" 101 " not in head.split(b"\r\n")[0]:
        raise SystemExit("no WebSocket upgrade: %r" % head[:200])
    return s


def main():
    port = int(sys.argv[1])
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 10
    host = sys.argv[3] if len(sys.argv) > 3 else "127.0.0.1"
    s = connect(port, host)
    frames, t_first, prev_x, prev_k, changed, ks, maxdisp, last = 0, None, None, None, 0, [], 0.0, None
    rest = None
    end = time.time() + seconds + 60  # the scene may come only when the station is ready
    for m in messages(s):
        j = json.loads(m)
        now = time.time()
        if j.get("type") == "scene":
            rest = j["rest_um"]
            end = now + seconds + 30
            continue
        if j.get("type") != "frame":
            continue
        if t_first is None:
            t_first, end = now, now + seconds
        frames += 1
        x = j["x_um"]
        if prev_x is not None and x != prev_x:
            changed += 1
        if prev_k is not None:
            ks.append(j["k"] - prev_k)
        if rest:
            maxdisp = max(maxdisp, max(abs(a - b) for a, b in zip(x, rest)))
        prev_x, prev_k, last = x, j["k"], j
        if now >= end:
            break
    s.close()
    span = (time.time() - t_first) if t_first else 0
    ks.sort()
    print(json.dumps({"port": port, "seconds": round(span, 2), "frames": frames, "frames_per_s": round(frames / span, 2) if span else 0,
                      "ticks_between_frames_median": ks[len(ks) // 2] if ks else None, "frames_with_a_changed_shape": changed,
                      "max_node_displacement_um": maxdisp, "station_mailbox_replaced": (last or {}).get("frames_dropped"),
                      "server_not_sent": (last or {}).get("server_dropped")}))
    return 0 if frames > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
