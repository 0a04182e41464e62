// util.js: the data block decoded into typed arrays (growing as a live session's rows
// arrive), row lookup, the journal at a time, formatting, colours.
// ``D`` is the page's data: the replay's data block, or a live session's (the page's wrapper).
/** A live session's page (allsky serve): rows and journal arrive as the mission flies. */
const LIVE = !!D.live;
const MODE_NAMES = Object.keys(D.modes);
// Mode colours (strip, shading, badge); the badge's text colour is chosen for contrast.
const MODE_COLOURS = ["#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2",
  "#edc948", "#9c755f", "#bab0ac", "#ff9da7", "#86bcb6", "#8cd17d"];
const AXIS_COLOURS = ["#1f5fa0", "#b34700", "#1e7b1e"];
const AXIS_NAMES = ["roll", "pitch", "yaw"];
const CPU_MODES = D.config.cpu_modes;  // the modes whose legs run CPU 22 (the mode table)
/** Modes whose CPU 22 pitch and yaw errors are the pointing error (on the target). */
const AIM_MODES = ["6-2", "hold", "standby"];
const RAD = Math.PI / 180;
const ARCSEC_PER_RAD = 180 * 3600 / Math.PI;
/** Smallest text the page draws [CSS px]. */
const MIN_FONT_PX = 11;
const FAULT_COLOUR = "#c0392b";
const TRUTH_COLOUR = "#d35400";

/** Integers from deltas; a ``[delta, count]`` element stands for ``count`` equal deltas. */
function undelta(d) {
  let n = 0;
  for (const e of d) n += Array.isArray(e) ? e[1] : 1;
  const out = new Float64Array(n);
  let s = 0, i = 0;
  for (const e of d) {
    if (Array.isArray(e)) { for (let k = 0; k < e[1]; k++) { s += e[0]; out[i++] = s; } }
    else { s += e; out[i++] = s; }
  }
  return out;
}

// The record: the telemetry columns decoded. ``C`` keeps the run-coded columns, the
// selector and the valves; T_MS, EXACT and CONT are views of growing buffers.
const C = { n: 0, runs: {}, selector: "", valves: ["", "", ""] };
let N = 0, T0 = 0, T1 = 0, STRIDE = 1;
/** Telemetry time of each row [ms], exact to the millisecond. */
let T_MS = new Float64Array(0);
const EXACT = {}, CONT = {};
const STORE = {};  // name -> {buf, n}: a column's values, with room to grow
/** Called with the first new row after rows are appended (a live page). */
const ON_ROWS = [];
/** Called after the journal's parts of the data are replaced (a live page). */
const ON_JOURNAL = [];

function put(name, values) {
  const st = STORE[name] || (STORE[name] = { buf: new Float64Array(0), n: 0 });
  if (st.n + values.length > st.buf.length) {
    const grown = new Float64Array(Math.max(2 * st.buf.length, st.n + values.length, 1024));
    grown.set(st.buf.subarray(0, st.n));
    st.buf = grown;
  }
  st.buf.set(values, st.n);
  st.n += values.length;
  return st.buf.subarray(0, st.n);
}

/** Append the rows of ``chunk`` (encoded as the data block's ``columns``) to the record. */
function appendColumns(chunk) {
  const i0 = N, n = chunk.n;
  if (!n) return;
  if (i0 > 0 && chunk.stride !== 1) throw new Error("appended rows must not be thinned");
  T_MS = put("t_ms", undelta(chunk.t_ms));
  for (const k in chunk.exact) EXACT[k] = put(`x:${k}`, undelta(chunk.exact[k]));
  for (const k in chunk.cont) {
    const a = undelta(chunk.cont[k].d), s = chunk.cont[k].scale;
    for (let i = 0; i < a.length; i++) a[i] /= s;
    CONT[k] = put(`c:${k}`, a);
  }
  for (const k in chunk.runs) {
    const runs = C.runs[k] || (C.runs[k] = []);
    for (const [row, v] of chunk.runs[k]) {
      if (!runs.length || runs[runs.length - 1][1] !== v) runs.push([row + i0, v]);
    }
  }
  C.selector += chunk.selector;
  chunk.valves.forEach((v, a) => { C.valves[a] += v; });
  N += n;
  C.n = N;
  if (i0 === 0) { STRIDE = chunk.stride; T0 = T_MS[0] / 1000; }
  T1 = T_MS[N - 1] / 1000;
  for (const f of ON_ROWS) f(i0);
}
appendColumns(D.columns);
/** Is a column in the record (a file of an earlier format lacks the newer ones)? */
const HAS = (name) => name in CONT || name in EXACT || name in C.runs;

