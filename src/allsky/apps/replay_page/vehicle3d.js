// vehicle3d.js: the vehicle, its axes, the Sun, the star in the slit, the target flown and
// the slit; jets firing, or on a wheel vehicle the wheels' momentum.
const VEHICLE = (function () {
  const canvas = document.getElementById("vehicle");
  // View basis, fixed for the mission: x toward the Sun at the start, z toward the first
  // target's part across it.
  const sun0 = sunAt(0), tgt = TARGETS[0].vec;
  let e1 = sun0, e3 = norm(cross(sun0, cross(tgt, sun0)));
  if (!isFinite(e3[0])) e3 = [0, 0, 1];
  const e2 = cross(e3, e1);
  let az = -35 * RAD, el = 22 * RAD;
  const REFERENCE = D.sky.reference, REF_VEC = starVec(REFERENCE);
  const WHEELS = D.vehicle.kind === "wheels";
  // A box longer along x (the instrument axis), as the vehicle drawing shows it.
  const BOX = [1.0, 0.45, 0.45];
  let readout = "";

  function project(v, w, h) {
    // inertial -> view frame (e1, e2, e3), then turn by azimuth and elevation.
    const a = dot(v, e1), b = dot(v, e2), c = dot(v, e3);
    const x1 = a * Math.cos(az) - b * Math.sin(az), y1 = a * Math.sin(az) + b * Math.cos(az);
    const depth = y1 * Math.cos(el) - c * Math.sin(el);
    const up = y1 * Math.sin(el) + c * Math.cos(el);
    const sc = Math.min(w * 0.6, h - 40) * 0.42;
    return [w / 2 + sc * x1, (h - 34) / 2 + 4 - sc * up, depth];
  }

  function arrow(ctx, p, q, colour, width, label, w, h, prio) {
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
    const ang = Math.atan2(q[1] - p[1], q[0] - p[0]);
    ctx.beginPath(); ctx.moveTo(q[0], q[1]);
    ctx.lineTo(q[0] - 9 * Math.cos(ang - 0.4), q[1] - 9 * Math.sin(ang - 0.4));
    ctx.lineTo(q[0] - 9 * Math.cos(ang + 0.4), q[1] - 9 * Math.sin(ang + 0.4));
    ctx.fill();
    if (label) L.want(label, q[0], q[1], q[0] + 4, q[1] - 4, { font: font(12, "600"), colour: colour,
      priority: prio === undefined ? 3 : prio, h: h - 34 });
  }
  let L = null;  // the drawing's labels (labelLayer)

  function draw(s, t) {
    const { ctx, w, h } = fitCanvas(canvas);
    ctx.clearRect(0, 0, w, h);
    L = labelLayer(ctx, w, h);
    const c = dcm(s.q);
    const P = (v, k) => project([v[0] * k, v[1] * k, v[2] * k], w, h);
    const o = P([0, 0, 0], 1);
    // Inertial directions: Sun, the star in the slit (else the reference star), the target.
    const sun = sunAt(t);
    const target = TARGETS[s.target];
    const inSlit = starInSlit(t);
    const slitVec = inSlit ? starVec(inSlit, t) : null;
    // [direction, colour, label, radius, label priority (lower: placed first)]
    const rays = [[sun, "#b07c00", "Sun", 8, 1], [target.vec, "#c0392b", `target ${target.name}`, 5, 0]];
    if (slitVec) rays.push([slitVec, "#6c3fb5", `${inSlit} (in the slit)`, 5, 1]);
    if (REF_VEC && inSlit !== REFERENCE) rays.push([REF_VEC, "#8b7aa8", `${REFERENCE} (reference)`, 4, 4]);
    for (const [v, col, name, r, prio] of rays) {
      const q = P(v, 1.3);
      ctx.setLineDash([5, 4]); ctx.strokeStyle = col; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = col; ctx.beginPath(); ctx.arc(q[0], q[1], r, 0, 7);
      ctx.fill();
      L.want(name, q[0], q[1], q[0] + 7, q[1] + 4, { colour: col, priority: prio, h: h - 34 });
    }
    // The tracker's slit field about +z, as a translucent pyramid.
    const slit = slitOutlineBody(2).map((b) => P(toInertial(c, b), 1.5));
    ctx.fillStyle = s.starPresent ? "rgba(108,63,181,0.22)" : "rgba(108,63,181,0.10)";
    ctx.strokeStyle = "rgba(108,63,181,0.6)"; ctx.lineWidth = 1;
    ctx.beginPath(); slit.forEach((p, k) => (k ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1])));
    ctx.closePath(); ctx.fill(); ctx.stroke();
    for (const k of [0, 3, 6, 9]) {
      ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(slit[k][0], slit[k][1]); ctx.stroke();
    }
    // The vehicle: a box in body axes, faces sorted back to front.
    const corners = [];
    for (const sx of [-1, 1]) for (const sy of [-1, 1]) for (const sz of [-1, 1])
      corners.push(P(toInertial(c, [sx * BOX[0] * 0.5, sy * BOX[1] * 0.5, sz * BOX[2] * 0.5]), 1));
    const faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]];
    faces.map((f) => [f, f.reduce((a, k) => a + corners[k][2], 0)])
      .sort((a, b) => b[1] - a[1]).forEach(([f]) => {
        ctx.beginPath();
        f.forEach((k, j) => (j ? ctx.lineTo(corners[k][0], corners[k][1])
          : ctx.moveTo(corners[k][0], corners[k][1])));
        ctx.closePath(); ctx.fillStyle = "rgba(200,208,222,0.85)"; ctx.fill();
        ctx.strokeStyle = "#556"; ctx.lineWidth = 1; ctx.stroke();
      });
    if (WHEELS) drawWheels(ctx, c, P, s, w, h);
    // Jets: a flame at the end of the box about each axis whose valve is open.
    const jetAt = [[0, 0.5 * BOX[1], 0], [0.5 * BOX[0], 0, 0], [0.5 * BOX[0], 0, 0]];
    s.valves.forEach((v, a) => {
      if (!v) return;
      const p = P(toInertial(c, jetAt[a]), 1);
      ctx.fillStyle = "#ff8c1a"; ctx.beginPath(); ctx.arc(p[0], p[1], 7, 0, 7); ctx.fill();
      L.want(`${"rpy"[a]}${v > 0 ? "+" : "\u2212"}`, p[0], p[1], p[0] + 8, p[1] + 4,
        { font: font(12, "bold"), colour: "#7a3a00", priority: 2, h: h - 34 });
    });
    // Body axes.
    const names = ["+x roll (sun 104)", "+y", "+z yaw (tracker 105)"];
    for (let a = 0; a < 3; a++) {
      const b = [0, 0, 0]; b[a] = 1;
      arrow(ctx, o, P(toInertial(c, b), a === 0 ? 1.2 : 0.9), AXIS_COLOURS[a], 2.5, names[a], w, h,
        a === 1 ? 4 : 2);
    }
    canvas.dataset.labelsDropped = L.flush();
    // Readouts: +x to the Sun and to the target (the truth), exact near zero (atan2).
    const x = toInertial(c, [1, 0, 0]);
    const sunSep = angleBetween(x, sun) * ARCSEC_PER_RAD;
    const tgtName = TARGETS.length > 1 ? `${s.target + 1} (${target.name})` : target.name;
    ctx.fillStyle = "#1d2330"; ctx.font = font(12);
    const line1 = `+x to target ${tgtName}: ${fmtSep(s.trueErr)} (true)`;
    const line2 = `+x to Sun: ${fmtSep(sunSep)} \u00b7 slit: ${inSlit || (s.starPresent ? "a star" : "empty")}`;
    fillTextInside(ctx, line1, 6, h - 20, w, h);
    fillTextInside(ctx, line2, 6, h - 5, w, h);
    readout = line1;
    canvas.setAttribute("data-to-target", fmtSep(s.trueErr));
    canvas.setAttribute("data-to-target-arcsec", s.xToTargetArcsec.toFixed(2));
    canvas.setAttribute("data-star", inSlit || "");
    canvas.setAttribute("aria-label", `Vehicle in 3-D at ${t.toFixed(1)} s: ${line1}; ${line2}.`);
  }

  function drawWheels(ctx, c, P, s, w, h) {
    // The wheels' momentum in body axes: one arrow of the array's total, scaled to the limit.
    const lim = D.vehicle.max_momentum_n_m_s, hv = s.wheelH;
    const mag = Math.hypot(hv[0], hv[1], hv[2]);
    const k = 0.8 * Math.min(1.5, mag / lim);
    if (mag > 1e-9) {
      const tip = P(toInertial(c, [hv[0] / mag * k, hv[1] / mag * k, hv[2] / mag * k]), 1);
      arrow(ctx, P([0, 0, 0], 1), tip, s.unloading ? "#d35400" : "#0b6e4f", 3,
        `wheels ${mag.toFixed(2)} N m s${s.unloading ? ", unloading" : ""}`, w, h, 3);
    }
    // Each wheel as a small disc on its spin axis.
    for (const ax of D.vehicle.axes) {
      const p = P(toInertial(c, [ax[0] * 0.3, ax[1] * 0.3, ax[2] * 0.3]), 1);
      ctx.fillStyle = "#0b6e4f"; ctx.beginPath(); ctx.arc(p[0], p[1], 4, 0, 7); ctx.fill();
    }
  }

  // Drag to turn the view; arrow keys turn it when the view has the focus.
  let drag = null;
  canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY, az, el]; });
  window.addEventListener("mouseup", () => { drag = null; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    az = drag[2] + (e.clientX - drag[0]) * 0.01;
    el = Math.max(-1.5, Math.min(1.5, drag[3] + (e.clientY - drag[1]) * 0.01));
    APP.redraw();
  });
  canvas.addEventListener("keydown", (e) => {
    const turn = { ArrowLeft: [-0.1, 0], ArrowRight: [0.1, 0], ArrowUp: [0, -0.1], ArrowDown: [0, 0.1] }[e.key];
    if (!turn) return;
    e.preventDefault(); e.stopPropagation();
    az += turn[0]; el = Math.max(-1.5, Math.min(1.5, el + turn[1]));
    APP.redraw();
  });
  return { draw: draw, readout: () => readout };
})();
