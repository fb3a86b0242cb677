// Live view client: one WebSocket ("haptic-view") to the station; a scene message, then frames.
"use strict";
const COLORS = ["#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"];
const COLOR_NAMES = ["red", "blue", "green", "purple", "orange", "brown"];  // COLORS in words, for the legend
const WINDOW_S = 20;
let scene = null, mesh = null, copies = [], proxies = {}, vpMark = null, devMark = null, coupling = null, contactPts = null;
let seekTo = null;  // a seek this page asked for: frames sent before the server applied it are stale and not shown
let statusSent = 0, renderer, camera, world, geom, charts = {}, linkState = {}, framesSeen = 0, lastSeq = 0, missed = 0;
let arrivals = [], opened = performance.now();  // arrival times (ms) of the frames of the last 2 s: the frame rate this page receives
let lastPlotsDrawn = 0, lastStatusDrawn = 0;
// ?exaggerate=E draws every copy's deformation (its displacement from rest) E times (display only;
// default: defaultExaggeration of the scene, said in the legend)
const ASKED_EXAGGERATION = Number(new URLSearchParams(location.search).get("exaggerate"));
let EXAGGERATE = 1;
let restMm = null;

// The deformation's default scale: the smallest of 1, 2, 5 x 10^k that draws a 1 mm displacement as
// at least a tenth of the object's radius (within 1 %; the paper's ball, radius 50 mm: x5, so its ~1.4 mm dent
// shows as ~7 mm); at least 1. restMm: the rest positions (mm), x y z per node.
function defaultExaggeration(restMm) {
  const n = restMm.length / 3, c = [0, 0, 0];
  for (let i = 0; i < 3 * n; ++i) c[i % 3] += restMm[i] / n;
  let radius = 0;
  for (let i = 0; i < n; ++i)
    radius = Math.max(radius, Math.hypot(restMm[3 * i] - c[0], restMm[3 * i + 1] - c[1], restMm[3 * i + 2] - c[2]));
  const want = 0.1 * radius / 1.0;
  if (!(want > 1)) return 1;
  const e = Math.pow(10, Math.floor(Math.log10(want)));
  return [1, 2, 5, 10].map(f => f * e).find(v => v >= 0.99 * want);  // 1 %: a radius rounded to the micrometre stays x5
}

// The colour of station p's wireframe and proxy: a neighbour's by its place among the neighbours,
// another user's after them.
function stationColor(neighbours, others, p) {
  const j = neighbours.indexOf(p);
  return j >= 0 ? j : neighbours.length + others.filter(o => !neighbours.includes(o)).indexOf(p);
}

// The users whose proxies the page cannot draw: every station of the run but this one and those in
// from.stations (scene.proxies_from: the stations whose proxies come, from.source where from).
function unknownProxies(station, users, from) {
  const u = [];
  for (let p = 1; p <= users; ++p) if (p !== station && !from.stations.includes(p)) u.push(p);
  return u;
}

// The legend under the 3D view: what each colour is, each neighbour's by its station, whose proxies
// are drawn and from what (from: scene.proxies_from; unknown: unknownProxies), and the scale the
// deformation is drawn at.
function legendText(neighbours, exaggerate, asked, from, unknown) {
  const name = p => "station " + p + " " + COLOR_NAMES[stationColor(neighbours, from.stations, p) % COLOR_NAMES.length];
  const nb = neighbours.map(name).join(", ");
  let px = "other users' proxies: " + (from.stations.length ? "diamonds in their colour, seen through the object (" +
    from.stations.map(name).join(", ") + ", from " + from.source + ")" : "none drawn");
  if (unknown.length) px += "; station" + (unknown.length > 1 ? "s " : " ") + unknown.join(", ") + ": not known to this station (" + from.missing + ")";
  return "grey: this copy · wireframes: the neighbours' last received copies (" + (nb || "none") + ")" +
    " · red dots: contact mesh · blue sphere: this station's proxy · green: device · " + px + " · deformation drawn x" + exaggerate +
    (asked ? " (?exaggerate)" : " (default; ?exaggerate=1 for true scale)");
}