/** Value at row ``i`` of a continuous column (thinned columns: the nearest kept row). */
function cont(name, i) {
  const a = CONT[name];
  return a ? a[Math.min(Math.floor(i / STRIDE), a.length - 1)] : NaN;
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
  if (!runs) return 0;
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
  return k < 0 ? "#888888" : MODE_COLOURS[k % MODE_COLOURS.length];
}

/** Relative luminance of "#rrggbb" (WCAG 2). */
function luminance(hex) {
  const c = [1, 3, 5].map((k) => parseInt(hex.slice(k, k + 2), 16) / 255)
    .map((v) => (v <= 0.03928 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4)));
  return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

/** Black or white, whichever reads better on background ``hex``. */
function textOn(hex) {
  const l = luminance(hex);
  return (l + 0.05) / 0.05 >= 1.05 / (l + 0.05) ? "#000000" : "#ffffff";
}

function modeLabel(name) { return name === "hold" ? "Hold" : MODE_NAMES.indexOf(name) >= 0
  && /^[0-9]/.test(name) ? `Mode ${name}` : name.charAt(0).toUpperCase() + name.slice(1); }

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
let TARGETS = D.sky.targets;

/** Replace the journal's parts of the data (a live page): the log, timeline, faults ... */
function setJournal(page) {
  for (const k in page) if (k !== "targets" && k !== "locked" && k !== "window") D[k] = page[k];
  if (page.targets) { D.sky.targets = page.targets; TARGETS = page.targets; }
  if ("locked" in page) D.sky.locked = page.locked;
  if (page.window) {  // star tracker 105's magnitude window, as commanded
    D.sky.window = page.window;
    for (const st of D.sky.stars) st.win = page.window[0] <= st.mag && st.mag <= page.window[1];
  }
  for (const f of ON_JOURNAL) f();
}

/** Index in TARGETS of the target flown at mission time t_s: the last one begun by then. */
function targetAt(t_s) {
  let k = 0;
  for (let j = 0; j < TARGETS.length; j++) if (TARGETS[j].start_s <= t_s + 1e-9) k = j;
  return k;
}

/** The entry of a time-stamped list (``t_s`` ascending) in force at time t. */
function inForce(list, t) {
  let out = null;
  if (!list) return out;
  for (const e of list) { if (e.t_s <= t + 1e-9) out = e; else break; }
  return out;
}

/** The star in the tracker's slit at time t (the journal's star_lock entries), or null. */
function starInSlit(t) {
  const e = inForce(D.tracker, t);
  return e ? e.star : null;
}

/** The faults acting at time t: onset at or before t, not yet ended. */
function faultsAt(t) {
  return D.faults.filter((f) => f.start_s <= t + 1e-9 && (f.end_s === null || t < f.end_s - 1e-9));
}

/** The mission's status at time t: "flying", "complete", "aborted" (null: not known). */
function statusAt(t) {
  const e = D.ending;
  if (!e) return t >= T1 - 1e-9 ? null : "flying";
  if (e.status !== "complete" && e.status !== "aborted") return "flying";
  if (t >= e.t_s - 1e-9) return e.status;
  // An ending between the last row and the next the recorder would have written (a live
  // flight ends on a frame, its rows come every few): the record ends with the mission.
  const last = N > 1 ? (T_MS[N - 1] - T_MS[N - 2]) / 1000 : 0;
  if (t >= T1 - 1e-9 && e.t_s - T1 < last - 1e-9) return e.status;
  return "flying";
}

/** Angle [rad] between unit-ish vectors a and b, exact near 0 and pi (atan2). */
function angleBetween(a, b) {
  const c = cross(a, b);
  return Math.atan2(Math.hypot(c[0], c[1], c[2]), dot(a, b));
}

