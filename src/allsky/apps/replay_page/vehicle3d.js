// vehicle3d.js: the vehicle, its axes, the Sun, the tracked star, the target flown and the slit.
const VEHICLE = (function () {
  const canvas = document.getElementById("vehicle");
  // View basis, fixed for the mission: x toward the Sun at the start, z toward the first
  // target's part across it.
  const sun0 = sunAt(0), tgt = TARGETS[0].vec;
  let e1 = sun0, e3 = norm(cross(sun0, cross(tgt, sun0)));
  if (!isFinite(e3[0])) e3 = [0, 0, 1];
  const e2 = cross(e3, e1);
  let az = -35 * RAD, el = 22 * RAD;
  const starVec = (function () {
    const name = D.sky.locked || D.sky.reference;
    const st = D.sky.stars.find((x) => x.name === name);
    return st ? unitFromRadec(st.ra, st.dec) : null;
  })();
  // A box longer along x (the instrument axis), as the vehicle drawing shows it.
  const BOX = [1.0, 0.45, 0.45];

  function project(v, w, h) {
    // inertial -> view frame (e1, e2, e3), then turn by azimuth and elevation.
    const a = dot(v, e1), b = dot(v, e2), c = dot(v, e3);
    const x1 = a * Math.cos(az) - b * Math.sin(az), y1 = a * Math.sin(az) + b * Math.cos(az);
    const depth = y1 * Math.cos(el) - c * Math.sin(el);
    const up = y1 * Math.sin(el) + c * Math.cos(el);
    const sc = Math.min(w, h) * 0.34;
    return [w / 2 + sc * x1, h / 2 - sc * up, depth];
  }

  function arrow(ctx, p, q, colour, width, label) {
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
    const ang = Math.atan2(q[1] - p[1], q[0] - p[0]);
    ctx.beginPath(); ctx.moveTo(q[0], q[1]);
    ctx.lineTo(q[0] - 9 * Math.cos(ang - 0.4), q[1] - 9 * Math.sin(ang - 0.4));
    ctx.lineTo(q[0] - 9 * Math.cos(ang + 0.4), q[1] - 9 * Math.sin(ang + 0.4));
    ctx.fill();
    if (label) { ctx.font = "11px sans-serif"; ctx.fillText(label, q[0] + 4, q[1] - 4); }
  }

  function draw(s, t) {
    const { ctx, w, h } = fitCanvas(canvas);
    ctx.clearRect(0, 0, w, h);
    const c = dcm(s.q);
    const P = (v, k) => project([v[0] * k, v[1] * k, v[2] * k], w, h);
    const o = P([0, 0, 0], 1);
    // Inertial directions: Sun, tracked star, target (long thin rays).
    const sun = sunAt(t);
    const target = TARGETS[s.target];
    const rays = [[sun, "#e6a800", "Sun"], [target.vec, "#c0392b", `target ${target.name}`]];
    if (starVec) rays.push([starVec, "#6c3fb5", D.sky.locked || D.sky.reference]);
    for (const [v, col, name] of rays) {
      const q = P(v, 1.3);
      ctx.setLineDash([5, 4]); ctx.strokeStyle = col; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.moveTo(o[0], o[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = col; ctx.beginPath(); ctx.arc(q[0], q[1], name === "Sun" ? 8 : 5, 0, 7);
      ctx.fill(); ctx.font = "11px sans-serif"; ctx.fillText(name, q[0] + 7, q[1] + 4);
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
    // Jets: a flame at the end of the box about each axis whose valve is open.
    const jetAt = [[0, 0.5 * BOX[1], 0], [0.5 * BOX[0], 0, 0], [0.5 * BOX[0], 0, 0]];
    s.valves.forEach((v, a) => {
      if (!v) return;
      const p = P(toInertial(c, jetAt[a]), 1);
      ctx.fillStyle = "#ff8c1a"; ctx.beginPath(); ctx.arc(p[0], p[1], 7, 0, 7); ctx.fill();
      ctx.fillStyle = "#7a2"; ctx.font = "bold 10px sans-serif";
      ctx.fillText(`${"rpy"[a]}${v > 0 ? "+" : "\u2212"}`, p[0] + 8, p[1] + 3);
    });
    // Body axes.
    const names = ["+x roll, sun sensor 104", "+y pitch", "+z yaw, tracker 105"];
    for (let a = 0; a < 3; a++) {
      const b = [0, 0, 0]; b[a] = 1;
      arrow(ctx, o, P(toInertial(c, b), a === 0 ? 1.2 : 0.9), AXIS_COLOURS[a], 2.5, names[a]);
    }
    ctx.fillStyle = "#333"; ctx.font = "11px sans-serif";
    const sep = Math.acos(Math.max(-1, Math.min(1, dot(toInertial(c, [1, 0, 0]), target.vec))))
      / RAD;
    const sunSep = Math.acos(Math.max(-1, Math.min(1, dot(toInertial(c, [1, 0, 0]), sun)))) / RAD;
    ctx.fillText(`+x to Sun ${sunSep.toFixed(2)}\u00b0, to target ${TARGETS.length > 1
      ? `${s.target + 1} (${target.name}) ` : ""}${sep.toFixed(2)}\u00b0`, 6, h - 6);
  }

  // Drag to turn the view.
  let drag = null;
  canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY, az, el]; });
  window.addEventListener("mouseup", () => { drag = null; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    az = drag[2] + (e.clientX - drag[0]) * 0.01;
    el = Math.max(-1.5, Math.min(1.5, drag[3] + (e.clientY - drag[1]) * 0.01));
    APP.redraw();
  });
  return { draw: draw };
})();
