// diagram.js: the block diagram drawn from the layout and wiring tables, with live values.
const DIAGRAM = (function () {
  const G = D.diagram, S = 100;  // user units per diagram unit
  const [X0, X1, Y0, Y1] = G.extent;
  const X = (x) => (x - X0) * S, Y = (y) => (Y1 - y) * S;
  const LIVE = "#1a9850", DEAD = "#b8bec9", PERM = "#3b4252";
  const svg = document.getElementById("diagram");
  const texts = {};  // numeral -> [text elements of its value lines]
  const lineEls = [];  // {el, head, spec}
  const switchEls = {};  // k -> {blade, label, open:[x,y], closed:[x,y]}
  const selectorEls = {};  // 7/8 -> {arm, pivot, contacts}
  const jetEls = [];
  const titles = [];  // [text, room]: squeezed to fit after the first layout
  let last = {};

  function build() {
    svg.setAttribute("viewBox", `0 0 ${(X1 - X0) * S} ${(Y1 - Y0) * S}`);
    svg.setAttribute("preserveAspectRatio", "xMidYMid meet");
    const defs = svgEl("defs", {}, svg);
    for (const [id, colour] of [["a-live", LIVE], ["a-dead", DEAD], ["a-perm", PERM]]) {
      const m = svgEl("marker", { id: id, viewBox: "0 0 10 10", refX: 9, refY: 5,
        markerWidth: 7, markerHeight: 7, orient: "auto-start-reverse" }, defs);
      svgEl("path", { d: "M0,0 L10,5 L0,10 z", fill: colour }, m);
    }
    for (const n in G.frames) {
      const [x, y, w, h] = G.frames[n].box;
      svgEl("rect", { x: X(x), y: Y(y + h), width: w * S, height: h * S, rx: 8,
        fill: "#f3f6fb", stroke: "#5577aa", "stroke-dasharray": "8 6", "stroke-width": 2 }, svg);
      const t = svgEl("text", { x: X(x + w) - 8, y: Y(y + h) + 20, "text-anchor": "end",
        "font-size": 18, fill: "#335588" }, svg);
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
        const t = svgEl("text", { x: X((p[0] + q[0]) / 2) + 8, y: Y((p[1] + q[1]) / 2),
          "font-size": 16, fill: "#8a6d00" }, svg);
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
    const g = svgEl("g", {}, svg);
    const title = svgEl("title", {}, g);
    title.textContent = `${b.name} (${b.numerals.join(", ")}): ${b.module}`;
    svgEl("rect", { x: X(x), y: Y(y + h), width: w * S, height: h * S, rx: 6,
      fill: b.shaded ? "#fff7e6" : "#ffffff", stroke: "#2b3040", "stroke-width": 2 }, g);
    const cx = X(x + w / 2), top = Y(y + h);
    if (n === "100") {
      const t = svgEl("text", { x: X(x) + 14, y: top + 28, "font-size": 24,
        "font-weight": 700 }, g);
      t.textContent = `${b.label} ${b.numerals.join(", ")}`;
      texts[n] = [svgEl("text", { x: X(x) + 14, y: top + 56, "font-size": 22,
        "font-family": "monospace" }, g), svgEl("text", { x: X(x) + 14, y: top + 84,
        "font-size": 22, "font-family": "monospace" }, g)];
      return;
    }
    const t1 = svgEl("text", { x: cx, y: top + 25, "text-anchor": "middle", "font-size": 24,
      "font-weight": 700 }, g);
    t1.textContent = b.numerals.length === 1 ? `${b.label} ${n}` : b.label;
    titles.push([t1, w * S - 10]);
    texts[n] = [0, 1, 2].map((k) => svgEl("text", { x: X(x) + 8, y: top + 52 + 24 * k,
      "font-size": 22, "font-family": "monospace" }, g));
    if (n === "39") {
      for (let a = 0; a < 3; a++) {
        const c = svgEl("circle", { cx: X(x + w) - 18, cy: top + 45 + 24 * a, r: 9,
          fill: "#ddd", stroke: "#777" }, g);
        jetEls.push(c);
      }
    }
  }

  function buildSwitches(spec) {
    const at = spec.points.length > 2 ? 1 : 0;
    const p = spec.points[at], q = spec.points[at + 1];
    const horizontal = Math.abs(q[1] - p[1]) < 1e-9;
    const sel = spec.switches.filter((k) => k === 7 || k === 8);
    if (sel.length) {
      buildSelector(sel[0], X((p[0] + q[0]) / 2), Y(p[1]));
      return;
    }
    const n = spec.switches.length, pitch = 46, width = n * pitch;
    let x0, y0;
    if (horizontal) {
      const dir = q[0] > p[0] ? 1 : -1;
      const start = spec.points.length > 2 ? X(p[0]) + dir * 14 : (X(p[0]) + X(q[0])) / 2 - dir * width / 2;
      x0 = dir > 0 ? start : start - width;
      y0 = Y(p[1]) - 16;
    } else {
      x0 = X(p[0]) - width - 8;
      y0 = (Y(p[1]) + Y(q[1])) / 2;
    }
    spec.switches.forEach((k, j) => {
      const x = x0 + j * pitch + 6, y = y0;
      const g = svgEl("g", {}, svg);
      const sw = D.diagram.switches[k - 1];
      svgEl("title", {}, g).textContent = `S${k}: ${sw.text}`;
      svgEl("circle", { cx: x, cy: y, r: 3.5, fill: "#333" }, g);
      svgEl("circle", { cx: x + 30, cy: y, r: 3.5, fill: "#333" }, g);
      const blade = svgEl("line", { x1: x, y1: y, x2: x + 27, y2: y - 15, stroke: "#999",
        "stroke-width": 4, "stroke-linecap": "round" }, g);
      const label = svgEl("text", { x: x + 15, y: y + 21, "text-anchor": "middle",
        "font-size": 19, "font-weight": 700, fill: "#a22" }, g);
      label.textContent = `S${k}`;
      g.setAttribute("data-switch", k);
      switchEls[k] = { g: g, blade: blade, label: label, x: x, y: y, state: null };
    });
  }

  function buildSelector(k, cx, cy) {
    const g = svgEl("g", {}, svg);
    const sw = D.diagram.switches[k - 1];
    svgEl("title", {}, g).textContent = `S7/S8 (coupled by line 132): ${sw.text}`;
    const px = cx - 26, contacts = [];
    svgEl("circle", { cx: px, cy: cy, r: 4, fill: "#333" }, g);
    for (let a = 0; a < 3; a++) {
      const yy = cy - 20 + 20 * a;
      contacts.push([cx + 18, yy]);
      svgEl("circle", { cx: cx + 18, cy: yy, r: 4, fill: AXIS_COLOURS[a] }, g);
      const t = svgEl("text", { x: cx + 27, y: yy + 5, "font-size": 13, fill: AXIS_COLOURS[a] }, g);
      t.textContent = "rpy"[a];
    }
    const arm = svgEl("line", { x1: px, y1: cy, x2: cx + 18, y2: cy, stroke: "#333",
      "stroke-width": 4, "stroke-linecap": "round" }, g);
    const label = svgEl("text", { x: cx - 6, y: cy - 26, "text-anchor": "middle",
      "font-size": 19, "font-weight": 700, fill: "#a22" }, g);
    label.textContent = `S${k}`;
    g.setAttribute("data-selector", k);
    selectorEls[k] = { g: g, arm: arm, contacts: contacts, state: null };
  }

  function setText(n, k, value) {
    const key = n + ":" + k;
    if (last[key] !== value) { texts[n][k].textContent = value; last[key] = value; }
  }

  function values(s, t) {
    const cfg = D.config;
    const v = {}, per = (n, f) => G.boxes[n].numerals.map((num, a) => `${num.padEnd(2)} ${f(a)}`);
    v["1"] = per("1", (a) => `${fmt(s.rate[a] / 3600, 3)}\u00b0/s`);
    const cmd = [s.closed[16] ? "+cmd" : "", "", s.closed[17] ? "+cmd" : ""];
    v["4"] = per("4", (a) => `${s.closed[a + 1] ? "\u2212drift" : "gyro"}${cmd[a]}`);
    v["8"] = per("8", (a) => `${fmtInt(s.pps[a])} p/s`);
    v["14"] = per("14", (a) => `${fmtInt(s.counters[a]).padStart(9)}`);
    v["13"] = per("13", (a) => `${fmtInt(s.drift[a]).padStart(6)}${s.closed[a + 4] ? " \u2190" : ""}`);
    const dlim = Math.pow(2, cfg.drift_dac_bits - 1);
    v["7"] = per("7", (a) => `${fmt(Math.max(-dlim, Math.min(dlim - 1, s.drift[a]))
      * cfg.drift_lsb_arcsec_s, 3)}\u00b0/h`);
    v["22"] = s.cpu ? [0, 1, 2].map((a) => `${"rpy"[a]} ${fmt(s.errors[a], 1)}\u2033`)
      : ["no target", "errors yet", ""];
    v["25"] = per("25", (a) => `${fmtInt(s.registers[a]).padStart(7)}`);
    const rlim = Math.pow(2, cfg.register_bits - 1);
    v["28"] = per("28", (a) => `${fmt(Math.max(-rlim, Math.min(rlim - 1, s.registers[a]))
      * cfg.register_lsb_arcsec, 1)}\u2033`);
    const w23 = inForce(D.registers["23"], t), w24 = inForce(D.registers["24"], t);
    v["23"] = D.registers.known ? [`SFr ${w23.sf_roll.toFixed(6)}`, `SFy ${w23.sf_yaw.toFixed(6)}`,
      `cc: line below${WORD_MARK[w23.source] || ""}`] : ["(needs the", "summary)", ""];
    v["24"] = w24 ? [`r ${fmt(w24.roll_deg, 3)}\u00b0`, `y ${fmt(w24.yaw_deg, 3)}\u00b0`,
      TARGETS.length > 1 ? w24.target.slice(0, 10) : ""]
      : [D.registers.known ? "empty" : "(needs the", D.registers.known ? "" : "summary)", ""];
    v["21"] = ["S7/S8 on", `${AXIS_NAMES[s.selector]}`, ""];
    const stored = D.registers["23"].filter((e) => e.t_s <= t && e.source !== "start"
      && e.source !== "withheld").length;
    v["19"] = [stored ? "wrote reg.23" : "idle", stored ? `${stored} time(s)` : "", ""];
    v["20"] = [`Mode ${s.mode}`, "", ""];
    const rc = cfg.rate_command_deg_s;
    v["120"] = [`120 ${s.closed[16] ? fmt(Math.sign(s.rate[0]) * rc, 1) + "\u00b0/s" : "off"}`,
      `128 ${s.closed[17] ? fmt(Math.sign(s.rate[2]) * rc, 1) + "\u00b0/s" : "off"}`, ""];
    v["104"] = s.sunPresent ? [`p ${fmt(s.sun[0], 1)}\u2033`, `y ${fmt(s.sun[1], 1)}\u2033`,
      "Sun present"] : ["", "", "no Sun"];
    const star = D.sky.locked || D.sky.reference;
    v["105"] = s.starPresent ? [`y ${fmt(s.trk[0], 1)}\u2033`, `p ${fmt(s.trk[1], 1)}\u2033`,
      `${star}`] : ["", "", "no star"];
    v["31"] = per("31", (a) => `${fmt(s.amps[a], 4)} V`);
    v["34"] = per("34", (a) => `valve ${["\u22121", " 0", "+1"][s.valves[a] + 1]}`);
    v["39"] = per("39", (a) => `${s.valves[a] ? (s.valves[a] > 0 ? "+fire" : "\u2212fire") : "off"}`);
    v["100"] = [`body rates ${s.rate.map((r) => fmt(r / 3600, 3)).join(" ")} \u00b0/s (x y z)`,
      `propellant ${s.propellant.toFixed(3)} kg of ${cfg.propellant_kg.toFixed(1)} kg`];
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
    if (sws.indexOf(7) >= 0 || sws.indexOf(8) >= 0) return s.cpu ? "live" : "dead";
    return sws.some((k) => s.closed[k]) ? "live" : "dead";
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
        L.el.setAttribute("stroke-width", st === "live" ? 6 : 3);
        L.el.setAttribute("stroke-dasharray", st === "dead" ? "10 8" : "none");
        L.el.setAttribute("marker-end", `url(#a-${st})`);
      }
    }
    for (const k in switchEls) {
      const e = switchEls[k], closed = s.closed[k];
      if (e.state !== closed) {
        e.state = closed;
        e.blade.setAttribute("x2", e.x + (closed ? 30 : 27));
        e.blade.setAttribute("y2", e.y + (closed ? 0 : -15));
        e.blade.setAttribute("stroke", closed ? LIVE : "#999");
        e.label.setAttribute("fill", closed ? LIVE : "#a22");
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
        c.setAttribute("fill", on ? "#ff8c1a" : "#ddd");
        c.setAttribute("stroke", on ? "#c0392b" : "#777");
      }
    });
  }

  build();
  squeezeTitles();
  return { update: update };
})();
