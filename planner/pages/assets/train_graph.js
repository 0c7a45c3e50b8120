"use strict";
const D = JSON.parse(document.getElementById("graph-data").textContent);
const NS = "http://www.w3.org/2000/svg";
const svg = document.getElementById("graph");
const tip = document.getElementById("tip");
const wrap = document.getElementById("wrap");
const M = {l: 150, r: 58, t: 14, b: 30};
// the plot fills the window below the bars (never under 320 px): set on every layout, so a resize follows
let H = 640;
function fitHeight() { return Math.max(320, Math.floor(innerHeight - (wrap.getBoundingClientRect().top + window.scrollY) - 14)); }
const st = {t0: D.view[0], t1: D.view[1], sel: null, con: null, hover: null, hoverCon: null,
  show: {down: true, up: true, conflicts: true, predicted: true}};
function el(name, attrs, parent) {
  const e = document.createElementNS(NS, name);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  if (parent) parent.appendChild(e);
  return e;
}
// data strings (train ids, causes) put into HTML: as text
function esc(s) { return String(s).replace(/[&<>"']/g, c => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;"})[c]); }
function undelta(a, s) { const o = new Float64Array(a.length); let v = 0; for (let i = 0; i < a.length; i++) { v += a[i]; o[i] = v / s; } return o; }
function hhmm(t, sec) {
  if (t === null || !isFinite(t)) return "–";
  t = Math.round(t); const h = Math.floor(t / 3600), m = Math.floor(t / 60) % 60, s = t % 60;
  const p = n => String(n).padStart(2, "0");
  return p(h) + ":" + p(m) + (sec ? ":" + p(s) : "");
}
for (const tr of D.trains) {
  tr.T = undelta(tr.t, 10); tr.X = undelta(tr.x, 1);
  tr.t0 = tr.T[0]; tr.t1 = tr.T[tr.T.length - 1];
}
const byId = new Map(D.trains.map(t => [t.id, t]));
// a typed or linked id matches exactly, else case-insensitively when only one train has it that way
const byFold = new Map();
for (const t of D.trains) { const k = t.id.toLowerCase(); byFold.set(k, byFold.has(k) ? null : t); }
function findTrain(text) {
  const s = String(text || "").trim();
  return byId.get(s) || byFold.get(s.toLowerCase()) || null;
}
const W = () => svg.clientWidth || 1200;
const PW = () => W() - M.l - M.r;
let PH = H - M.t - M.b;
const y0 = D.line.start_m, y1 = D.line.end_m;
// layers: axes, stairway, trains (one viewBox-scaled group), conflicts, highlight, ticks
// the day's temporary restrictions: hatched time-location blocks (drawn in pixels, so the hatching keeps its size)
const defs = el("defs", {}, svg);
const hatch = el("pattern", {id: "tsr-hatch", patternUnits: "userSpaceOnUse", width: 8, height: 8,
  patternTransform: "rotate(45)"}, defs);
