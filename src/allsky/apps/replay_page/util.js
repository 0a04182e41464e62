// util.js: the data block decoded into typed arrays, row lookup, formatting, colours.
const D = JSON.parse(document.getElementById("allsky-data").textContent);
const C = D.columns;
const N = C.n;
const MODE_NAMES = Object.keys(D.modes);
const MODE_COLOURS = ["#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2",
  "#edc948", "#9c755f"];
const AXIS_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c"];
const AXIS_NAMES = ["roll", "pitch", "yaw"];
const CPU_MODES = ["6-1", "6-2", "hold"];
const RAD = Math.PI / 180;

function undelta(d) {
  const out = new Float64Array(d.length);
  let s = 0;
  for (let i = 0; i < d.length; i++) { s += d[i]; out[i] = s; }
  return out;
}

/** Telemetry time of each row [ms], exact to the millisecond. */
const T_MS = undelta(C.t_ms);
const T0 = T_MS[0] / 1000, T1 = T_MS[N - 1] / 1000;
const EXACT = {};
for (const k in C.exact) EXACT[k] = undelta(C.exact[k]);
const CONT = {};
for (const k in C.cont) {
  const a = undelta(C.cont[k].d), s = C.cont[k].scale;
  for (let i = 0; i < a.length; i++) a[i] /= s;
  CONT[k] = a;
}
const STRIDE = C.stride;

/** Value at row ``i`` of a continuous column (thinned columns: the nearest kept row). */
function cont(name, i) {
  return CONT[name][Math.min(Math.floor(i / STRIDE), CONT[name].length - 1)];
}

/** The last row at or before mission time ``t_s`` (the first row before the record). */
function rowAt(t_s) {
  const ms = Math.round(t_s * 1000);
  let lo = 0, hi = N - 1;
  if (ms <= T_MS[0]) return 0;
  if (ms >= T_MS[hi]) return hi;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (T_MS[mid] <= ms) lo = mid; else hi = mid;
  }
  return lo;
}

/** Value of a run-coded column at row ``i``: ``runs`` is [[first row, value], ...]. */
function runValue(runs, i) {
  let lo = 0, hi = runs.length - 1;
  if (hi < 0) return 0;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (runs[mid][0] <= i) lo = mid; else hi = mid - 1;
  }
  return runs[lo][1];
}

/** Mode name of a telemetry mode code. */
function modeName(code) {
  for (const n of MODE_NAMES) if (Math.abs(D.modes[n].code - code) < 1e-6) return n;
  return "?";
}

function modeColour(name) {
  const k = MODE_NAMES.indexOf(name);
  return k < 0 ? "#888" : MODE_COLOURS[k % MODE_COLOURS.length];
}

/** Switch numbers of the selectors (S7/S8), from the wiring table. */
const SELECTORS = D.diagram.switches.filter((sw) => sw.selector).map((sw) => sw.n);

/**
 * Is switch Sk closed in switch-bank bitmask ``mask``? A selector (S7/S8) is never
 * open: it always joins its common terminal to one contact (the row's ``selector``),
 * and the bitmask holds no bit for it.
 */
function switchClosed(mask, k) {
  if (SELECTORS.indexOf(k) >= 0) return true;
  return ((Math.floor(mask / Math.pow(2, k - 1))) % 2) === 1;
}

/** Register 23's words by where they come from: the summary's are exact, others marked. */
const WORD_MARK = { counters: " \u2248", later: " ?" };

/** The targets in flight order: name, inertial direction, start_s and end_s [s]. */
const TARGETS = D.sky.targets;

/** Index in TARGETS of the target flown at mission time t_s: the last one begun by then. */
function targetAt(t_s) {
  let k = 0;
  for (let j = 0; j < TARGETS.length; j++) if (TARGETS[j].start_s <= t_s + 1e-9) k = j;
  return k;
}

/** Everything the page shows at row ``i``, read once per redraw. */
function rowState(i) {
  const mask = runValue(C.runs.switches, i);
  const s = {
    i: i, t_s: T_MS[i] / 1000, mode: modeName(runValue(C.runs.mode, i)), mask: mask,
    selector: +C.selector[i],
    q: [cont("q_w", i), cont("q_x", i), cont("q_y", i), cont("q_z", i)],
    rate: [cont("rate_x", i), cont("rate_y", i), cont("rate_z", i)],
    sun: [cont("sun_pitch", i), cont("sun_yaw", i)],
    sunPresent: runValue(C.runs.sun_present, i) > 0.5,
    trk: [cont("tracker_yaw", i), cont("tracker_pitch", i)],
    starPresent: runValue(C.runs.star_present, i) > 0.5,
    counters: [EXACT.counter14[i], EXACT.counter16[i], EXACT.counter18[i]],
    drift: [EXACT.drift_counter13[i], EXACT.drift_counter15[i], EXACT.drift_counter17[i]],
    registers: [EXACT.register25[i], EXACT.register26[i], EXACT.register27[i]],
    valves: [C.valves[0].charCodeAt(i) - 49, C.valves[1].charCodeAt(i) - 49,
      C.valves[2].charCodeAt(i) - 49],
    amps: [cont("amp31", i), cont("amp32", i), cont("amp33", i)],
    errors: [cont("error_roll", i), cont("error_pitch", i), cont("error_yaw", i)],
    corrected: [cont("corrected_roll", i), cont("intermediate_pitch", i), cont("corrected_yaw", i)],
    propellant: cont("propellant", i), overflow: runValue(C.runs.overflow, i),
  };
  s.closed = {};
  for (let k = 1; k <= 19; k++) s.closed[k] = switchClosed(mask, k);
  s.cpu = CPU_MODES.indexOf(s.mode) >= 0;
  s.target = targetAt(s.t_s);
  // Pulse rate of converters 8/10/12 from the counters' change over the last interval.
  const j = i > 0 ? i - 1 : 0, dt = (T_MS[i] - T_MS[j]) / 1000;
  s.pps = [0, 1, 2].map((a) => (dt > 0 ? (s.counters[a] - [EXACT.counter14, EXACT.counter16,
    EXACT.counter18][a][j]) / dt : 0));
  return s;
}

