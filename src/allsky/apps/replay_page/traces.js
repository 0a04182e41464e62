// traces.js: attitude errors per axis and the counters against time, modes shaded, a cursor.
const TRACES = (function () {
  const canvas = document.getElementById("traces");
  const LEFT = 92, RIGHT = 190, TOP = 12, BOTTOM = 14;
  const LIN = 10;  // arcsec: linear inside, logarithmic beyond (as the PNG figures)
  const sym = (v) => Math.sign(v) * Math.log10(1 + Math.abs(v) / LIN);
  // Where each signal applies, per row, computed once.
  const flags = (f) => { const a = new Uint8Array(N); for (let i = 0; i < N; i++) a[i] = f(i) ? 1 : 0; return a; };
  const SUN_ON = flags((i) => runValue(C.runs.sun_present, i) > 0.5);
  const STAR_ON = flags((i) => runValue(C.runs.star_present, i) > 0.5);
  const CPU_ON = flags((i) => CPU_MODES.indexOf(modeName(runValue(C.runs.mode, i))) >= 0);
  const sunOn = (i) => SUN_ON[i] === 1, starOn = (i) => STAR_ON[i] === 1, cpuOn = (i) => CPU_ON[i] === 1;
  const SUN = "#d62728", TRK = "#9467bd", CPU = "#111";
  const pw = D.config.pulse_weight_arcsec / 3600;  // degrees per pulse
  const strips = [
    { name: "roll error [\u2033]", sym: true, series: [["tracker yaw 105", "tracker_yaw", starOn, TRK],
      ["CPU 22 roll", "error_roll", cpuOn, CPU]] },
    { name: "pitch error [\u2033]", sym: true, series: [["sun pitch 104", "sun_pitch", sunOn, SUN],
      ["tracker pitch 105", "tracker_pitch", starOn, TRK], ["CPU 22 pitch", "error_pitch", cpuOn, CPU]] },
    { name: "yaw error [\u2033]", sym: true, series: [["sun yaw 104", "sun_yaw", sunOn, SUN],
      ["CPU 22 yaw", "error_yaw", cpuOn, CPU]] },
    { name: "counters [\u00b0]", sym: false, series: [["14 roll", "counter14", null, AXIS_COLOURS[0]],
      ["16 pitch", "counter16", null, AXIS_COLOURS[1]], ["18 yaw", "counter18", null, AXIS_COLOURS[2]]] },
  ];
  let bg = null, bgKey = "", geom = null;

  function value(name, i) { return EXACT[name] ? EXACT[name][i] * pw : cont(name, i); }

  function layout(w, h) {
    const sh = (h - TOP - BOTTOM) / strips.length;
    return { w: w, h: h, sh: sh, x: (t) => LEFT + (t - T0) / Math.max(T1 - T0, 1e-9) * (w - LEFT - RIGHT),
      t: (x) => T0 + (x - LEFT) / (w - LEFT - RIGHT) * (T1 - T0) };
  }

  function render(w, h) {
    const key = `${w}x${h}`;
    if (bg && bgKey === key) return bg;
    geom = layout(w, h);
    const off = offscreenCanvas(w, h), ctx = off.ctx;
    bg = off.canvas;
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, w, h);
    for (const m of D.timeline) {
      const x0 = geom.x(m.start_s), x1 = geom.x(m.end_s);
      ctx.fillStyle = modeColour(m.mode); ctx.globalAlpha = 0.13;
      ctx.fillRect(x0, TOP, x1 - x0, h - TOP - BOTTOM);
      ctx.globalAlpha = 1; ctx.font = "bold 10px sans-serif";
      // A mode of no duration (the hand-over to the next target) is named in the event log.
      if (x1 - x0 >= 1) ctx.fillText(m.mode, (x0 + x1) / 2 - 6, TOP - 2);
    }
    const px = w - LEFT - RIGHT;
    strips.forEach((st, k) => {
      const y0 = TOP + k * geom.sh, y1 = y0 + geom.sh - 3;
      let lo = Infinity, hi = -Infinity;
      for (const [, name, keep] of st.series) for (let i = 0; i < N; i++) {
        if (keep && !keep(i)) continue;
        const v = st.sym ? sym(value(name, i)) : value(name, i);
        if (v < lo) lo = v; if (v > hi) hi = v;
      }
      if (!(hi > lo)) { lo -= 1; hi += 1; }
      const Y = (v) => y1 - (v - lo) / (hi - lo) * (y1 - y0 - 2);
      st.Y = Y; st.y0 = y0; st.y1 = y1;
      ctx.strokeStyle = "#ccd"; ctx.lineWidth = 1; ctx.strokeRect(LEFT, y0, px, y1 - y0);
      if (st.sym && lo < 0 && hi > 0) {
        ctx.strokeStyle = "#aab"; ctx.beginPath(); ctx.moveTo(LEFT, Y(0)); ctx.lineTo(LEFT + px, Y(0)); ctx.stroke();
      }
      ctx.fillStyle = "#333"; ctx.font = "10px sans-serif";
      ctx.fillText(st.name, 2, y0 + 10);
      const tick = (v) => st.sym ? `${v < 0 ? "\u2212" : ""}${Math.round(LIN * (Math.pow(10, Math.abs(v)) - 1))}` : v.toFixed(0);
      ctx.fillStyle = "#778"; ctx.fillText(tick(hi), 2, y0 + 21); ctx.fillText(tick(lo), 2, y1);
      // Each series as a min/max band per pixel column, drawn only where it applies.
      for (const [, name, keep, colour] of st.series) {
        ctx.strokeStyle = colour; ctx.lineWidth = 1; ctx.beginPath();
        let col = -1, mn = 0, mx = 0, open = false;
        const flush = () => { if (col >= 0 && open) { ctx.moveTo(LEFT + col + 0.5, Y(mn)); ctx.lineTo(LEFT + col + 0.5, Y(mx) - 0.5); } };
        for (let i = 0; i < N; i++) {
          const c = Math.floor(geom.x(T_MS[i] / 1000) - LEFT);
          if (c !== col) { flush(); col = c; open = false; }
          if (keep && !keep(i)) continue;
          const v = st.sym ? sym(value(name, i)) : value(name, i);
          if (!open) { mn = v; mx = v; open = true; } else { if (v < mn) mn = v; if (v > mx) mx = v; }
        }
        flush(); ctx.stroke();
      }
    });
    ctx.fillStyle = "#555"; ctx.font = "10px sans-serif";
    ctx.fillText(`mission time ${T0.toFixed(0)}-${T1.toFixed(0)} s; errors: linear within \u00b1${LIN}\u2033, logarithmic beyond`, LEFT, h - 3);
    bgKey = key;
    return bg;
  }

  function draw(s, t) {
    const { ctx, w, h } = fitCanvas(canvas);
    ctx.drawImage(render(w, h), 0, 0, w, h);
    const x = geom.x(t);
    ctx.strokeStyle = "#e0218a"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(x, TOP); ctx.lineTo(x, h - BOTTOM); ctx.stroke();
    ctx.font = "10px monospace";
    strips.forEach((st) => {
      let y = st.y0 + 10;
      for (const [label, name, keep, colour] of st.series) {
        const on = !keep || keep(s.i);
        ctx.fillStyle = on ? colour : "#bbb";
        const v = value(name, s.i);
        const txt = on ? (st.sym ? `${fmt(v, 1)}\u2033` : `${fmt(v, 3)}\u00b0`) : "\u2014";
        ctx.fillText(`${label.padEnd(17).slice(0, 17)} ${txt}`, w - RIGHT + 4, y);
        y += 11;
      }
    });
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
  return { draw: draw };
})();