/** Everything the page shows at row ``i``, read once per redraw. */
function rowState(i) {
  const mask = runValue(C.runs.switches, i);
  const qn = norm4([cont("q_w", i), cont("q_x", i), cont("q_y", i), cont("q_z", i)]);
  const s = {
    i: i, t_s: T_MS[i] / 1000, mode: modeName(runValue(C.runs.mode, i)), mask: mask,
    selector: +C.selector[i], q: qn,
    rate: [cont("rate_x", i), cont("rate_y", i), cont("rate_z", i)],
    // The gyros' outputs [arcsec/s], what counters 14/16/18 integrate (NaN: not recorded).
    gyro: [cont("gyro_roll", i), cont("gyro_pitch", i), cont("gyro_yaw", i)],
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
    wheelH: [cont("wheel_h_x", i), cont("wheel_h_y", i), cont("wheel_h_z", i)],
    unloading: runValue(C.runs.unloading, i) > 0.5,
  };
  s.closed = {};
  for (let k = 1; k <= 19; k++) s.closed[k] = switchClosed(mask, k);
  s.cpu = CPU_MODES.indexOf(s.mode) >= 0;
  s.target = targetAt(s.t_s);
  // Pulse rate of converters 8/10/12 from the counters' change over the last interval.
  const j = i > 0 ? i - 1 : 0, dt = (T_MS[i] - T_MS[j]) / 1000;
  s.pps = [0, 1, 2].map((a) => (dt > 0 ? (s.counters[a] - [EXACT.counter14, EXACT.counter16,
    EXACT.counter18][a][j]) / dt : 0));
  s.rateDeg = s.rate.map((r) => r / RAD);
  s.gyroDeg = s.gyro.map((r) => r / 3600);
  // The truth: +x to the target being flown (the recorded column; the attitude otherwise).
  const c = dcm(s.q), x = toInertial(c, [1, 0, 0]);
  s.xToTargetArcsec = angleBetween(x, TARGETS[s.target].vec) * ARCSEC_PER_RAD;
  s.trueErr = HAS("true_error") ? cont("true_error", i) : s.xToTargetArcsec;
  // CPU 22's pointing error: pitch and yaw move +x off the target (Mode 6-2 and the hold).
  s.cpuPointing = AIM_MODES.indexOf(s.mode) >= 0 ? Math.hypot(s.errors[1], s.errors[2]) : null;
  return s;
}

function fmt(v, digits, width) {
  let s = (v >= 0 ? "+" : "\u2212") + Math.abs(v).toFixed(digits);
  if (width) s = s.padStart(width);
  return s;
}

function fmtInt(v) { return (v < 0 ? "\u2212" : "") + Math.abs(Math.round(v)).toString(); }

/** A rate [deg/s] in at most 7 characters: 3 decimals below 10 deg/s, 2 beyond. */
function fmtRate(v) { return fmt(v, Math.abs(v) < 9.9995 ? 3 : 2); }

/** An angle [arcsec] in arcsec below 1 deg, in degrees beyond (unsigned: a separation). */
function fmtSep(arcsec) {
  if (!Number.isFinite(arcsec)) return "\u2014";
  return arcsec < 3600 ? `${arcsec.toFixed(1)}\u2033` : `${(arcsec / 3600).toFixed(3)}\u00b0`;
}

/** A signed error [arcsec], one decimal below 10000 arcsec. */
function fmtErr(v) { return Math.abs(v) < 9999.95 ? `${fmt(v, 1)}\u2033` : `${fmt(v, 0)}\u2033`; }

function fmtTime(t) {
  const m = Math.floor(t / 60), s = t - 60 * m;
  return `${t.toFixed(1)} s (${m}:${s.toFixed(1).padStart(4, "0")})`;
}

function norm4(q) {
  const n = Math.hypot(q[0], q[1], q[2], q[3]) || 1;
  return [q[0] / n, q[1] / n, q[2] / n, q[3] / n];
}