// The status line of the proxies drawn: counted from the 3D scene (markers visible), out of the run's users.
function proxyLine(drawn, users, from, unknown) {
  return "proxies drawn: " + drawn + " of " + users + " users (this station's" +
    (from.stations.length ? "; stations " + from.stations.join(", ") + " from " + from.source : "") +
    (unknown.length ? "; " + unknown.join(", ") + ": not known to this station, " + from.missing : "") + ")";
}
const shown = (um, i) => restMm[i] + EXAGGERATE * (um * 1e-3 - restMm[i]);  // mm
let cursorT = null;  // a recording: the plots hold the whole run, a vertical line marks the frame shown

// Draws the timeline's cursor (a recording's current time) on every plot.
const cursorPlugin = {id: "cursor", afterDatasetsDraw(c) {
  if (cursorT === null) return;
  const x = c.scales.x.getPixelForValue(cursorT), a = c.chartArea;
  if (x < a.left || x > a.right) return;
  c.ctx.save(); c.ctx.strokeStyle = "#000"; c.ctx.lineWidth = 1.5;
  c.ctx.beginPath(); c.ctx.moveTo(x, a.top); c.ctx.lineTo(x, a.bottom); c.ctx.stroke(); c.ctx.restore();
}};

function setup3d(s) {
  const canvas = document.getElementById("view3d");
  renderer = new THREE.WebGLRenderer({canvas: canvas, antialias: true});
  renderer.setClearColor(0xffffff);
  world = new THREE.Scene();
  world.add(new THREE.AmbientLight(0x909090));
  const light = new THREE.DirectionalLight(0xffffff, 0.7); light.position.set(1, 2, 3); world.add(light);
  const n = s.nodes, rest = new Float32Array(3 * n);
  let c = [0, 0, 0];
  for (let i = 0; i < 3 * n; ++i) { rest[i] = s.rest_um[i] * 1e-3; c[i % 3] += rest[i] / n; }  // mm
  restMm = rest;
  const asked = ASKED_EXAGGERATION > 0;
  EXAGGERATE = asked ? Math.max(1, ASKED_EXAGGERATION) : defaultExaggeration(rest);
  if (!s.proxies_from) s.proxies_from = {stations: [], source: "", missing: "this server sends no other proxies"};
  const from = s.proxies_from, others = from.stations;  // whose proxies come with the frames (a recording: from their logs; live: the neighbours')
  document.getElementById("legend").textContent = legendText(s.neighbours, EXAGGERATE, asked, from, unknownProxies(s.station, s.users, from));
  geom = new THREE.BufferGeometry();
  geom.setAttribute("position", new THREE.BufferAttribute(rest.slice(), 3));
  geom.setIndex(s.triangles);
  geom.computeVertexNormals();
  mesh = new THREE.Mesh(geom, new THREE.MeshPhongMaterial({color: 0xb0b0b0, side: THREE.DoubleSide, flatShading: true}));
  world.add(mesh);
  // the edges share the mesh's geometry, so they deform with it (a WireframeGeometry would copy the rest shape)
  world.add(new THREE.Mesh(geom, new THREE.MeshBasicMaterial({color: 0x555555, wireframe: true})));
  s.neighbours.forEach((p, j) => {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(rest.slice(), 3));
    g.setIndex(s.triangles);
    const w = new THREE.Mesh(g, new THREE.MeshBasicMaterial({color: COLORS[j % COLORS.length], wireframe: true, transparent: true, opacity: 0.5}));
    w.visible = false; world.add(w); copies.push(w);
  });
  const cp = new Float32Array(3 * s.contact.length);
  const cg = new THREE.BufferGeometry(); cg.setAttribute("position", new THREE.BufferAttribute(cp, 3));
  contactPts = new THREE.Points(cg, new THREE.PointsMaterial({color: 0xff0000, size: 6, sizeAttenuation: false}));
  world.add(contactPts);
  vpMark = new THREE.Mesh(new THREE.SphereGeometry(2.5, 16, 12), new THREE.MeshPhongMaterial({color: 0x1f4fff}));
  devMark = new THREE.Mesh(new THREE.BoxGeometry(4, 4, 4), new THREE.MeshPhongMaterial({color: 0x20a020}));
  vpMark.userData.proxyOf = s.station;
  others.forEach(p => {
    const m = new THREE.Mesh(new THREE.OctahedronGeometry(3),
      new THREE.MeshBasicMaterial({color: COLORS[stationColor(s.neighbours, others, p) % COLORS.length], depthTest: false}));
    m.renderOrder = 1;  // drawn through the object: a user pushing from the far side is seen too
    m.userData.proxyOf = p; m.visible = false; world.add(m); proxies[p] = m;
  });
  world.add(vpMark); world.add(devMark);
  const lg = new THREE.BufferGeometry(); lg.setAttribute("position", new THREE.BufferAttribute(new Float32Array(6), 3));
  coupling = new THREE.Line(lg, new THREE.LineBasicMaterial({color: 0x20a020})); world.add(coupling);
  camera = new THREE.PerspectiveCamera(40, 560 / 440, 1, 5000);
  camera.position.set(c[0] + 110, c[1] + 140, c[2] + 200); camera.lookAt(c[0], c[1], c[2]);
  world.add(new THREE.AxesHelper(30));
}

