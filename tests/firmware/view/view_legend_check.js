// The live view's legend and default deformation scale (tools/view/view.js legendText,
// defaultExaggeration), in node (no browser): the paper's ball (radius 50 mm) is drawn x5 by default
// and the legend says so and how to see the true scale; a larger object gets a larger factor, a
// tiny one 1; every neighbour is named with its wireframe's colour, every other user whose proxy a
// recording draws with its diamond's colour and where they come from, the users whose proxies the
// page cannot draw (a live station: its non-neighbours) said as not known to it; an asked factor is
// said as asked.
// Usage: node view_legend_check.js tools/view/view.js
const fs = require("fs");
const src = fs.readFileSync(process.argv[2], "utf8");
const grab = (re, what) => { const m = src.match(re); if (!m) { console.log("FAILED: no " + what + " in " + process.argv[2]); process.exit(1); } return m[0]; };
const code = [grab(/const COLOR_NAMES = \[[^\]]*\];/, "COLOR_NAMES"), grab(/function defaultExaggeration\(restMm\) \{[\s\S]*?\n\}\n/, "defaultExaggeration"),
              grab(/function stationColor\(neighbours, others, p\) \{[\s\S]*?\n\}\n/, "stationColor"),
              grab(/function unknownProxies\(station, users, from\) \{[\s\S]*?\n\}\n/, "unknownProxies"),
              grab(/function legendText\(neighbours, exaggerate, asked, from, unknown\) \{[\s\S]*?\n\}\n/, "legendText")].join("\n");
const {defaultExaggeration, legendText, unknownProxies} = new Function(code + "; return {defaultExaggeration, legendText, unknownProxies};")();
const ball = r => {  // an octahedron of radius r mm about (10, -20, 30)
  const p = [];
  for (const [x, y, z] of [[r, 0, 0], [-r, 0, 0], [0, r, 0], [0, -r, 0], [0, 0, r], [0, 0, -r]]) p.push(10 + x, -20 + y, 30 + z);
  return p;
};
const fail = [];
for (const [r, want] of [[50, 5], [50.4, 5], [49, 5], [51, 10], [150, 20], [8, 1], [0, 1]]) {
  const got = defaultExaggeration(ball(r));
  if (got !== want) fail.push("radius " + r + " mm: x" + got + ", want x" + want);
}
const logs = stations => ({stations: stations, source: "their logs", missing: "no log of the same run next to station-1.h5"});
const lg = legendText([2, 3, 4], 5, false, logs([2, 3, 4]), []);
for (const want of ["station 2 red", "station 3 blue", "station 4 green", "deformation drawn x5", "?exaggerate=1 for true scale",
                    "proxies: diamonds in their colour, seen through the object (station 2 red, station 3 blue, station 4 green, from their logs)"])
  if (!lg.includes(want)) fail.push("legend lacks " + JSON.stringify(want) + ": " + JSON.stringify(lg));
if (lg.includes("not known")) fail.push("every proxy drawn, yet: " + JSON.stringify(lg));
// a ring: station 1's neighbours are 2 and 4; station 3's proxy (from its log) gets the next colour
const ring = legendText([2, 4], 5, false, logs([2, 3, 4]), []);
if (!ring.includes("(station 2 red, station 3 green, station 4 blue, from their logs)")) fail.push("ring: " + JSON.stringify(ring));
// a line 1-2-3-4 seen from station 1: stations 3 and 4 are no neighbours, each gets a colour of its own
const line = legendText([2], 5, false, logs([2, 3, 4]), []);
if (!line.includes("(station 2 red, station 3 blue, station 4 green, from their logs)")) fail.push("line: " + JSON.stringify(line));
// a live station in a ring of 4: its neighbours' proxies come with their state packets, station 3's is not known to it
const live = {stations: [2, 4], source: "their state packets", missing: "not its neighbours"};
const unknown = unknownProxies(1, 4, live);
if (JSON.stringify(unknown) !== "[3]") fail.push("live ring: unknown " + JSON.stringify(unknown) + ", want [3]");
const ringLive = legendText([2, 4], 5, false, live, unknown);
if (!ringLive.includes("(station 2 red, station 4 blue, from their state packets); station 3: not known to this station (not its neighbours)"))
  fail.push("live ring: " + JSON.stringify(ringLive));
const asked = legendText([1], 20, true, logs([]), []);
if (!asked.includes("x20 (?exaggerate)") || asked.includes("default")) fail.push("asked x20: " + JSON.stringify(asked));
console.log(fail.length ? "FAILED: " + fail.join("; ") : "view legend check: " + lg);
process.exit(fail.length ? 1 : 0);