/** Body-from-inertial rotation matrix rows of quaternion q = [w, x, y, z] (normalised). */
function dcm(q0) {
  const [w, x, y, z] = norm4(q0);
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

/** The Moon and the planets at mission time t_s [s], geocentric (the page's sky):
 *  [{name, ra_deg, dec_deg, magnitude, phase, in_window, flown}], flown meaning the
 *  tracker sees them (star_tracker.moving_bodies). Between the samples the direction is
 *  interpolated; past them, held. */
function bodiesAt(t_s) {
  const out = [];
  for (const b of D.sky.bodies || []) {
    const n = b.ra.length, x = Math.max(0, Math.min(n - 1, t_s / b.step_s));
    const k = Math.min(n - 2, Math.floor(x)), w = n > 1 ? x - k : 0;
    const u = unitFromRadec(b.ra[Math.max(k, 0)], b.dec[Math.max(k, 0)]);
    const v = n > 1 ? unitFromRadec(b.ra[k + 1], b.dec[k + 1]) : u;
    const [ra, dec] = radec(norm([0, 1, 2].map((i) => u[i] + w * (v[i] - u[i]))));
    out.push({ name: b.name, ra_deg: ra, dec_deg: dec, magnitude: b.mag, phase: b.phase,
      in_window: b.win, flown: b.flown });
  }
  return out;
}

/** Inertial direction of a catalog star, or of a moving body at mission time t_s [s], by
 *  name; or null. */
function starVec(name, t_s) {
  const st = D.sky.stars.find((x) => x.name === name);
  if (st) return unitFromRadec(st.ra, st.dec);
  const b = bodiesAt(t_s || 0).find((x) => x.name === name);
  return b ? unitFromRadec(b.ra_deg, b.dec_deg) : null;
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

/** A canvas font of at least MIN_FONT_PX. */
function font(px, weight, family) {
  return `${weight || ""} ${Math.max(MIN_FONT_PX, px)}px ${family || "system-ui, sans-serif"}`.trim();
}

/** Write ``text`` at (x, y), moved inside [0, w] x [0, h] so that none of it is cut. */
function fillTextInside(ctx, text, x, y, w, h) {
  const m = ctx.measureText(text), tw = m.width;
  const asc = m.actualBoundingBoxAscent || 9, desc = m.actualBoundingBoxDescent || 3;
  const xx = Math.max(1, Math.min(x, w - tw - 1)), yy = Math.max(asc + 1, Math.min(y, h - desc - 1));
  ctx.fillText(text, xx, yy);
  return [xx, yy, tw];
}

/** The labels of one drawing of a canvas, placed so that no two overlap.
 *
 *  ``want`` queues a label: its text, font and colour, the point it names (ax, ay) and
 *  the place it prefers (baseline-left px, py); ``flush`` writes them by priority (lower
 *  first), each at the first free one of its preferred place and places around its point,
 *  farther and farther, inside [0, w] x [0, h]. A label no place is free for is not
 *  written (``dropped`` counts them). ``reserve`` keeps a box [x0, y0, x1, y1] free. */
function labelLayer(ctx, w, h) {
  const boxes = [], queue = [];
  let dropped = 0;
  const free = (b) => boxes.every((o) => b[2] <= o[0] || b[0] >= o[2] || b[3] <= o[1] || b[1] >= o[3]);
  function put(q) {
    ctx.font = q.font;
    const m = ctx.measureText(q.text), tw = m.width;
    const asc = m.actualBoundingBoxAscent || 9, desc = m.actualBoundingBoxDescent || 3;
    const lh = asc + desc;
    const cands = [[q.px, q.py]];
    for (let k = 1; k <= 5; k++) {
      const d = 3 + 5 * k, v = (k - 1) * lh;
      cands.push([q.ax + d, q.ay + asc / 2], [q.ax - d - tw, q.ay + asc / 2],
        [q.ax - tw / 2, q.ay - d - desc - v], [q.ax - tw / 2, q.ay + d + asc + v],
        [q.ax + d, q.ay - d - desc - v], [q.ax + d, q.ay + d + asc + v],
        [q.ax - d - tw, q.ay - d - desc - v], [q.ax - d - tw, q.ay + d + asc + v]);
    }
    for (const [cx, cy] of cands) {
      const x = Math.max(1, Math.min(cx, q.w - tw - 1)), y = Math.max(asc + 1, Math.min(cy, q.h - desc - 1));
      const b = [x - 1, y - asc - 1, x + tw + 1, y + desc + 1];
      if (free(b)) {
        ctx.fillStyle = q.colour; ctx.globalAlpha = q.alpha;
        ctx.fillText(q.text, x, y);
        ctx.globalAlpha = 1;
        boxes.push(b);
        return b;
      }
    }
    dropped += 1;
    return null;
  }
  return {
    reserve: (b) => boxes.push(b),
    want: (text, ax, ay, px, py, opts) => queue.push(Object.assign({ text: text, ax: ax, ay: ay,
      px: px, py: py, font: font(12), colour: "#1d2330", priority: 5, alpha: 1, w: w, h: h },
      opts || {}, { order: queue.length })),
    flush: () => {
      queue.sort((a, b) => a.priority - b.priority || a.order - b.order).forEach(put);
      queue.length = 0;
      return dropped;
    },
    boxes: () => boxes.map((b) => b.slice()),
  };
}

const SVG_NS = "http://www.w3.org/2000/svg";
function svgEl(tag, attrs, parent) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const k in attrs) el.setAttribute(k, attrs[k]);
  if (parent) parent.appendChild(el);
  return el;
}