function chart(id, title, names, ylabel) {
  const ds = names.map((n, i) => ({label: n, data: [], borderColor: COLORS[i % COLORS.length], borderWidth: 1.2, pointRadius: 0}));
  return new Chart(document.getElementById(id), {type: "line", data: {datasets: ds}, plugins: [cursorPlugin],
    options: {animation: false, responsive: true, maintainAspectRatio: false, parsing: false,
      plugins: {title: {display: true, text: title}, legend: {labels: {boxWidth: 10, font: {size: 10}}}},
      scales: {x: {type: "linear", title: {display: true, text: "t (s)"}}, y: {title: {display: true, text: ylabel}}}}});
}

function setupCharts(s) {
  charts.force = chart("p_force", "device force u_i", ["x", "y", "z"], "N");
  charts.energy = chart("p_energy", "energies (13) port, (14) controller, VO", ["port (13)", "controller (14)", "VO"], "J");
  charts.cons = chart("p_cons", "distance to the last received copies (not the run's consensus error)", ["max |x - x_hat_j|"], "mm");
  const ln = [];
  s.neighbours.forEach(p => { ln.push("N_" + s.station + p); ln.push("Nbar_" + s.station + p); });
  charts.links = chart("p_links", "index delay N_ij vs bound Nbar_ij", ln, "ticks");
  charts.delay = chart("p_delay", "per-link one-way delay / loss", s.neighbours.flatMap(p => ["delay " + p + " (ms)", "loss " + p + " (%)"]), "ms / %");
  charts.tick = chart("p_tick", "tick time and wake-up latency (max per frame)", ["tick time", "wake-up latency"], "µs");
}

function push(c, i, t, y) {
  const d = c.data.datasets[i].data;
  d.push({x: t, y: y});
  while (d.length && d[0].x < t - WINDOW_S) d.shift();
}

// A recording's tick times (scene.history rows: the largest per frame, us), as its status line says them.
function tickTimeLine(history) {
  const us = history.map(r => r[8]).filter(Number.isFinite).sort((a, b) => a - b);
  if (!us.length) return "tick time (recorded): none";
  return "tick time (recorded): largest " + us[us.length - 1].toFixed(1) + " µs, median of the frames' largest " + us[us.length >> 1].toFixed(1) + " µs";
}

