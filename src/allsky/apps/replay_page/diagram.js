// diagram.js: the block diagram drawn from the layout and wiring tables, with live values,
// the faults acting marked on their blocks, and on a wheel vehicle the wheels.
const DIAGRAM = (function () {
  const G = D.diagram, S = 100;  // user units per diagram unit
  const [X0, X1, Y0, Y1] = G.extent;
  const X = (x) => (x - X0) * S, Y = (y) => (Y1 - y) * S;
  const LIVE = "#1a7f43", DEAD = "#8a93a3", PERM = "#3b4252", OPEN_LABEL = "#a11d1d";
  const F = 26, LINE = 29;  // text size and line pitch [user units]: 11 px at 0.43 px/unit
  const WHEELS = D.vehicle.kind === "wheels";
  const svg = document.getElementById("diagram");
  const texts = {};  // numeral -> [text elements of its value lines]
  const boxEls = {};  // numeral -> {rect, mark, title}
  const lineEls = [];  // {el, head, spec}
  const switchEls = {};  // k -> {blade, label, open:[x,y], closed:[x,y]}
  const selectorEls = {};  // 7/8 -> {arm, pivot, contacts}
  const jetEls = [];
  const titles = [];  // [text, room]: squeezed to fit after the first layout
  let last = {};
  // Every box shows one side: the vehicle strip the truth (the vehicle as it is), every other
  // box the machine's belief (what its sensors say, its counters hold, it computes, commands).
  const SIDE = (n) => (n === "100" ? "truth" : "belief");
  const SIDE_COLOUR = { belief: "#2c4f86", truth: "#b8860b" };
  const SIDE_WORDS = { belief: "belief (what the machine measures, holds or commands)",
    truth: "truth (the vehicle as it really is)" };

  function build() {
    svg.setAttribute("viewBox", `0 0 ${(X1 - X0) * S} ${(Y1 - Y0) * S}`);
    svg.setAttribute("preserveAspectRatio", "xMidYMin meet");
    const defs = svgEl("defs", {}, svg);
    for (const [id, colour] of [["a-live", LIVE], ["a-dead", DEAD], ["a-perm", PERM]]) {
      const m = svgEl("marker", { id: id, viewBox: "0 0 10 10", refX: 9, refY: 5,
        markerWidth: 6, markerHeight: 6, orient: "auto-start-reverse" }, defs);
      svgEl("path", { d: "M0,0 L10,5 L0,10 z", fill: colour }, m);
    }
    const hatch = svgEl("pattern", { id: "fault-hatch", width: 14, height: 14,
      patternUnits: "userSpaceOnUse", patternTransform: "rotate(45)" }, defs);
    svgEl("rect", { width: 14, height: 14, fill: "#fdecea" }, hatch);
    svgEl("line", { x1: 0, y1: 0, x2: 0, y2: 14, stroke: "#f5b7b1", "stroke-width": 6 }, hatch);
    for (const n in G.frames) {
      const [x, y, w, h] = G.frames[n].box;
      svgEl("rect", { x: X(x), y: Y(y + h), width: w * S, height: h * S, rx: 8,
        fill: "#f3f6fb", stroke: "#5577aa", "stroke-dasharray": "8 6", "stroke-width": 2 }, svg);
      const t = svgEl("text", { x: X(x) + 10, y: Y(y + h) + F - 2, "font-size": F,
        fill: "#2c4f86", "font-weight": 600 }, svg);
      t.textContent = `${G.frames[n].label} ${n}`;
    }
    const lineLayer = svgEl("g", {}, svg);
    for (const spec of G.lines) {
      const d = spec.points.map((p, k) => `${k ? "L" : "M"}${X(p[0])},${Y(p[1])}`).join(" ");
      const el = svgEl("path", { d: d, fill: "none", stroke: PERM, "stroke-width": 3,
        "marker-end": "url(#a-perm)" }, lineLayer);
      lineEls.push({ el: el, spec: spec, state: "" });
      if (spec.text) {
        const p = spec.points[0], q = spec.points[1];
        const t = svgEl("text", { x: X((p[0] + q[0]) / 2) + 10, y: Y((p[1] + q[1]) / 2) + 9,
          "font-size": F, fill: "#6b5200" }, svg);
        t.textContent = spec.text;
      }
    }
    for (const n in G.boxes) buildBox(n, G.boxes[n]);
    for (const spec of G.lines) if (spec.switches.length) buildSwitches(spec);
  }

  function squeezeTitles() {
    for (const [el, room] of titles) {
      if (el.getComputedTextLength() > room) {
        el.setAttribute("textLength", room);
        el.setAttribute("lengthAdjust", "spacingAndGlyphs");
      }
    }
  }

  function buildBox(n, b) {
    const [x, y, w, h] = b.box;
    const side = SIDE(n);
    const g = svgEl("g", { "data-box": n, "data-side": side }, svg);
    const title = svgEl("title", {}, g);
    const wheelBox = WHEELS && n === "39";
    title.textContent = `${wheelBox ? D.diagram.plain_wheels : b.plain} (${SIDE_WORDS[side]})`;
    const rect = svgEl("rect", { x: X(x), y: Y(y + h), width: w * S, height: h * S, rx: 6,
      fill: b.shaded ? "#fff7e6" : "#ffffff", stroke: "#2b3040", "stroke-width": 2 }, g);
    // The side of truth and belief the box shows: a stripe down its left edge.
    svgEl("rect", { x: X(x) + 1, y: Y(y + h) + 6, width: 7, height: h * S - 12,
      fill: SIDE_COLOUR[side], class: `side-stripe ${side}` }, g);
    const mark = svgEl("text", { x: X(x) + 4, y: Y(y + h) + F, "font-size": F,
      "font-weight": 700, fill: FAULT_COLOUR, visibility: "hidden" }, g);
    mark.textContent = "\u26a0";
    boxEls[n] = { g: g, rect: rect, mark: mark, fill: rect.getAttribute("fill"), fault: "" };
    const cx = X(x + w / 2), top = Y(y + h);
    if (n === "100") {
      const t = svgEl("text", { x: X(x) + 12, y: top + F + 6, "font-size": F,
        "font-weight": 700 }, g);
      t.textContent = `${b.label} ${b.numerals.join(", ")}`;
      const room = (t.textContent.length + 1) * F * 0.62;
      texts[n] = [svgEl("text", { x: X(x) + 12 + room, y: top + F + 6, "font-size": F,
        "font-family": "DejaVu Sans Mono, monospace" }, g)];
      return;
    }
    const two = G.two_line_titles[n];
    const lines = two || [wheelBox ? "Reaction wheels" : (b.numerals.length === 1
      ? `${b.label} ${n}` : b.label)];
    lines.forEach((text, k) => {
      const t = svgEl("text", { x: cx, y: top + F + k * LINE, "text-anchor": "middle",
        "font-size": F, "font-weight": 700 }, g);
      t.textContent = text;
      titles.push([t, w * S - 12]);
    });
    const first = top + F + lines.length * LINE + 2;
    const count = 4 - lines.length;
    texts[n] = [0, 1, 2].slice(0, count).map((k) => svgEl("text", { x: X(x) + 8,
      y: first + LINE * k, "font-size": F, "font-family": "DejaVu Sans Mono, monospace" }, g));
    if (n === "39" && !WHEELS) {
      for (let a = 0; a < 3; a++) {
        const c = svgEl("circle", { cx: X(x + w) - 18, cy: first + LINE * a - 9, r: 10,
          fill: "#dddddd", stroke: "#555555" }, g);
        jetEls.push(c);
      }
    }
  }

  function buildSwitches(spec) {
    const at = spec.points.length > 2 ? 1 : 0;
    const p = spec.points[at], q = spec.points[at + 1];
    const horizontal = Math.abs(q[1] - p[1]) < 1e-9;
    const sel = spec.switches.filter((k) => SELECTORS.indexOf(k) >= 0);
    if (sel.length) {
      buildSelector(sel[0], X((p[0] + q[0]) / 2), Y(p[1]));
      return;
    }
    const n = spec.switches.length, pitch = 60, width = n * pitch;
    let x0, y0;
    if (horizontal) {
      const dir = q[0] > p[0] ? 1 : -1;
      const start = spec.points.length > 2 ? X(p[0]) + dir * 14 : (X(p[0]) + X(q[0])) / 2 - dir * width / 2;
      x0 = dir > 0 ? start : start - width;
      y0 = Y(p[1]) - 14;
    } else {
      x0 = X(p[0]) - width - 8;
      y0 = (Y(p[1]) + Y(q[1])) / 2 - 6;
    }
    spec.switches.forEach((k, j) => {
      const x = x0 + j * pitch + 8, y = y0;
      const g = svgEl("g", {}, svg);
      const sw = D.diagram.switches[k - 1];
      svgEl("title", {}, g).textContent = `S${k}: ${sw.text}`;
      svgEl("circle", { cx: x, cy: y, r: 4, fill: "#333333" }, g);
      svgEl("circle", { cx: x + 34, cy: y, r: 4, fill: "#333333" }, g);
      const blade = svgEl("line", { x1: x, y1: y, x2: x + 30, y2: y - 16, stroke: DEAD,
        "stroke-width": 5, "stroke-linecap": "round" }, g);
      const label = svgEl("text", { x: x + 17, y: y + F + 2, "text-anchor": "middle",
        "font-size": F, "font-weight": 700, fill: OPEN_LABEL }, g);
      label.textContent = `S${k}`;
      g.setAttribute("data-switch", k);
      switchEls[k] = { g: g, blade: blade, label: label, x: x, y: y, state: null };
    });
  }

  function buildSelector(k, cx, cy) {
    const g = svgEl("g", {}, svg);
    const sw = D.diagram.switches[k - 1];
    svgEl("title", {}, g).textContent = `S7/S8 (moved together): ${sw.text}`;
    const px = cx - 30, contacts = [];
    svgEl("circle", { cx: px, cy: cy, r: 5, fill: "#333333" }, g);
    for (let a = 0; a < 3; a++) {
      const yy = cy - 28 + 28 * a;
      contacts.push([cx + 16, yy]);
      svgEl("circle", { cx: cx + 16, cy: yy, r: 5, fill: AXIS_COLOURS[a] }, g);
      const t = svgEl("text", { x: cx + 26, y: yy + 9, "font-size": F, fill: AXIS_COLOURS[a],
        "font-weight": 700 }, g);
      t.textContent = "rpy"[a];
    }
    const arm = svgEl("line", { x1: px, y1: cy, x2: cx + 16, y2: cy, stroke: "#333333",
      "stroke-width": 5, "stroke-linecap": "round" }, g);
    const label = svgEl("text", { x: cx - 14, y: cy - 36, "text-anchor": "middle",
      "font-size": F, "font-weight": 700, fill: "#333333" }, g);
    label.textContent = `S${k}`;
    g.setAttribute("data-selector", k);
    selectorEls[k] = { g: g, arm: arm, contacts: contacts, state: null };
  }

  function setText(n, k, value) {
    const key = n + ":" + k;
    if (last[key] !== value && texts[n][k]) { texts[n][k].textContent = value; last[key] = value; }
  }

  /** One value line: the numeral in two places, a space, the value right-aligned in w. */
  const line = (num, value, w) => `${num.padEnd(2)} ${String(value).padStart(w || 8)}`;

  function values(s, t) {
    const cfg = D.config;
    const v = {}, per = (n, f, w) => G.boxes[n].numerals.map((num, a) => line(num, f(a), w));
    // Belief: the gyros' outputs (a dead gyro reads zero); the true rates are the vehicle's.
    v["1"] = per("1", (a) => (Number.isNaN(s.gyroDeg[a]) ? "not rec."
      : `${fmtRate(s.gyroDeg[a])}\u00b0/s`));
    const cmd = [s.closed[16] ? "+cmd" : "", "", s.closed[17] ? "+cmd" : ""];
    v["4"] = per("4", (a) => `${s.closed[a + 1] ? "\u2212drift" : "gyro"}${cmd[a]}`, 9);
    v["8"] = per("8", (a) => `${fmtInt(s.pps[a])} p/s`, 9);
    v["14"] = per("14", (a) => fmtInt(s.counters[a]), 9);
    v["13"] = per("13", (a) => `${fmtInt(s.drift[a])}${s.closed[a + 4] ? " \u2190" : "  "}`, 9);
    const dlim = Math.pow(2, cfg.drift_dac_bits - 1);
    v["7"] = per("7", (a) => `${fmt(Math.max(-dlim, Math.min(dlim - 1, s.drift[a]))
      * cfg.drift_lsb_arcsec_s, 3)}\u00b0/h`, 9);
    v["22"] = s.cpu ? [0, 1, 2].map((a) => `${"rpy"[a]} ${fmtErr(s.errors[a])}`)
      : ["no target", "errors yet", ""];
    v["25"] = per("25", (a) => fmtInt(s.registers[a]), 8);
    const rlim = Math.pow(2, cfg.register_bits - 1);
    v["28"] = per("28", (a) => `${fmt(Math.max(-rlim, Math.min(rlim - 1, s.registers[a]))
      * cfg.register_lsb_arcsec, 1)}\u2033`, 7);
    const w23 = inForce(D.registers["23"], t), w24 = inForce(D.registers["24"], t);
    v["23"] = D.registers.known ? [`r ${w23.sf_roll.toFixed(6)}`, `y ${w23.sf_yaw.toFixed(6)}`]
      : ["needs the", "summary"];
    v["24"] = w24 ? [`r ${fmt(w24.roll_deg, 3)}\u00b0`, `y ${fmt(w24.yaw_deg, 2)}\u00b0`]
      : [D.registers.known ? "empty" : "needs the", D.registers.known ? "" : "summary"];
    v["21"] = ["S7/S8 on", `${AXIS_NAMES[s.selector]}`];
    const stored = D.registers["23"].filter((e) => e.t_s <= t && e.source !== "start"
      && e.source !== "withheld").length;
    v["19"] = [stored ? "wrote 23" : "idle", stored ? `${stored} time${stored > 1 ? "s" : ""}` : ""];
    v["20"] = [modeLabel(s.mode), ""];
    const rc = cfg.rate_command_deg_s;
    v["120"] = [`120 ${s.closed[16] ? fmt(Math.sign(s.rate[0]) * rc, 1) + "\u00b0/s" : "off"}`,
      `128 ${s.closed[17] ? fmt(Math.sign(s.rate[2]) * rc, 1) + "\u00b0/s" : "off"}`, ""];
    v["104"] = s.sunPresent ? [`p ${fmtErr(s.sun[0])}`, `y ${fmtErr(s.sun[1])}`,
      "Sun present"] : ["", "", "no Sun"];
    const star = starInSlit(t);
    const starText = star === null ? (s.starPresent ? "a star" : "no star")
      : star.slice(0, 12);
    v["105"] = s.starPresent ? [`y ${fmtErr(s.trk[0])}`, `along ${fmt(s.trk[1] / 3600, 2)}\u00b0`,
      starText] : ["", "", starText];
    v["31"] = per("31", (a) => `${fmt(s.amps[a], 3)} V`, 9);
    v["34"] = per("34", (a) => `valve ${["\u22121", " 0", "+1"][s.valves[a] + 1]}`, 8);
    if (WHEELS) {
      v["39"] = [0, 1, 2].map((a) => `${"xyz"[a]} ${fmt(s.wheelH[a], 2).padStart(6)} Nms`);
    } else {
      v["39"] = per("39", (a) => `${s.valves[a] ? (s.valves[a] > 0 ? "+fire" : "\u2212fire") : "off"}`, 5);
    }
    const extra = WHEELS && s.unloading ? " \u00b7 unloading" : "";
    v["100"] = [`true body rates (r p y) ${s.rateDeg.map((r) => fmtRate(r)).join(" ")} \u00b0/s`
      + ` \u00b7 propellant ${s.propellant.toFixed(3)}/${cfg.propellant_kg.toFixed(1)} kg${extra}`];
    return v;
  }

  function lineState(spec, s) {
    if (spec.vehicle) return "perm";
    const sws = spec.switches;
    if (!sws.length) {
      if (spec.from === "23" || spec.from === "24" || (spec.from === "25" && spec.to === "28"))
        return s.cpu ? "live" : "dead";
      return "perm";
    }
    if (sws.some((k) => SELECTORS.indexOf(k) >= 0)) return s.cpu ? "live" : "dead";
    return sws.some((k) => s.closed[k]) ? "live" : "dead";
  }

  function markFaults(t) {
    const on = {};
    for (const f of faultsAt(t)) for (const n of f.boxes) (on[n] = on[n] || []).push(f.text);
    for (const n in boxEls) {
      const e = boxEls[n], text = (on[n] || []).join("; ");
      if (e.fault === text) continue;
      e.fault = text;
      e.rect.setAttribute("stroke", text ? FAULT_COLOUR : "#2b3040");
      e.rect.setAttribute("stroke-width", text ? 6 : 2);
      e.rect.setAttribute("fill", text ? "url(#fault-hatch)" : e.fill);
      e.mark.setAttribute("visibility", text ? "visible" : "hidden");
      e.g.setAttribute("data-fault", text);
      const title = e.g.querySelector("title");
      title.textContent = (WHEELS && n === "39" ? D.diagram.plain_wheels : G.boxes[n].plain)
        + (text ? ` Fault acting: ${text}.` : "");
    }
  }

  function update(s, t) {
    const v = values(s, t);
    for (const n in texts) {
      const lines = v[n] || [];
      for (let k = 0; k < texts[n].length; k++) setText(n, k, lines[k] || "");
    }
    for (const L of lineEls) {
      const st = lineState(L.spec, s);
      if (st !== L.state) {
        L.state = st;
        const colour = st === "live" ? LIVE : st === "dead" ? DEAD : PERM;
        L.el.setAttribute("stroke", colour);
        L.el.setAttribute("stroke-width", st === "live" ? 7 : 3);
        L.el.setAttribute("stroke-dasharray", st === "dead" ? "10 8" : "none");
        L.el.setAttribute("marker-end", `url(#a-${st})`);
      }
    }
    for (const k in switchEls) {
      const e = switchEls[k], closed = s.closed[k];
      if (e.state !== closed) {
        e.state = closed;
        e.blade.setAttribute("x2", e.x + (closed ? 34 : 30));
        e.blade.setAttribute("y2", e.y + (closed ? 0 : -16));
        e.blade.setAttribute("stroke", closed ? LIVE : DEAD);
        e.label.setAttribute("fill", closed ? LIVE : OPEN_LABEL);
        e.g.setAttribute("data-closed", closed);
      }
    }
    for (const k in selectorEls) {
      const e = selectorEls[k];
      if (e.state !== s.selector) {
        e.state = s.selector;
        const c = e.contacts[s.selector];
        e.arm.setAttribute("x2", c[0]);
        e.arm.setAttribute("y2", c[1]);
        e.arm.setAttribute("stroke", AXIS_COLOURS[s.selector]);
        e.g.setAttribute("data-axis", AXIS_NAMES[s.selector]);
      }
    }
    jetEls.forEach((c, a) => {
      const on = s.valves[a] !== 0;
      if (c._on !== on) {
        c._on = on;
        c.setAttribute("fill", on ? "#ff8c1a" : "#dddddd");
        c.setAttribute("stroke", on ? "#a04000" : "#555555");
      }
    });
    if (WHEELS) {
      const e = boxEls["39"], un = s.unloading ? "true" : "false";
      if (e.g.getAttribute("data-unloading") !== un) {
        e.g.setAttribute("data-unloading", un);
        if (!e.fault) e.rect.setAttribute("stroke", s.unloading ? "#d35400" : "#2b3040");
        if (!e.fault) e.rect.setAttribute("stroke-width", s.unloading ? 6 : 2);
      }
    }
    markFaults(t);
    const sum = `Block diagram at ${t.toFixed(1)} s, ${modeLabel(s.mode)}: switches closed `
      + `${Object.keys(s.closed).filter((k) => s.closed[k] && SELECTORS.indexOf(+k) < 0)
        .map((k) => "S" + k).join(", ") || "none"}; S7/S8 on ${AXIS_NAMES[s.selector]}.`;
    if (svg.getAttribute("aria-label") !== sum) svg.setAttribute("aria-label", sum);
  }

  build();
  squeezeTitles();
  return { update: update };
})();
