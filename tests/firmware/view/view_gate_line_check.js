// The live view's status line for the gate (tools/view/view.js gateLine): a run the per-edge energy
// gate held reads "HELD BY THE GATE" with its trips, the energy it removed and the worst port
// energy; edge drops alone read "EDGES DROPPED"; neither reads "not acted". Runs the page's own
// function in node (no browser). Usage: node view_gate_line_check.js tools/view/view.js
const fs = require("fs");
const src = fs.readFileSync(process.argv[2], "utf8");
const m = src.match(/function gateLine\(g\) \{[\s\S]*?\n\}\n/);
if (!m) { console.log("FAILED: no gateLine in " + process.argv[2]); process.exit(1); }
const gateLine = new Function(m[0] + "; return gateLine;")();
const fail = [];
const held = gateLine({trips: 263, removed_J: 20.75, edge_drops: 0, port_min_J: -0.01437, held: true});
for (const want of ["HELD BY THE GATE", "263 energy-gate trips", "20.8 J removed", "worst port energy -0.0144 J"])
  if (!held.includes(want)) fail.push("held: " + JSON.stringify(want) + " missing in " + JSON.stringify(held));
const drops = gateLine({trips: 0, removed_J: 0, edge_drops: 7, port_min_J: -0.001, held: false});
if (!drops.includes("EDGES DROPPED") || !drops.includes("7 edge drops")) fail.push("drops: " + JSON.stringify(drops));
const quiet = gateLine({trips: 0, removed_J: 0, edge_drops: 0, port_min_J: 0, held: false});
if (!quiet.startsWith("gate: not acted")) fail.push("neither acted: " + JSON.stringify(quiet));
console.log(fail.length ? "FAILED: " + fail.join("; ") : "view gate line check: " + held);
process.exit(fail.length ? 1 : 0);