// A recording's plots: every kept frame's values at once (scene.history rows, firmware/view/timeline.cpp).
function fillHistory(s) {
  s.history.forEach(r => {
    const t = r[0];
    for (let a = 0; a < 3; ++a) charts.force.data.datasets[a].data.push({x: t, y: r[1 + a]});
    for (let e = 0; e < 3; ++e) charts.energy.data.datasets[e].data.push({x: t, y: r[4 + e]});
    charts.cons.data.datasets[0].data.push({x: t, y: r[7]});
    charts.tick.data.datasets[0].data.push({x: t, y: r[8]}); charts.tick.data.datasets[1].data.push({x: t, y: r[9]});
    const L = s.neighbours.length;  // then (index delay, bound) per link, then (delay ms, loss %) per link
    for (let j = 0; j < L; ++j) {
      charts.links.data.datasets[2 * j].data.push({x: t, y: r[10 + 2 * j]}); charts.links.data.datasets[2 * j + 1].data.push({x: t, y: r[11 + 2 * j]});
      if (r.length >= 10 + 4 * L) {
        charts.delay.data.datasets[2 * j].data.push({x: t, y: r[10 + 2 * L + 2 * j]}); charts.delay.data.datasets[2 * j + 1].data.push({x: t, y: r[11 + 2 * L + 2 * j]});
      }
    }
  });
  const t0 = s.history[0][0], t1 = s.history[s.history.length - 1][0];
  Object.values(charts).forEach(c => { c.options.scales.x.min = Math.floor(t0); c.options.scales.x.max = t1; });
  charts.delay.options.plugins.title.text = "per-link delay (age of each packet used, ms) / loss (cumulative %)";
}

function onScene(s) {
  scene = s;
  setup3d(s); setupCharts(s);
  if (s.history && s.history.length) fillHistory(s);
  document.getElementById("status").textContent = "station " + s.station + " (" + s.mode + "): connected; waiting for the first frame" +
    (s.mode === "station" ? " (the station publishes frames while its run goes on)" : "");
  if (s.mode === "replay" || s.mode === "sim") {
    document.getElementById("timeline").style.display = "block";
    const seek = document.getElementById("seek");
    seek.max = s.timeline_frames - 1;
    const seekFrame = n => { if (!Number.isFinite(n)) return; seekTo = Math.max(0, Math.min(n, s.timeline_frames - 1)); ws.send(JSON.stringify({seek: seekTo})); };
    seek.oninput = () => seekFrame(Number(seek.value));
    const play = document.getElementById("play");
    const q = new URLSearchParams(location.search);  // ?seek=N&pause=1: open the timeline at frame N (paused)
    // the timeline is the server's, shared by its browsers: a page opened without ?pause plays it
    if (q.has("pause")) { ws.send(JSON.stringify({play: false})); play.textContent = "play"; } else ws.send(JSON.stringify({play: true}));
    if (q.has("seek")) seekFrame(Number(q.get("seek")));
    play.onclick = () => { const p = play.textContent === "play"; ws.send(JSON.stringify({play: p})); play.textContent = p ? "pause" : "play"; };
  }
}

let pending = null;
function onFrame(f) {
  if (!scene) return;
  if (seekTo !== null) {  // the server sends frames[index] first after a seek: wait for it
    if (f.index !== seekTo) return;
    seekTo = null;
  }
  addPoints(f);
  if (!pending) requestAnimationFrame(() => { draw(pending); pending = null; });
  pending = f;
}