/** The entry of a time-stamped list (``t_s`` ascending) in force at time t. */
function inForce(list, t) {
  let out = null;
  for (const e of list) { if (e.t_s <= t + 1e-9) out = e; else break; }
  return out;
}

function fmt(v, digits, width) {
  let s = (v >= 0 ? "+" : "\u2212") + Math.abs(v).toFixed(digits);
  if (width) s = s.padStart(width);
  return s;
}

function fmtInt(v) { return (v < 0 ? "\u2212" : "") + Math.abs(Math.round(v)).toString(); }

function fmtTime(t) {
  const m = Math.floor(t / 60), s = t - 60 * m;
  return `${t.toFixed(1)} s (${m}:${s.toFixed(1).padStart(4, "0")})`;
}

/** Body-from-inertial rotation matrix rows of quaternion q = [w, x, y, z]. */
function dcm(q) {
  const [w, x, y, z] = q;
  return [
    [w * w + x * x - y * y - z * z, 2 * (x * y + w * z), 2 * (x * z - w * y)],
    [2 * (x * y - w * z), w * w - x * x + y * y - z * z, 2 * (y * z + w * x)],
    [2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z],
  ];
}

/** Inertial direction of body vector b: C^T b. */
function toInertial(c, b) {
  return [c[0][0] * b[0] + c[1][0] * b[1] + c[2][0] * b[2],
    c[0][1] * b[0] + c[1][1] * b[1] + c[2][1] * b[2],
    c[0][2] * b[0] + c[1][2] * b[1] + c[2][2] * b[2]];
}

function norm(v) { const n = Math.hypot(v[0], v[1], v[2]); return [v[0] / n, v[1] / n, v[2] / n]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function cross(a, b) {
  return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
}

/** Sun direction (inertial) at mission time t, as the mission computed it. */
function sunAt(t) {
  const s0 = D.sky.sun0, r = D.sky.sun_rate;
  return norm([s0[0] + r[0] * t, s0[1] + r[1] * t, s0[2] + r[2] * t]);
}

/** Right ascension and declination [deg] of a unit vector. */
function radec(v) {
  let ra = Math.atan2(v[1], v[0]) / RAD;
  if (ra < 0) ra += 360;
  return [ra, Math.asin(Math.max(-1, Math.min(1, v[2]))) / RAD];
}

function unitFromRadec(ra, dec) {
  return [Math.cos(dec * RAD) * Math.cos(ra * RAD), Math.cos(dec * RAD) * Math.sin(ra * RAD),
    Math.sin(dec * RAD)];
}

/** The tracker slit's outline in body axes: rays at its edges (yaw across, pitch along). */
function slitOutlineBody(steps) {
  const n = D.sky.slit_narrow_half_deg * RAD, l = D.sky.slit_long_half_deg * RAD;
  const pts = [];
  const edge = (p, y) => norm([Math.tan(p), -Math.tan(y), 1]);
  for (let k = 0; k <= steps; k++) pts.push(edge(-l + 2 * l * k / steps, -n));
  for (let k = 0; k <= steps; k++) pts.push(edge(l, -n + 2 * n * k / steps));
  for (let k = 0; k <= steps; k++) pts.push(edge(l - 2 * l * k / steps, n));
  for (let k = 0; k <= steps; k++) pts.push(edge(-l, n - 2 * n * k / steps));
  return pts;
}

/** A canvas sized to its box in device pixels; returns its 2-D context in CSS pixels. */
function fitCanvas(canvas) {
  const r = canvas.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(r.width)), h = Math.max(1, Math.round(r.height));
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return { ctx: ctx, w: w, h: h };
}

/** An offscreen canvas of w x h CSS pixels in device pixels; its 2-D context in CSS pixels. */
function offscreenCanvas(w, h) {
  const canvas = document.createElement("canvas"), dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(w * dpr);
  canvas.height = Math.round(h * dpr);
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return { canvas: canvas, ctx: ctx };
}

const SVG_NS = "http://www.w3.org/2000/svg";
function svgEl(tag, attrs, parent) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const k in attrs) el.setAttribute(k, attrs[k]);
  if (parent) parent.appendChild(el);
  return el;
}