el("rect", {width: 8, height: 8, fill: "#ef6c00", "fill-opacity": 0.10}, hatch);
el("line", {x1: 0, y1: 0, x2: 0, y2: 8, stroke: "#ef6c00", "stroke-width": 2.5, "stroke-opacity": 0.55}, hatch);
const gGrid = el("g", {id: "grid"}, svg);
const gTsr = el("g", {id: "restrictions"}, svg);
const inner = el("svg", {id: "plot", x: M.l, y: M.t, preserveAspectRatio: "none", overflow: "hidden"}, svg);
const gStair = el("g", {id: "stair"}, inner);
const gTrains = el("g", {id: "trains", fill: "none"}, inner);
const gPred = el("g", {id: "predicted", fill: "none"}, inner);
const gLoops = el("g", {id: "loops"}, inner);
const gCon = el("g", {id: "conflicts"}, inner);
const gHi = el("g", {id: "highlight", fill: "none"}, inner);
const gAxis = el("g", {id: "axis"}, svg);
const paths = [];
for (const tr of D.trains) {
  let d = "M" + tr.T[0].toFixed(1) + " " + tr.X[0].toFixed(0);
  for (let i = 1; i < tr.T.length; i++) d += "L" + tr.T[i].toFixed(1) + " " + tr.X[i].toFixed(0);
  const rapid = tr.svc === "rapid";
  const p = el("path", {d: d, stroke: D.colours[tr.dir + " " + tr.svc], "stroke-width": rapid ? 1.6 : 1.0,
    "vector-effect": "non-scaling-stroke", "data-train": tr.id, class: "train " + tr.dir + " " + tr.svc}, gTrains);
  tr.path = p; paths.push(p);
}
const pos = new Map(D.stations.map(s => [s[0], s[2]]));
for (const tr of D.trains) for (const c of tr.calls) if (tr.loops.includes(c[0]) && c[1] !== null && c[2] !== null) {
  const r = el("rect", {x: c[1], y: pos.get(c[0]) - 60, width: Math.max(c[2] - c[1], 1), height: 120,
    fill: "none", stroke: "#333", "stroke-width": 1, "vector-effect": "non-scaling-stroke", class: "loop " + tr.dir}, gLoops);
  r.dataset.train = tr.id;
}
// the predicted day (D.predicted, only when a train is late): each late train's events as predicted, every delay
// carried forward; a dashed run in the train's colour where it is late, a dot at each late event
const PR = D.predicted || null;
function delayText(o) { const d = Math.max(o, 0) / 10; return (d >= 10 ? d.toFixed(0) : d.toFixed(1)) + " s"; }
function eventText(tr, p, i) {
  const s = D.stations[p.st[i]], c = p.C.get(i);
  return tr.id + " " + (p.e[i] === "a" ? "arrival" : "departure") + " at " + s[1] + " (" + s[0] + "): scheduled " +
    hhmm(p.S[i], true) + " → predicted " + hhmm(p.T[i], true) + ", " + delayText(p.o[i]) + " late" + (c ? " · " + c : "");
}
function crossing(T, X, s, x, from, leave) {
  // the trajectory's first point past chainage x in direction s (leave: beyond x; else at or beyond it), from index
  // `from`, and the time the front is at x (between that point and the one before)
  for (let k = Math.max(from, 1); k < T.length; k++) {
    if (leave ? s * X[k] <= s * x + 0.5 : s * X[k] < s * x - 0.5) continue;
    const a = X[k - 1], b = X[k];
    const t = Math.abs(b - x) <= 0.5 && !leave ? T[k] : Math.abs(a - x) <= 0.5 || b === a ? T[k - 1] :
      T[k - 1] + (x - a) / (b - a) * (T[k] - T[k - 1]);
    return {k: k, t: t};
  }
  return null;
}
function predSegment(tr, p, i) {
  // from event i to i + 1: a dwell is flat; a run follows the shape of the train's drawn run between the two
  // stations, its times stretched onto the predicted ones (a straight line where the drawn run does not reach);
  // the search starts where the train's segment before it ended (p.k: the events run in order along the line)
  const ta = p.T[i], tb = p.T[i + 1], xa = p.X[i], xb = p.X[i + 1];
  let pts = [[ta, xa], [tb, xb]];
  if (xa !== xb) {
    const sg = xb > xa ? 1 : -1, a = crossing(tr.T, tr.X, sg, xa, p.k, true);
    const b = a && crossing(tr.T, tr.X, sg, xb, a.k, false);
    if (b) p.k = b.k;
    if (a && b && b.t > a.t) {
      pts = [[ta, xa]];
      for (let k = a.k; k < b.k; k++) pts.push([ta + (tr.T[k] - a.t) / (b.t - a.t) * (tb - ta), tr.X[k]]);
      pts.push([tb, xb]);
    }
  }
  return "M" + pts.map(q => q[0].toFixed(1) + " " + q[1].toFixed(0)).join("L");
}
if (PR) for (const p of PR.trains) {
  const tr = byId.get(p.id);
  if (!tr) continue;
  p.T = undelta(p.t, 10); p.S = p.T.map((t, i) => t - p.o[i] / 10); p.X = p.st.map(i => PR.stops[tr.dir][i]);
  p.C = new Map(p.c.map(([i, k]) => [i, PR.causes[k]])); p.L = new Set(p.late);
  p.worst = p.late.reduce((w, i) => p.o[i] > p.o[w] ? i : w, p.late[0]);
  tr.pred = p; p.els = []; p.k = 1;
  const colour = D.colours[tr.dir + " " + tr.svc], width = tr.svc === "rapid" ? 1.8 : 1.4;
  for (let i = 0; i + 1 < p.T.length; i++) {
    if (!p.L.has(i) && !p.L.has(i + 1)) continue;
    const seg = el("path", {d: predSegment(tr, p, i), stroke: colour, "stroke-width": width, "stroke-dasharray": "5 3",
      "vector-effect": "non-scaling-stroke", class: "pred " + tr.dir}, gPred);
    seg.dataset.train = tr.id; p.els.push(seg);
    el("title", {}, seg).textContent = eventText(tr, p, i + 1);
  }
  for (const i of p.late) {  // a dot: a path of no length with round ends, its size in pixels
    const dot = el("path", {d: "M" + p.T[i].toFixed(1) + " " + p.X[i].toFixed(0) + "h0", stroke: colour, "stroke-width": 5,
      "stroke-linecap": "round", "vector-effect": "non-scaling-stroke", class: "pred-dot " + tr.dir}, gPred);
    dot.dataset.train = tr.id; p.els.push(dot);
    el("title", {}, dot).textContent = eventText(tr, p, i);
  }
}
// conflicts: one box per (conflict, resource), at least D.conflict.min_px on each side (sized in layout)
const conRects = [];
for (const c of D.conflicts) {
  const r = el("rect", {fill: D.conflict.colour, "fill-opacity": 0.85, stroke: "#000", "stroke-width": 1.5,
    "vector-effect": "non-scaling-stroke", class: "conflict"}, gCon);
  r.dataset.a = c[1]; r.dataset.b = c[2]; r.dataset.cid = c[0]; r.con = c; conRects.push(r);
}
const byCon = new Map();
for (const c of D.conflicts) { if (!byCon.has(c[0])) byCon.set(c[0], []); byCon.get(c[0]).push(c); }
function box(r, t0, t1, x0, x1) {
  // a data-space box grown about its centre to the minimum size in pixels
  const kt = (st.t1 - st.t0) / PW(), kx = (y1 - y0) / PH, mt = D.conflict.min_px * kt, mx = D.conflict.min_px * kx;
  const w = Math.max(t1 - t0, mt), h = Math.max(x1 - x0, mx);
  r.setAttribute("x", (t0 + t1) / 2 - w / 2); r.setAttribute("width", w);
  r.setAttribute("y", (x0 + x1) / 2 - h / 2); r.setAttribute("height", h);
}
function sizeConflicts() {
  for (const r of conRects) box(r, r.con[5], r.con[6], r.con[3], r.con[4]);
  for (const r of gStair.querySelectorAll("rect.overlap")) box(r, +r.dataset.t0, +r.dataset.t1, +r.dataset.x0, +r.dataset.x1);
}
function sx(t) { return M.l + (t - st.t0) / (st.t1 - st.t0) * PW(); }
function sy(x) { return M.t + (x - y0) / (y1 - y0) * PH; }
function layout() {
  H = fitHeight(); PH = H - M.t - M.b; svg.setAttribute("height", H);
  const w = W();
  svg.setAttribute("viewBox", "0 0 " + w + " " + H);
  inner.setAttribute("width", PW()); inner.setAttribute("height", PH);
  inner.setAttribute("viewBox", st.t0 + " " + y0 + " " + (st.t1 - st.t0) + " " + (y1 - y0));
  gGrid.textContent = ""; gAxis.textContent = ""; gTsr.textContent = "";
  for (const s of D.stations) {
    el("line", {x1: M.l, x2: w - M.r, y1: sy(s[2]), y2: sy(s[2]), stroke: "#d5d9de"}, gGrid);
    const t = el("text", {x: M.l - 6, y: sy(s[2]) + 4, "text-anchor": "end", "font-size": 12}, gAxis);
    t.textContent = s[1] + " (" + s[0] + ")";
  }
  kmAxis(w);
  tsrBlocks();
  trainLabels();
  const span = st.t1 - st.t0;
  svg.classList.toggle("wide", span > 3 * 3600);  // the late events' dots only where they stand apart
  const step = span > 6 * 3600 ? 3600 : span > 2 * 3600 ? 1800 : span > 3600 ? 600 : span > 1200 ? 300 : 60;
  for (let t = Math.ceil(st.t0 / step) * step; t <= st.t1; t += step) {
    const hour = t % 3600 === 0;
    el("line", {x1: sx(t), x2: sx(t), y1: M.t, y2: H - M.b, stroke: hour ? "#b9bec4" : "#eceef1"}, gGrid);
    const lab = el("text", {x: sx(t), y: H - M.b + 16, "text-anchor": "middle", "font-size": 11, class: "tick"}, gAxis);
    lab.textContent = hhmm(t);
  }
  el("rect", {x: M.l, y: M.t, width: PW(), height: PH, fill: "none", stroke: "#8a9199"}, gAxis);
  document.getElementById("range").textContent = hhmm(st.t0) + " – " + hhmm(st.t1);
  sizeConflicts();
  for (const b of document.querySelectorAll("#hours button")) b.classList.toggle("on", +b.dataset.t0 === st.t0 && +b.dataset.t1 === st.t1);
}
function kmAxis(w) {
  // chainage in km on the right, at a round step giving about eight ticks
  const span = (y1 - y0) / 1000, steps = [0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200];
  const step = steps.find(k => span / k <= 10) || 500;
  const first = Math.ceil(y0 / 1000 / step) * step;
  for (let k = first; k <= y1 / 1000 + 1e-9; k += step) {
    const y = sy(k * 1000);
    el("line", {x1: w - M.r, x2: w - M.r + 4, y1: y, y2: y, stroke: "#8a9199"}, gAxis);
    const lab = el("text", {x: w - M.r + 7, y: y + 4, "font-size": 11, class: "tick"}, gAxis);
    lab.textContent = (+k.toFixed(1)).toString() + (k === first ? " km" : "");
  }
}
function clip(v, lo, hi) { return Math.min(Math.max(v, lo), hi); }
function tsrBlocks() {
  for (const r of D.restrictions || []) {
    if (r[4] <= st.t0 || r[3] >= st.t1) continue;
    const xa = clip(sx(r[3]), M.l, M.l + PW()), xb = clip(sx(r[4]), M.l, M.l + PW());
    const ya = sy(r[1]), yb = sy(r[2]), h = Math.max(yb - ya, 3);
    const b = el("rect", {x: xa, y: ya, width: Math.max(xb - xa, 1), height: h, fill: "url(#tsr-hatch)",
      stroke: "#ef6c00", "stroke-width": 1, class: "tsr"}, gTsr);
    const dir = r[6] === "both" ? "" : " " + r[6];
    el("title", {}, b).textContent = r[0] + ": " + r[5] + " km/h" + dir + ", km " + (r[1] / 1000).toFixed(3) + "–" +
      (r[2] / 1000).toFixed(3) + ", " + hhmm(r[3]) + "–" + hhmm(r[4]);
    const lab = el("text", {x: xa + 3, y: ya - 3, "font-size": 11, fill: "#b34700", class: "tsr-label"}, gTsr);
    lab.textContent = r[0] + " " + r[5] + " km/h" + dir;
  }
}
function trainLabels() {
  // train numbers on their lines where the view is narrow enough to read them (three hours or less)
  if (st.t1 - st.t0 > 3 * 3600) return;
  for (const tr of D.trains) {
    if (!st.show[tr.dir] || tr.t1 <= st.t0 || tr.t0 >= st.t1) continue;
    if (tr.t0 < st.t0 && st.t1 - st.t0 > 3600) continue;  // at its departure; at the left edge only within an hour
    const t = Math.max(tr.t0, st.t0), x = xAt(tr, t);
    if (x === null || !isFinite(x)) continue;
    const lab = el("text", {x: sx(t) + 3, y: sy(x) + (tr.dir === "down" ? 12 : -3), "font-size": 11,
      fill: D.colours[tr.dir + " " + tr.svc], class: "train-label"}, gAxis);
    lab.textContent = tr.id;
  }
}
function visible() {
  for (const tr of D.trains) tr.path.style.display = st.show[tr.dir] ? "" : "none";
  for (const r of gLoops.children) r.style.display = st.show[byId.get(r.dataset.train).dir] ? "" : "none";
  gCon.style.display = st.show.conflicts ? "" : "none";
  for (const p of gPred.children) p.style.display = st.show[byId.get(p.dataset.train).dir] ? "" : "none";
  gPred.style.display = st.show.predicted ? "" : "none";
  if (st.sel) highlight(st.sel, "sel");
}
function setView(t0, t1) {
  const full = D.day[1] - D.day[0];
  const span = Math.min(Math.max(t1 - t0, 300), full);
  t0 = Math.min(Math.max(t0, D.day[0]), D.day[1] - span);
  st.t0 = t0; st.t1 = t0 + span; layout();
}
function xAt(tr, t) {
  const T = tr.T; let lo = 0, hi = T.length - 1;
  if (t < T[0] || t > T[hi]) return null;
  while (hi - lo > 1) { const m = (lo + hi) >> 1; if (T[m] <= t) lo = m; else hi = m; }
  const f = T[hi] > T[lo] ? (t - T[lo]) / (T[hi] - T[lo]) : 0;
  return tr.X[lo] + f * (tr.X[hi] - tr.X[lo]);
}
function nearest(px, py) {
  // pixel distance from the pointer to each drawn train's polyline near the pointer's time
  const kt = PW() / (st.t1 - st.t0), kx = PH / (y1 - y0);
  const t = st.t0 + (px - M.l) / kt, tol = 8;
  let best = null, bd = tol;
  for (const tr of D.trains) {
    if (!st.show[tr.dir] || tr.t1 < t - tol / kt - 600 || tr.t0 > t + tol / kt + 600) continue;
    const T = tr.T, X = tr.X;
    let lo = 0, hi = T.length - 1;
    const ta = t - tol / kt - 1;
    while (hi - lo > 1) { const m = (lo + hi) >> 1; if (T[m] <= ta) lo = m; else hi = m; }
    for (let i = lo; i < T.length - 1 && T[i] <= t + tol / kt + 1; i++) {
      const ax = M.l + (T[i] - st.t0) * kt, ay = M.t + (X[i] - y0) * kx;
      const bx = M.l + (T[i + 1] - st.t0) * kt, by = M.t + (X[i + 1] - y0) * kx;
      const dx = bx - ax, dy = by - ay, L = dx * dx + dy * dy;
      const u = L > 0 ? Math.max(0, Math.min(1, ((px - ax) * dx + (py - ay) * dy) / L)) : 0;
      const d = Math.hypot(px - ax - u * dx, py - ay - u * dy);
      if (d < bd) { bd = d; best = tr; }
    }
  }
  return best;
}
function calls(tr) {
  const first = tr.calls[0], last = tr.calls[tr.calls.length - 1];
  return [first[0], first[2], last[0], last[1]];
}
function tipHtml(tr, t) {
  const [o, dep, d, arr] = calls(tr);
  const stops = tr.calls.filter(c => c[3]).length;
  let h = "<b>" + esc(tr.id) + "</b> · " + esc(tr.type) + " · " + tr.svc + " · " + tr.dir + "<br>" +
    esc(o) + " " + hhmm(dep) + " → " + esc(d) + " " + hhmm(arr) + " · " + stops + " of " + tr.calls.length + " calls stop";
  const x = xAt(tr, t);
  if (x !== null) {
    let near = D.stations[0]; for (const s of D.stations) if (Math.abs(s[2] - x) < Math.abs(near[2] - x)) near = s;
    h += "<br>at " + hhmm(t, true) + ": " + (x / 1000).toFixed(2) + " km (" + (Math.abs(near[2] - x) < 150 ? "at " : "near ") + esc(near[0]) + ")";
  }
  if (tr.pred) {  // the predicted day: how late, and the late event nearest the pointer's time
    const p = tr.pred, i = p.late.reduce((b, k) => Math.abs(p.T[k] - t) < Math.abs(p.T[b] - t) ? k : b, p.late[0]);
    h += "<br><span class='flag'>predicted day: " + p.late.length + " event" + (p.late.length > 1 ? "s" : "") + " late, up to " +
      delayText(p.o[p.worst]) + "</span><br>" + esc(eventText(tr, p, i).slice(tr.id.length + 1));
  }
  if (tr.m) {
    h += "<table><tr><td>margin</td><td>" + tr.m.margin_s + " s</td><td>bad day</td><td>" + tr.m.remaining_margin_s +
      " s</td></tr><tr><td>least on a leg</td><td>" + tr.m.min_remaining_margin_s + " s</td><td>legs</td><td>" + tr.m.n_legs + "</td></tr></table>";
    const f = []; if (tr.m.n_impossible) f.push(tr.m.n_impossible + " impossible");
    if (tr.m.n_short_bad_day) f.push(tr.m.n_short_bad_day + " short on a bad day"); if (tr.m.n_tight) f.push(tr.m.n_tight + " tight");
    if (tr.m.n_unreachable) f.push(tr.m.n_unreachable + " unreachable");
    if (f.length) h += "<span class='flag'>" + f.join(", ") + "</span><br>";
  } else h += "<br>margin: not given";
  if (tr.loops.length) h += "<br>stands on the loop at " + esc(tr.loops.join(", "));
  const cs = D.conflicts.filter(c => c[1] === tr.id || c[2] === tr.id);
  if (cs.length) {
    const ids = [...new Set(cs.map(c => c[0]))];
    h += "<br><span class='flag'>" + ids.length + " conflict" + (ids.length > 1 ? "s" : "") + "</span>: " +
      ids.slice(0, 3).map(i => { const c = cs.find(z => z[0] === i); return "#" + i + " with " + esc(c[1] === tr.id ? c[2] : c[1]) + " at " + esc(c[11] || c[9]) + " (delay " + c[7] + " s)"; }).join("; ");
  }
  return h + "<br><i>click: blocking-time stairway" + (D.tt ? ", running-time table and speed–distance charts" : "") + "</i>";
}
function highlight(tr, cls) {
  for (const p of gHi.querySelectorAll("." + cls)) p.remove();
  if (!tr) return;
  const p = tr.path.cloneNode(); p.setAttribute("stroke", cls === "sel" ? "#000" : tr.path.getAttribute("stroke"));
  p.setAttribute("stroke-width", cls === "hov" ? 3 : 2.6); p.setAttribute("class", cls);
  if (cls === "sel2") { p.setAttribute("stroke", "#000"); p.setAttribute("stroke-dasharray", "7 4"); }
  gHi.appendChild(p);
  if (tr.pred && cls !== "sel2" && st.show.predicted) for (const q of tr.pred.els) {  // its predicted run over it
    const c = q.cloneNode(true); c.setAttribute("class", cls + " pred");
    if (!q.classList.contains("pred-dot")) c.setAttribute("stroke-width", 2.4);
    gHi.appendChild(c);
  }
}
function stair(tr, colour, edge, cls) {
  // one train's blocking-time stairway: a box per window, opening to closing over the resource's chainage
  const w = D.windows[tr.id];
  if (!w) return 0;
  const s = undelta(w[0], 10), lo = undelta(w[2], 1);
  for (let i = 0; i < s.length; i++) {
    const r = el("rect", {x: s[i], y: lo[i], width: w[1][i] / 10, height: Math.max(w[3][i], 25), fill: colour,
      "fill-opacity": 0.45, stroke: edge, "stroke-width": 0.6, "vector-effect": "non-scaling-stroke", class: "window " + cls}, gStair);
    r.dataset.train = tr.id;
    const ti = el("title", {}, r); ti.textContent = tr.id + " · " + D.resources[w[4][i]] + ": " + hhmm(s[i], true) + "–" + hhmm(s[i] + w[1][i] / 10, true);
  }
  return s.length;
}
function clearSel() {
  st.sel = null; st.con = null; gStair.textContent = "";
  highlight(null, "sel"); highlight(null, "sel2");
  for (const r of conRects) r.classList.remove("chosen");
}
function zoomTo(tr) { setView(tr.t0 - 600, tr.t1 + 600); }
function refit() { if (fitHeight() !== H) layout(); }  // the selection's links may wrap the bar above the plot
function select(id) {
  const tr = id ? findTrain(id) : null;
  clearSel(); st.sel = tr;
  highlight(tr, "sel");
  const info = document.getElementById("selinfo");
  if (!tr) { for (const id of ["tt-link", "chart-links"]) { const x = document.getElementById(id); if (x) x.style.display = "none"; }
    info.textContent = "none"; history.replaceState(null, "", location.pathname + location.search); refit(); return; }
  const n = stair(tr, D.conflict.stair_a, "#8a6500", "a");
  info.textContent = tr.id + " (" + n + " blocking windows)";
  const tt = document.getElementById("tt-link");
  if (tt && D.tt) { tt.href = D.tt + "#train-" + encodeURIComponent(tr.id); tt.textContent = "running-time table of " + tr.id + " →"; tt.style.display = "inline"; }
  const ch = document.getElementById("chart-links");
  if (ch && D.charts) {
    ch.textContent = " · speed–distance charts:";
    const mine = (D.charts.by_train[tr.id] || []).map(i => D.charts.legs[i]);
    for (const [label, href] of mine) {
      const a = document.createElement("a"); a.href = href; a.textContent = label; ch.append(" ", a);
    }
    ch.style.display = mine.length ? "inline" : "none";
  }
  history.replaceState(null, "", "#train=" + encodeURIComponent(tr.id));
  refit();
}
function conText(rows) {
  const c = rows[0], t0 = Math.min(...rows.map(r => r[5])), t1 = Math.max(...rows.map(r => r[6]));
  return "#" + c[0] + ": " + c[1] + " before " + c[2] + " at " + c[9] + (rows.length > 1 ? " and " + (rows.length - 1) + " more" : "") +
    (c[11] ? " · " + c[11] : "") + " · " + hhmm(t0, true) + "–" + hhmm(t1, true) + " · delay " + c[7] + " s [" + c[8] + "]";
}
function selectConflict(cid, zoom) {
  const rows = byCon.get(cid);
  if (!rows) return;
  clearSel();
  const c = rows[0], A = byId.get(c[1]), B = byId.get(c[2]);
  st.con = cid;
  if (A) stair(A, D.conflict.stair_a, "#8a6500", "a");
  if (B) stair(B, D.conflict.stair_b, "#1d5f86", "b");
  for (const r of rows) {  // the overlap on each resource, over both stairways
    const o = el("rect", {fill: D.conflict.colour, "fill-opacity": 0.9, stroke: "#000", "stroke-width": 2,
      "vector-effect": "non-scaling-stroke", class: "overlap"}, gStair);
    o.dataset.t0 = r[5]; o.dataset.t1 = r[6]; o.dataset.x0 = r[3]; o.dataset.x1 = r[4];
    el("title", {}, o).textContent = "overlap " + hhmm(r[5], true) + "–" + hhmm(r[6], true) + " on " + r[9];
  }
  highlight(A, "sel"); highlight(B, "sel2");
  for (const r of conRects) r.classList.toggle("chosen", +r.dataset.cid === cid);
  document.getElementById("selinfo").textContent = conText(rows);
  history.replaceState(null, "", "#conflict=" + cid);
  if (zoom) {
    // both trains' windows on the conflict's resources, with a quarter of an hour around them (when the view is
    // wider than two hours or does not hold the overlap)
    const t0 = Math.min(...rows.map(r => r[5])), t1 = Math.max(...rows.map(r => r[6]));
    if (st.t1 - st.t0 > 2 * 3600 || t0 < st.t0 || t1 > st.t1) setView(t0 - 900, t1 + 900); else sizeConflicts();
  } else sizeConflicts();
}
svg.addEventListener("mousemove", ev => {
  const r = svg.getBoundingClientRect(), px = ev.clientX - r.left, py = ev.clientY - r.top;
  const box = ev.target.closest && ev.target.closest("rect.conflict");
  st.hoverCon = box ? +box.dataset.cid : null;
  if (box) {  // over a conflict: it, not the train under it
    if (st.hover) { st.hover = null; highlight(null, "hov"); }
    const rows = byCon.get(st.hoverCon);
    tip.innerHTML = "<b>conflict " + esc(conText(rows)).replace(/ · /g, "<br>") + "</b><br>" + esc(rows[0][10]) +
      (rows[0][12] !== null ? "<br>headway " + rows[0][12] + " s, minimum headway " + rows[0][13] + " s" : "") +
      "<br><i>click: both trains' blocking-time stairways</i>";
    tip.style.display = "block";
    const left = px + 16 + 360 > W() ? px - 16 - tip.offsetWidth : px + 16;
    tip.style.left = left + "px"; tip.style.top = Math.min(py + 12, H - tip.offsetHeight) + "px";
    return;
  }
  const tr = (px > M.l && py > M.t && py < H - M.b) ? nearest(px, py) : null;
  if (tr !== st.hover) { st.hover = tr; highlight(tr, "hov"); }
  if (!tr) { tip.style.display = "none"; return; }
  const t = st.t0 + (px - M.l) / PW() * (st.t1 - st.t0);
  tip.innerHTML = tipHtml(tr, t); tip.style.display = "block";
  const left = px + 16 + 360 > W() ? px - 16 - tip.offsetWidth : px + 16;
  tip.style.left = left + "px"; tip.style.top = Math.min(py + 12, H - tip.offsetHeight) + "px";
});
svg.addEventListener("mouseleave", () => { tip.style.display = "none"; st.hover = null; highlight(null, "hov"); });
svg.addEventListener("click", ev => {
  const box = ev.target.closest && ev.target.closest("rect.conflict");
  if (box) { tip.style.display = "none"; selectConflict(+box.dataset.cid, true); } else select(st.hover ? st.hover.id : null);
});
svg.addEventListener("wheel", ev => {
  ev.preventDefault();
  const r = svg.getBoundingClientRect(), px = ev.clientX - r.left;
  const f = Math.exp(ev.deltaY * 0.0015), t = st.t0 + (px - M.l) / PW() * (st.t1 - st.t0);
  setView(t - (t - st.t0) * f, t + (st.t1 - t) * f);
}, {passive: false});
let drag = null;
svg.addEventListener("mousedown", ev => { drag = {x: ev.clientX, t0: st.t0, t1: st.t1}; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", ev => {
  if (!drag) return; const dt = (ev.clientX - drag.x) / PW() * (drag.t1 - drag.t0);
  if (Math.abs(ev.clientX - drag.x) > 2) setView(drag.t0 - dt, drag.t1 - dt);
});
svg.addEventListener("dblclick", () => setView(D.day[0], D.day[1]));
const hours = document.getElementById("hours");
function viewButton(text, t0, t1, title, cls) {
  const b = document.createElement("button"); b.textContent = text; b.className = cls;
  b.dataset.t0 = t0; b.dataset.t1 = t1; b.title = title; hours.appendChild(b); return b;
}
viewButton("whole day", D.day[0], D.day[1], hhmm(D.day[0]) + "–" + hhmm(D.day[1]), "day");
if (D.start_view[0] !== D.day[0] || D.start_view[1] !== D.day[1])
  viewButton(D.start_view_name + " " + hhmm(D.start_view[0]) + "–" + hhmm(D.start_view[1]), D.start_view[0], D.start_view[1],
    "the view the page opens on", "start");