// Every frame's values go into the plots (cheap); drawing happens once per animation frame.
function addPoints(f) {
  const now = performance.now();
  arrivals.push(now);
  while (arrivals.length && arrivals[0] < now - 2000) arrivals.shift();
  if (scene.history) { cursorT = f.t; framesSeen++; lastSeq = f.seq; return; }  // a recording: the curves are all there
  if (lastSeq && f.seq > lastSeq + 1 && scene.mode === "station") missed += f.seq - lastSeq - 1;
  if (f.seq < lastSeq) Object.values(charts).forEach(c => c.data.datasets.forEach(d => d.data = []));  // timeline jumped back
  lastSeq = f.seq; framesSeen++;
  const t = f.t;
  for (let a = 0; a < 3; ++a) push(charts.force, a, t, f.force[a]);
  push(charts.energy, 0, t, f.port_J); push(charts.energy, 1, t, f.controller_J); push(charts.energy, 2, t, f.vo_J);
  push(charts.cons, 0, t, f.received_copy_distance_m * 1e3);
  f.links.forEach((l, j) => {
    push(charts.links, 2 * j, t, l.index_delay); push(charts.links, 2 * j + 1, t, l.bound);
    if (l.delay_ms !== undefined) { push(charts.delay, 2 * j, t, l.delay_ms); push(charts.delay, 2 * j + 1, t, 100 * l.loss); }
  });
  push(charts.tick, 0, t, f.exec_max_us); push(charts.tick, 1, t, f.wake_max_us);
}

function draw(f) {
  const pos = geom.attributes.position;
  for (let i = 0; i < f.x_um.length; ++i) pos.array[i] = shown(f.x_um[i], i);
  pos.needsUpdate = true; geom.computeVertexNormals();
  copies.forEach((w, j) => {
    if (j >= f.copies_um.length) { w.visible = false; return; }
    const a = w.geometry.attributes.position;
    for (let i = 0; i < f.copies_um[j].length; ++i) a.array[i] = shown(f.copies_um[j][i], i);
    a.needsUpdate = true; w.visible = true;
  });
  const ca = contactPts.geometry.attributes.position;
  scene.contact.forEach((p, i) => { for (let d = 0; d < 3; ++d) ca.array[3 * i + d] = shown(f.x_um[3 * p + d], 3 * p + d); });
  ca.needsUpdate = true;
  vpMark.position.set(f.vp[0] * 1e3, f.vp[1] * 1e3, f.vp[2] * 1e3);
  Object.values(proxies).forEach(m => { m.visible = false; });
  (f.proxies || []).forEach(o => {  // the other users' proxies a recording holds at this frame
    const m = proxies[o.station];
    if (m) { m.position.set(o.vp[0] * 1e3, o.vp[1] * 1e3, o.vp[2] * 1e3); m.visible = true; }
  });
  devMark.position.set(f.device[0] * 1e3, f.device[1] * 1e3, f.device[2] * 1e3);
  const la = coupling.geometry.attributes.position;
  la.array.set([f.vp[0] * 1e3, f.vp[1] * 1e3, f.vp[2] * 1e3, f.device[0] * 1e3, f.device[1] * 1e3, f.device[2] * 1e3]); la.needsUpdate = true;
  renderer.render(world, camera);
  // the 3D view follows every frame; the six plots and the status text are redrawn at most 10
  // and 4 times a second (redrawing them per frame kept a software-rendered page below 20 frames/s)
  const now = performance.now();
  if (now - lastPlotsDrawn >= 100) { lastPlotsDrawn = now; Object.values(charts).forEach(c => c.update("none")); }
  if (now - lastStatusDrawn >= 250) { lastStatusDrawn = now; status(f); }
}

// What the per-edge energy gate and the edge-drop rule did so far: a run the gate held never reads
// as plain "stable" here either.
function gateLine(g) {
  if (!g) return "gate: (not reported)";
  const J = x => x.toPrecision(3) + " J";
  if (g.trips === 0 && g.edge_drops === 0) return "gate: not acted (worst port energy " + J(g.port_min_J) + ")";
  return "gate: " + (g.held ? "HELD BY THE GATE — " : "EDGES DROPPED — ") + g.trips + " energy-gate trips, " + J(g.removed_J) +
    " removed, " + g.edge_drops + " edge drops; worst port energy " + J(g.port_min_J);
}

