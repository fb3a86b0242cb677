#!/usr/bin/python3
"""Reads the lab console page's DOM (chromium --dump-dom) and checks that every station 1..N has a
row showing its state: a row per station (data-station), its state among the allowed ones, and, while
running, its time, tick and N / N-bar for every neighbour. Prints what it found; exit 1 naming each
station whose row or state is missing.
  console_dom.py DOM.html USERS running|done [STATION-N.JSON-DIR]"""
import html.parser
import json
import os
import sys


class Rows(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.rows, self.cur, self.cell, self.token = {}, None, None, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "tr" and "data-station" in a:
            self.cur = {"state": a.get("data-state"), "class": a.get("class", ""), "cells": []}
            self.rows[int(a["data-station"])] = self.cur
        elif tag == "td" and self.cur is not None:
            self.cell = []
        elif tag == "input" and a.get("name") == "token":
            self.token = a.get("value")

    def handle_endtag(self, tag):
        if tag == "td" and self.cur is not None and self.cell is not None:
            self.cur["cells"].append("".join(self.cell).strip())
            self.cell = None
        elif tag == "tr":
            self.cur = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell.append(data)


def main():
    path, users, want = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    json_dir = sys.argv[4] if len(sys.argv) > 4 else None
    p = Rows()
    p.feed(open(path, errors="replace").read())
    bad = []
    for i in range(1, users + 1):
        r = p.rows.get(i)
        if r is None:
            bad.append("station %d: no row on the page" % i)
            continue
        c = r["cells"]  # station, host, state, t, tick, N/Nbar, overruns, missed, port, controller, gate, exit, verdict, view
        if len(c) < 14:
            bad.append("station %d: its row has %d cells, not 14" % (i, len(c)))
            continue
        if want == "running":
            if r["state"] not in ("running", "run over") or "bad" in r["class"].split():
                bad.append("station %d: state %r (%s), not running" % (i, r["state"], c[12]))
            elif not (c[3] and c[4] and c[5] and c[6]):
                bad.append("station %d: running but t %r, tick %r, N/Nbar %r, overruns %r not all shown" % (i, c[3], c[4], c[5], c[6]))
        else:
            j = json.load(open(os.path.join(json_dir, "station-%d.json" % i)))
            if r["state"] != "done" or c[11] != str(j.get("exit_code")):
                bad.append("station %d: state %r exit %r, station-%d.json says exit %s" % (i, r["state"], c[11], i, j.get("exit_code")))
    extra = sorted(k for k in p.rows if not 1 <= k <= users)
    if extra:
        bad.append("rows of stations that are not in the lab: %s" % extra)
    for b in bad:
        print("FAILED: " + b)
    if not bad:
        sample = p.rows[users]["cells"]
        print("ok: %d of %d station rows show their state (%s); station %d: t %s s, tick %s, N/Nbar %s, overruns %s, exit %s"
              % (len(p.rows), users, want, users, sample[3], sample[4], sample[5], sample[6], sample[11] or "-"))
    if p.token and len(sys.argv) > 5:
        open(sys.argv[5], "w").write(p.token)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