for (let t = D.day[0]; t < D.day[1]; t += 3600) {
  const b = document.createElement("button"); b.textContent = hhmm(t).slice(0, 2); b.className = "hour";
  b.dataset.t0 = t; b.dataset.t1 = t + 3600; b.title = hhmm(t) + "–" + hhmm(t + 3600); hours.appendChild(b);
}
hours.addEventListener("click", ev => { const b = ev.target.closest("button"); if (b) setView(+b.dataset.t0, +b.dataset.t1); });
for (const k of ["down", "up", "conflicts", "predicted"]) {
  const box = document.getElementById("show-" + k);  // "predicted" only when a train is late
  if (box) box.addEventListener("change", ev => { st.show[k] = ev.target.checked; visible(); layout(); });
}
document.getElementById("find").addEventListener("change", ev => {
  const tr = findTrain(ev.target.value);
  ev.target.style.background = tr || !ev.target.value ? "" : "#fdecea";
  if (tr) { select(tr.id); zoomTo(tr); }
});
window.addEventListener("resize", layout);
function fromHash() {
  // #train=ID: that train selected, the view on its run; #conflict=N: that conflict, zoomed
  const m = /train=([^&]+)/.exec(location.hash), mc = /conflict=(\d+)/.exec(location.hash);
  let text = null;
  if (m) { try { text = decodeURIComponent(m[1]); } catch (e) { text = m[1]; } }
  const tr = text !== null ? findTrain(text) : null;
  if (mc && byCon.has(+mc[1])) { selectConflict(+mc[1], true); return true; }
  if (tr) { select(tr.id); zoomTo(tr); return true; }
  if (text !== null) document.getElementById("selinfo").textContent = "no train " + text + " on this line";
  return false;
}
window.addEventListener("hashchange", fromHash);
layout(); visible();
if (!fromHash() && D.select && findTrain(D.select)) select(findTrain(D.select).id);
document.body.dataset.ready = "1";