// This host since the previous frame (the station's one starving-host rule: 1 % of the periods
// skipped, or a wake-up a period late).
function hostLine(h) {
  if (!h) return "host: (not reported)";
  const ms = x => x.toFixed(2) + " ms";
  if (h.starving) return "host: STARVING — woke up to " + ms(h.wake_max_ms) + " late, " + h.skipped_periods + " periods skipped (period " + ms(h.period_ms) + ")";
  return "host: keeps its " + ms(h.period_ms) + " period (latest wake-up " + ms(h.wake_max_ms) + ")";
}

function status(f) {
  const lines = [];
  lines.push("station " + scene.station + " (" + scene.mode + ") · t = " + f.t.toFixed(2) + " s · tick " + f.k);
  let pas = "B_i = " + scene.damping_Ns_per_m.toFixed(2) + " N s/m";
  if (scene.damping_min_Ns_per_m !== undefined)
    pas += " vs eq. (18) minimum " + scene.damping_min_Ns_per_m.toFixed(2) + (scene.passivity_condition_met ? " — passivity condition met" : " — NOT MET");
  lines.push("passivity: " + pas);
  lines.push("safe state: " + (f.safe_state ? "YES (zero force)" : "no") + " · contact: " + (f.contact ? "yes" : "no"));
  lines.push(gateLine(f.gate));
  const drawn = world.children.filter(o => o.userData.proxyOf !== undefined && o.visible).length;
  lines.push(proxyLine(drawn, scene.users, scene.proxies_from, unknownProxies(scene.station, scene.users, scene.proxies_from)));
  const nb = f.links.map(l => {
    const up = l.up !== undefined ? l.up : l.within;
    // since when: the server's (links[].since_s, over every frame since the run began), else this page's own
    const st = linkState[l.peer] || {up: up, since: f.t};
    if (st.up !== up) { st.up = up; st.since = f.t; }
    if (l.since_s !== undefined) st.since = l.since_s;
    linkState[l.peer] = st;
    const over = l.index_delay > l.bound;  // its newest data is older than the guard: not used this tick
    return "neighbour " + l.peer + ": " + (up ? "up" : "DOWN") + " since " + st.since.toFixed(2) + " s (N = " + l.index_delay +
      (over ? " > Nbar = " + l.bound + ": OVER THE BOUND, its data is not used)" : ", Nbar = " + l.bound + ")");
  });
  lines.push("neighbours:\n  " + nb.join("\n  "));
  lines.push(hostLine(f.host));
  if (scene.history) lines.push(tickTimeLine(scene.history));
  const rate = arrivals.length / Math.min(2, Math.max(0.001, (performance.now() - opened) / 1000));  // frames per second
  lines.push("frames: " + framesSeen + " received (" + rate.toFixed(1) + "/s over the last 2 s), " + missed + " missed here" + (f.frames_dropped !== undefined ? ", " + f.frames_dropped + " replaced in the station's mailbox" : "") +
    (f.server_dropped !== undefined ? ", " + f.server_dropped + " not sent (browser busy)" : ""));
  if (scene.mode !== "station") document.getElementById("tl").textContent = "frame " + f.index + " / " + scene.timeline_frames;
  if (f.index !== undefined) document.getElementById("seek").value = f.index;
  document.getElementById("status").textContent = lines.join("\n");
  if (++statusSent % 10 === 1) ws.send(JSON.stringify({status: document.getElementById("status").textContent}));  // what this page shows, for the server's log
}

const ws = new WebSocket("ws://" + location.host + "/", "haptic-view");
ws.onmessage = ev => { const m = JSON.parse(ev.data); if (m.type === "scene") onScene(m); else if (m.type === "frame") onFrame(m); };
ws.onopen = () => { opened = performance.now(); };
ws.onclose = () => { document.getElementById("status").textContent += "\n(connection closed)"; };
