// skymap.js: RA/Dec map with the Sun, catalog stars, the Moon and the planets, targets and the
// tracker's slit footprint.
const SKY = (function () {
  const canvas = document.getElementById("sky");
  let bg = null, bgKey = "";
  // +x (instrument, sun sensor) and +z (tracker boresight) of every row, as RA/Dec.
  const XRD = [], ZRD = [];
  function extend(i0) {
    for (let i = i0; i < N; i++) {
      const c = dcm([cont("q_w", i), cont("q_x", i), cont("q_y", i), cont("q_z", i)]);
      const x = radec(c[0]), z = radec(c[2]);
      XRD[2 * i] = x[0]; XRD[2 * i + 1] = x[1]; ZRD[2 * i] = z[0]; ZRD[2 * i + 1] = z[1];
    }
  }
  extend(0);
  ON_ROWS.push(extend);
  ON_JOURNAL.push(() => { bg = null; });  // the window's stars may have changed
  const SLIT = slitOutlineBody(3);
  const PAD = 30, BOTTOM = 16;

  function xy(ra, dec, w, h) {
    return [PAD + (1 - ra / 360) * (w - PAD), (90 - dec) / 180 * (h - BOTTOM)];
  }

  function background(w, h) {
    const key = `${w}x${h}`;
    if (bg && bgKey === key) return bg;
    const off = offscreenCanvas(w, h), ctx = off.ctx;
    bg = off.canvas;
    ctx.fillStyle = "#0d1630"; ctx.fillRect(0, 0, w, h);
    ctx.strokeStyle = "#26345a"; ctx.lineWidth = 1; ctx.fillStyle = "#aab6d6";
    ctx.font = font(11);
    const raStep = w - PAD > 360 ? 30 : 60;
    for (let ra = 0; ra <= 360; ra += 30) {
      const [x] = xy(ra, 0, w, h);
      ctx.beginPath(); ctx.moveTo(x, 0); ctx.lineTo(x, h - BOTTOM); ctx.stroke();
      if (ra < 360 && ra % raStep === 0) fillTextInside(ctx, `${ra / 15}h`, x - 22, h - 3, w, h);
    }
    for (let dec = -60; dec <= 60; dec += 30) {
      const [, y] = xy(0, dec, w, h);
      ctx.beginPath(); ctx.moveTo(PAD, y); ctx.lineTo(w, y); ctx.stroke();
      fillTextInside(ctx, `${dec > 0 ? "+" : ""}${dec}\u00b0`, 1, y + 4, w, h);
    }
    gridBoxes = [];
    for (let dec = -60; dec <= 60; dec += 30) {  // the Dec labels' boxes, kept free of labels
      const [, y] = xy(0, dec, w, h);
      ctx.font = font(11);
      gridBoxes.push([0, y - 10, PAD, y + 6]);
    }
    for (const st of D.sky.stars) {
      const [x, y] = xy(st.ra, st.dec, w, h);
      const r = Math.max(0.8, 2.6 - 0.55 * st.mag);
      ctx.fillStyle = "#e8ecff"; ctx.beginPath(); ctx.arc(x, y, r, 0, 7); ctx.fill();
      if (st.win) {
        ctx.strokeStyle = "#b48cff"; ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.arc(x, y, r + 3.5, 0, 7); ctx.stroke();
      }
    }
    bgKey = key;
    return bg;
  }
  let gridBoxes = [];

  // The catalog's names (stars in the tracker's window, and the brightest on a wide map):
  // written with the drawing's other labels, after them, where there is room.
  function starNames(L, w, h) {
    for (const st of D.sky.stars) {
      if (!st.win && !(st.mag < 0.1 && w > 380)) continue;
      const [x, y] = xy(st.ra, st.dec, w, h);
      const r = Math.max(0.8, 2.6 - 0.55 * st.mag);
      L.want(st.name, x, y, x + r + (st.win ? 5 : 2), y + 4, { font: font(11),
        colour: st.win ? "#d5c2ff" : "#aab6d6", priority: st.win ? 6 : 7, h: h - BOTTOM });
    }
  }

  function polygon(ctx, pts, w, h, fill, stroke) {
    // Unwrap in RA so that a footprint across 0h/24h stays whole, then draw it twice.
    const p = pts.map((v) => { const [ra, dec] = radec(v); return xy(ra, dec, w, h); });
    const span = w - PAD;
    for (let k = 1; k < p.length; k++) {
      while (p[k][0] - p[k - 1][0] > span / 2) p[k][0] -= span;
      while (p[k - 1][0] - p[k][0] > span / 2) p[k][0] += span;
    }
    for (const shift of [0, -span, span]) {
      ctx.beginPath();
      p.forEach((q, k) => (k ? ctx.lineTo(q[0] + shift, q[1]) : ctx.moveTo(q[0] + shift, q[1])));
      ctx.closePath();
      if (fill) { ctx.fillStyle = fill; ctx.fill(); }
      if (stroke) { ctx.strokeStyle = stroke; ctx.stroke(); }
    }
  }

  function trail(ctx, rd, i0, i1, w, h, colour, width) {
    ctx.strokeStyle = colour; ctx.lineWidth = width; ctx.beginPath();
    let prev = null;
    const step = Math.max(1, Math.floor((i1 - i0) / 1500));
    for (let i = i0; i <= i1; i += step) {
      const p = xy(rd[2 * i], rd[2 * i + 1], w, h);
      if (!prev || Math.abs(p[0] - prev[0]) > (w - PAD) / 2) ctx.moveTo(p[0], p[1]);
      else ctx.lineTo(p[0], p[1]);
      prev = p;
    }
    ctx.stroke();
  }

  let L = null;  // the drawing's labels (labelLayer)
  function marker(ctx, v, w, h, colour, label, r, fontSpec, prio) {
    const [ra, dec] = radec(v);
    const [x, y] = xy(ra, dec, w, h);
    ctx.fillStyle = colour; ctx.strokeStyle = colour; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(x, y, r, 0, 7);
    if (label === "Sun") ctx.fill(); else ctx.stroke();
    if (label !== "Sun") {
      ctx.beginPath(); ctx.moveTo(x - r - 4, y); ctx.lineTo(x + r + 4, y);
      ctx.moveTo(x, y - r - 4); ctx.lineTo(x, y + r + 4); ctx.stroke();
    }
    ctx.font = fontSpec || font(12, "bold");
    // Near the right edge the label goes to the left of the marker.
    const room = ctx.measureText(label).width;
    L.want(label, x, y, x + r + 4 + room > w ? x - r - 4 - room : x + r + 4, y - r,
      { font: fontSpec || font(12, "bold"), colour: colour, priority: prio === undefined ? 2 : prio,
        alpha: ctx.globalAlpha, h: h - BOTTOM });
  }

  function draw(s, t, modeStartRow) {
    const { ctx, w, h } = fitCanvas(canvas);
    ctx.drawImage(background(w, h), 0, 0, w, h);
    L = labelLayer(ctx, w, h);
    for (const b of gridBoxes) L.reserve(b);
    // The slit's swath since the mode began, then its footprint now.
    const i0 = modeStartRow, i1 = s.i;
    const step = Math.max(1, Math.ceil((i1 - i0) / 160));
    for (let i = i0; i < i1; i += step) {
      const c = dcm([cont("q_w", i), cont("q_x", i), cont("q_y", i), cont("q_z", i)]);
      polygon(ctx, SLIT.map((b) => toInertial(c, b)), w, h, "rgba(150,110,255,0.07)", null);
    }
    trail(ctx, ZRD, 0, i1, w, h, "rgba(180,140,255,0.55)", 1);
    trail(ctx, XRD, 0, i1, w, h, "rgba(120,200,255,0.7)", 1.2);
    const c = dcm(s.q);
    polygon(ctx, SLIT.map((b) => toInertial(c, b)), w, h,
      s.starPresent ? "rgba(180,140,255,0.40)" : "rgba(180,140,255,0.22)", "#c9b0ff");
    marker(ctx, sunAt(t), w, h, "#ffd23f", "Sun", 6, undefined, 1);
    // Every target: the one being flown bold, the others faint.
    TARGETS.forEach((tgt, k) => {
      if (k === s.target) return;
      ctx.globalAlpha = 0.45;
      marker(ctx, tgt.vec, w, h, "#ff9d92", `${k + 1} ${tgt.name}`, 3.5, font(11), 4);
      ctx.globalAlpha = 1;
    });
    const cur = TARGETS[s.target];
    marker(ctx, cur.vec, w, h, "#ff6b5b", TARGETS.length > 1
      ? `target ${s.target + 1}/${TARGETS.length} ${cur.name}` : `target ${cur.name}`, 5, undefined, 0);
    // The Moon and the planets: orange diamonds, ringed where the tracker can lock them.
    for (const b of bodiesAt(t)) {
      const [bx, by] = xy(b.ra_deg, b.dec_deg, w, h);
      const r = Math.max(2.5, Math.min(6, 3 - 0.4 * b.magnitude));
      ctx.fillStyle = "#ff9f1c"; ctx.beginPath();
      ctx.moveTo(bx, by - r); ctx.lineTo(bx + r, by); ctx.lineTo(bx, by + r); ctx.lineTo(bx - r, by);
      ctx.closePath(); ctx.fill();
      if (b.in_window && b.flown) {
        ctx.strokeStyle = "#b48cff"; ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.arc(bx, by, r + 3.5, 0, 7); ctx.stroke();
      }
      L.want(b.name, bx, by, bx + r + 3, by + 4, { font: font(11), colour: "#ffc27a",
        priority: b.in_window && b.flown ? 5 : 7, h: h - BOTTOM });
    }
    const x = radec(c[0]), [px, py] = xy(x[0], x[1], w, h);
    ctx.fillStyle = "#7fd0ff"; ctx.beginPath(); ctx.arc(px, py, 3.5, 0, 7); ctx.fill();
    L.want("+x", px, py, px + 5, py + 13, { font: font(12, "bold"), colour: "#7fd0ff", priority: 1,
      h: h - BOTTOM });
    // The star in the slit (the journal's), ringed in white.
    const inSlit = starInSlit(t), sv = inSlit ? starVec(inSlit, t) : null;
    if (sv) {
      const [ra, dec] = radec(sv), [sx, sy] = xy(ra, dec, w, h);
      ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 2;
      ctx.beginPath(); ctx.arc(sx, sy, 8, 0, 7); ctx.stroke();
    }
    starNames(L, w, h);
    canvas.dataset.labelsDropped = L.flush();
    canvas.setAttribute("aria-label", `Sky map at ${t.toFixed(1)} s: +x at RA ${x[0].toFixed(1)}\u00b0, `
      + `Dec ${x[1].toFixed(1)}\u00b0; target ${cur.name}; slit ${inSlit ? "on " + inSlit : "empty"}.`);
  }

  return { draw: draw };
})();
