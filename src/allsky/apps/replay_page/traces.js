// traces.js: errors per axis, the true error to the target beside CPU 22's, counters, valve
// duty (or the wheels' momentum) against time: ticks, thresholds, modes and faults shaded.
const TRACES = (function () {
  const canvas = document.getElementById("traces");
  const LEFT = 118, RIGHT = 10, TOP = 16, BOTTOM = 30;
  const LIN = 10;  // arcsec: linear inside, logarithmic beyond (as the PNG figures)
  const sym = (v) => Math.sign(v) * Math.log10(1 + Math.abs(v) / LIN);
  const unsym = (y) => Math.sign(y) * LIN * (Math.pow(10, Math.abs(y)) - 1);
  const LOG_FLOOR = 0.05;  // arcsec: the log strip's floor
  const lg = (v) => Math.log10(Math.max(LOG_FLOOR, v));
  // Where each signal applies, per row, computed once (and for each row a live page adds).
  const SUN_ON = [], STAR_ON = [], CPU_ON = [], AIM_ON = [];
  const MODE_OF = (i) => modeName(runValue(C.runs.mode, i));
  const sunOn = (i) => SUN_ON[i] === 1, starOn = (i) => STAR_ON[i] === 1;
  const cpuOn = (i) => CPU_ON[i] === 1, aimOn = (i) => AIM_ON[i] === 1;
  const SUN = "#c62828", TRK = "#7b3fb5", CPU = "#111111";
  const pw = D.config.pulse_weight_arcsec / 3600;  // degrees per pulse
  const settle = D.config.settle_threshold_arcsec, handover = D.config.handover_arcsec;
  const WHEELS = D.vehicle.kind === "wheels";
  // Valve duty: on-time per second over the second before each row [%].
  const DUTY_COLS = ["jet_on_roll", "jet_on_pitch", "jet_on_yaw"];
  const DUTY = DUTY_COLS.map((name) => (HAS(name) ? [] : null));
  let dutyJ = 0;
  function extend(i0) {
    for (let i = i0; i < N; i++) {
      SUN_ON[i] = runValue(C.runs.sun_present, i) > 0.5 ? 1 : 0;
      STAR_ON[i] = runValue(C.runs.star_present, i) > 0.5 ? 1 : 0;
      const mode = MODE_OF(i);
      CPU_ON[i] = CPU_MODES.indexOf(mode) >= 0 ? 1 : 0;
      AIM_ON[i] = AIM_MODES.indexOf(mode) >= 0 ? 1 : 0;
      while (dutyJ < i && T_MS[i] - T_MS[dutyJ + 1] >= 1000) dutyJ++;
      const dt = (T_MS[i] - T_MS[dutyJ]) / 1000;
      DUTY.forEach((out, a) => {
        if (out) out[i] = dt > 0 ? 100 * (cont(DUTY_COLS[a], i) - cont(DUTY_COLS[a], dutyJ)) / dt : 0;
      });
    }
  }
  let renderedAt = 0;
  extend(0);
  ON_ROWS.push(extend);
  ON_JOURNAL.push(() => { bg = null; });
  const v = (name, scale) => (i) => (EXACT[name] ? EXACT[name][i] : cont(name, i)) * (scale || 1);
  const strips = [
    { name: "roll error", unit: "\u2033", kind: "sym", lines: [settle, handover],
      series: [["tracker 105 across the slit", v("tracker_yaw"), starOn, TRK, null, "tracker 105"],
        ["CPU 22 roll", v("error_roll"), cpuOn, CPU, null, "CPU 22"]] },
    { name: "pitch error", unit: "\u2033", kind: "sym", lines: [settle, handover],
      series: [["sun sensor 104 pitch", v("sun_pitch"), sunOn, SUN, null, "sun sensor 104"],
        ["star along the slit (tracker 105 pitch)", v("tracker_pitch"), starOn, TRK, [4, 3], "star along the slit (105 pitch)"],
        ["CPU 22 pitch", v("error_pitch"), cpuOn, CPU, null, "CPU 22"]] },
    { name: "yaw error", unit: "\u2033", kind: "sym", lines: [settle, handover],
      series: [["sun sensor 104 yaw", v("sun_yaw"), sunOn, SUN, null, "sun sensor 104"],
        ["CPU 22 yaw", v("error_yaw"), cpuOn, CPU, null, "CPU 22"]] },
    { name: "to target", unit: "\u2033", kind: "log", lines: [settle, handover],
      series: [["true error, +x to the target (truth)", (i) => (HAS("true_error")
        ? cont("true_error", i) : NaN), null, TRUTH_COLOUR, null, "true error to the target"],
      ["CPU 22's error (pitch, yaw), Modes 6-2 and hold", (i) => Math.hypot(cont("error_pitch", i),
        cont("error_yaw", i)), aimOn, CPU, null, "CPU 22"]] },
    { name: "counters", unit: "\u00b0", kind: "lin",
      series: [0, 1, 2].map((a) => [`counter ${[14, 16, 18][a]} ${AXIS_NAMES[a]}`,
        v(`counter${[14, 16, 18][a]}`, pw), null, AXIS_COLOURS[a], null, AXIS_NAMES[a]]) },
  ];
  if (WHEELS) {
    const lim = D.vehicle.max_momentum_n_m_s;
    strips.push({ name: "wheels", unit: " Nms", kind: "lin", lines: [],
      series: [0, 1, 2].map((a) => [`wheel momentum ${"xyz"[a]}`, v(`wheel_h_${"xyz"[a]}`),
        null, AXIS_COLOURS[a], null, AXIS_NAMES[a]]), fixed: null, limit: lim });
  }
  const fired = DUTY[0] && DUTY.some((d) => d.some((x) => x > 0));
  if (DUTY[0] && (fired || !WHEELS || LIVE)) {
    strips.push({ name: "valve duty", unit: "%", kind: "lin", fixed: [0, 100],
      series: [0, 1, 2].map((a) => [`jets ${39 + a} ${AXIS_NAMES[a]}: on-time per second`,
        (i) => DUTY[a][i], null, AXIS_COLOURS[a], null, AXIS_NAMES[a]]) });
  }
  let bg = null, bgKey = "", geom = null, zoom = false, span = [T0, T1];

  function niceStep(range, px) {
    const want = range / Math.max(1, px / 80);
    for (const s of [1, 2, 5, 10, 20, 30, 60, 120, 300, 600, 1200, 1800, 3600, 7200])
      if (s >= want) return s;
    return 10800;
  }

  function layout(w, h) {
    const sh = (h - TOP - BOTTOM) / strips.length;
    const [a, b] = span, len = Math.max(b - a, 1e-9);
    return { w: w, h: h, sh: sh, x: (t) => LEFT + (t - a) / len * (w - LEFT - RIGHT),
      t: (x) => a + (x - LEFT) / (w - LEFT - RIGHT) * len };
  }

  /** Tick values of a strip in its own (transformed) coordinate, with labels. */
  function ticks(st, lo, hi, pxPerUnit) {
    let cand;
    if (st.kind === "sym") {
      cand = [0];
      for (const m of [10, 100, 3600, 36000, 360000]) cand.push(m, -m);
      cand = cand.map((c) => [sym(c), c === 0 ? "0" : `${c < 0 ? "\u2212" : "+"}${Math.abs(c) >= 3600
        ? Math.abs(c) / 3600 + "\u00b0" : Math.abs(c) + "\u2033"}`]);
    } else if (st.kind === "log") {
      cand = [0.1, 1, 10, 100, 3600, 36000, 360000].map((c) => [lg(c), c >= 3600
        ? `${c / 3600}\u00b0` : `${c}\u2033`]);
    } else {
      const step = niceStepLin(hi - lo, pxPerUnit);
      cand = [];
      for (let x = Math.ceil(lo / step) * step; x <= hi + 1e-9; x += step)
        cand.push([x, `${Math.abs(x) < 1e-9 ? 0 : +x.toPrecision(6)}${st.unit}`]);
    }
    const inside = cand.filter(([y]) => y >= lo - 1e-9 && y <= hi + 1e-9);
    // Keep ticks at least 13 px apart, the zero (or the smallest) first.
    inside.sort((a, b) => Math.abs(a[0]) - Math.abs(b[0]));
    const kept = [];
    for (const c of inside) if (kept.every((k) => Math.abs(k[0] - c[0]) * pxPerUnit >= 13)) kept.push(c);
    return kept;
  }

  function niceStepLin(range, pxPerUnit) {
    const want = 16 / Math.max(pxPerUnit, 1e-9);
    const p = Math.pow(10, Math.floor(Math.log10(Math.max(want, range / 4, 1e-12))));
    for (const m of [1, 2, 5, 10]) if (m * p >= want && m * p >= range / 4) return m * p;
    return 10 * p;
  }

  function render(w, h) {
    const key = `${w}x${h}:${span[0]}:${span[1]}`;
    if (bg && bgKey === key) return bg;
    // A live page redraws its background at most four times a second as rows arrive.
    const now = performance.now();
    if (LIVE && bg && bgKey.startsWith(`${w}x${h}:`) && now - renderedAt < 250) return bg;
    renderedAt = now;
    geom = layout(w, h);
    const off = offscreenCanvas(w, h), ctx = off.ctx;
    bg = off.canvas;
    const i0 = rowAt(span[0]), i1 = rowAt(span[1]);
    ctx.fillStyle = "#ffffff"; ctx.fillRect(0, 0, w, h);
    const bottom = h - BOTTOM;
    for (const m of D.timeline) {
      if (m.end_s < span[0] || m.start_s > span[1]) continue;
      const x0 = Math.max(LEFT, geom.x(m.start_s)), x1 = Math.min(w - RIGHT, geom.x(m.end_s));
      ctx.fillStyle = modeColour(m.mode); ctx.globalAlpha = 0.12;
      ctx.fillRect(x0, TOP, x1 - x0, bottom - TOP);
      ctx.globalAlpha = 1; ctx.fillStyle = "#1d2330"; ctx.font = font(11, "bold");
      // A mode of no duration (the hand-over to the next target) is named in the event log.
      const label = m.mode;
      if (x1 - x0 >= ctx.measureText(label).width + 4) fillTextInside(ctx, label, (x0 + x1) / 2 - ctx.measureText(label).width / 2, TOP - 3, w, h);
    }
    // Faults: hatched bands over every strip.
    for (const f of D.faults) {
      const a = Math.max(span[0], f.start_s), b = Math.min(span[1], f.end_s === null ? T1 : f.end_s);
      if (b < a) continue;
      const x0 = geom.x(a), x1 = Math.max(x0 + 2, geom.x(b));
      ctx.fillStyle = "rgba(192,57,43,0.10)"; ctx.fillRect(x0, TOP, x1 - x0, bottom - TOP);
      ctx.strokeStyle = "rgba(192,57,43,0.35)"; ctx.lineWidth = 1;
      for (let x = x0 - (bottom - TOP); x < x1; x += 8) {
        ctx.beginPath(); ctx.moveTo(Math.max(x, x0), TOP + Math.max(0, x0 - x));
        ctx.lineTo(Math.min(x + (bottom - TOP), x1), TOP + Math.min(bottom - TOP, x1 - x)); ctx.stroke();
      }
      ctx.strokeStyle = FAULT_COLOUR; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.moveTo(x0, TOP); ctx.lineTo(x0, bottom); ctx.stroke();
    }
    const px = w - LEFT - RIGHT;
    strips.forEach((st, k) => {
      const y0 = TOP + k * geom.sh + 2, y1 = y0 + geom.sh - 4;
      let lo = Infinity, hi = -Infinity;
      const tr = (x) => (st.kind === "sym" ? sym(x) : st.kind === "log" ? lg(x) : x);
      if (st.fixed) { [lo, hi] = st.fixed; }
      else {
        for (const [, f, keep] of st.series) for (let i = i0; i <= i1; i++) {
          if (keep && !keep(i)) continue;
          const val = f(i);
          if (!Number.isFinite(val)) continue;
          const y = tr(val);
          if (y < lo) lo = y; if (y > hi) hi = y;
        }
        if (st.limit) { lo = Math.min(lo, -st.limit); hi = Math.max(hi, st.limit); }
        if (st.kind === "sym") { lo = Math.min(lo, 0); hi = Math.max(hi, 0); }
      }
      if (!(hi > lo)) { lo -= 1; hi += 1; }
      const Y = (y) => y1 - (y - lo) / (hi - lo) * (y1 - y0);
      st.Y = Y; st.y0 = y0; st.y1 = y1; st.tr = tr;
      ctx.strokeStyle = "#b9c0cc"; ctx.lineWidth = 1; ctx.strokeRect(LEFT, y0, px, y1 - y0);
      // Thresholds: the sequencer's settle threshold and the hand-over, dashed.
      const marks = (st.lines || []).concat(st.limit ? [st.limit] : []);
      ctx.setLineDash([6, 4]); ctx.lineWidth = 1;
      for (const m of marks) for (const sgn of st.kind === "log" ? [1] : [1, -1]) {
        const y = Y(tr(sgn * m));
        if (y < y0 || y > y1) continue;
        ctx.strokeStyle = m === settle ? "#2e7d32" : "#8d6e00";
        ctx.beginPath(); ctx.moveTo(LEFT, y); ctx.lineTo(LEFT + px, y); ctx.stroke();
      }
      ctx.setLineDash([]);
      // Strip name and ticks.
      ctx.fillStyle = "#1d2330"; ctx.font = font(11, "bold");
      fillTextInside(ctx, `${st.name}`, 2, y0 + 11, LEFT - 40, h);
      ctx.font = font(11); ctx.fillStyle = "#3a4354";
      for (const [y, label] of ticks(st, lo, hi, (y1 - y0) / (hi - lo))) {
        const yy = Y(y);
        if (yy < y0 + 5 || yy > y1 - 4) continue;  // a label must stay inside its strip
        ctx.strokeStyle = "#6b7385"; ctx.beginPath(); ctx.moveTo(LEFT - 4, yy); ctx.lineTo(LEFT, yy); ctx.stroke();
        ctx.strokeStyle = "#e3e7ee"; ctx.beginPath(); ctx.moveTo(LEFT, yy); ctx.lineTo(LEFT + px, yy); ctx.stroke();
        const tw = ctx.measureText(label).width;
        fillTextInside(ctx, label, LEFT - 6 - tw, yy + 4, w, h);
      }
      // Each series as a min/max band per pixel column, drawn only where it applies.
      for (const [, f, keep, colour, dash] of st.series) {
        ctx.strokeStyle = colour; ctx.lineWidth = 1.2; ctx.setLineDash(dash || []); ctx.beginPath();
        let col = -1, mn = 0, mx = 0, open = false;
        const flush = () => { if (col >= 0 && open) { ctx.moveTo(LEFT + col + 0.5, Y(mn)); ctx.lineTo(LEFT + col + 0.5, Y(mx) - 0.8); } };
        for (let i = i0; i <= i1; i++) {
          const c = Math.floor(geom.x(T_MS[i] / 1000) - LEFT);
          if (c !== col) { flush(); col = c; open = false; }
          if (keep && !keep(i)) continue;
          const val = f(i);
          if (!Number.isFinite(val)) continue;
          const y = Math.max(lo, Math.min(hi, tr(val)));
          if (!open) { mn = y; mx = y; open = true; } else { if (y < mn) mn = y; if (y > mx) mx = y; }
        }
        flush(); ctx.stroke(); ctx.setLineDash([]);
      }
    });
    // Time axis.
    ctx.strokeStyle = "#6b7385"; ctx.fillStyle = "#3a4354"; ctx.font = font(11);
    const step = niceStep(span[1] - span[0], px);
    for (let t = Math.ceil(span[0] / step) * step; t <= span[1] + 1e-9; t += step) {
      const x = geom.x(t);
      ctx.beginPath(); ctx.moveTo(x, bottom); ctx.lineTo(x, bottom + 4); ctx.stroke();
      const label = `${t.toFixed(0)}`;
      fillTextInside(ctx, label, x - ctx.measureText(label).width / 2, bottom + 16, w, h);
    }
    fillTextInside(ctx, "mission time [s]", 2, bottom + 16, LEFT - 6, h);
    // Warnings and the abort, marked above the strips.
    for (const wn of D.warnings) {
      if (wn.t_s < span[0] || wn.t_s > span[1]) continue;
      ctx.fillStyle = "#8d5a00"; ctx.font = font(12, "bold");
      fillTextInside(ctx, "\u26a0", geom.x(wn.t_s) - 6, TOP - 2, w, h);
    }
    if (D.ending && D.ending.status === "aborted" && D.ending.t_s >= span[0] && D.ending.t_s <= span[1] + 1e-9) {
      const x = geom.x(D.ending.t_s);
      ctx.strokeStyle = FAULT_COLOUR; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(x, TOP); ctx.lineTo(x, bottom); ctx.stroke();
    }
    bgKey = key;
    return bg;
  }

  function setZoom(on, t) {
    zoom = !!on;
    span = [T0, T1];
    if (zoom) {
      const rec = D.timeline.filter((r) => r.start_s <= t + 1e-9).pop();
      if (rec && rec.end_s > rec.start_s) span = [rec.start_s, rec.end_s];
    }
  }

  function draw(s, t) {
    if (zoom) setZoom(true, t);
    else if (span[0] !== T0 || span[1] !== T1) span = [T0, T1];
    const { ctx, w, h } = fitCanvas(canvas);
    ctx.drawImage(render(w, h), 0, 0, w, h);
    const x = geom.x(t);
    ctx.strokeStyle = "#c2185b"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(x, TOP); ctx.lineTo(x, h - BOTTOM); ctx.stroke();
    canvas.setAttribute("aria-label", `Traces from ${span[0].toFixed(0)} to ${span[1].toFixed(0)} s `
      + `at ${t.toFixed(1)} s: true error to the target ${fmtSep(s.trueErr)}`
      + (s.cpuPointing === null ? "" : `, CPU 22's ${fmtSep(s.cpuPointing)}`)
      + `; counters 14, 16, 18 at ${s.counters.map((c) => (c * pw).toFixed(3)).join(", ")} deg.`);
  }

  function timeAt(clientX) {
    const r = canvas.getBoundingClientRect();
    if (!geom) return null;
    return Math.max(T0, Math.min(T1, geom.t(clientX - r.left)));
  }

  let dragging = false;
  canvas.addEventListener("mousedown", (e) => { dragging = true; const t = timeAt(e.clientX); if (t !== null) APP.seek(t); });
  window.addEventListener("mouseup", () => { dragging = false; });
  canvas.addEventListener("mousemove", (e) => { if (dragging) { const t = timeAt(e.clientX); if (t !== null) APP.seek(t); } });
  const legend = strips.map((st) => ({ name: st.name, series: st.series.map((x) => [x[0], x[3], !!x[4], x[5]]) }));
  return { draw: draw, setZoom: setZoom, isZoomed: () => zoom, span: () => span.slice(), legend: legend };
})();
