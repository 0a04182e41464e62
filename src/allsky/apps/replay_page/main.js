// main.js: the mission clock, header, ending, truth beside belief, event log, controls,
// keys, help, announcements and window.allsky.
const APP = (function () {
  let t = T0, playing = false, speed = 50, lastFrame = null, currentEvent = -1, lastMode = "";
  let lastStatus = "", lastAnnounced = "", stale = false;  // stale: the journal changed
  // A live page follows the newest row until the user moves the clock back.
  let follow = LIVE;
  const $ = (id) => document.getElementById(id);
  const scrub = $("scrub"), playBtn = $("btn-play"), speedSel = $("speed");
  const modeStarts = [];  // [row, name] of each run of the mode column
  const timing = { lastDrawMs: 0, draws: 0, parts: {} };
  let WAITING = [];
  const landings = [];

  function modeRuns() {
    modeStarts.length = 0;
    for (const [row, code] of C.runs.mode) modeStarts.push([row, modeName(code)]);
  }

  // Mode boundaries to step to: the first telemetry row after each mode starts (the row at
  // the start time itself is written by the last frame of the mode before). A mode of no
  // duration has no row of its own: its step lands in the mode after it.
  function findLandings() {
    landings.length = 0;
    for (const m of D.timeline) {
      let lo = 0, hi = N - 1;
      const ms = Math.round(m.start_s * 1000);
      if (T_MS[hi] <= ms) continue;
      if (ms <= T_MS[0]) { if (!landings.length) landings.push(T0); continue; }
      while (lo < hi) { const mid = (lo + hi) >> 1; if (T_MS[mid] > ms) hi = mid; else lo = mid + 1; }
      const ts = T_MS[lo] / 1000;
      if (!landings.length || landings[landings.length - 1] < ts) landings.push(ts);
    }
  }
  modeRuns();
  findLandings();
  WAITING = D.events.filter((e) => e.waiting !== undefined && e.waiting !== null);

  function modeStartRow(i) {
    let r = 0;
    for (const [row] of modeStarts) if (row <= i) r = row;
    return r;
  }

  // Who, when, what: the scenario, its date, seed and description.
  (function missionLine() {
    const m = D.mission;
    $("scenario-name").textContent = m.name ? `${m.name}` : "mission replay";
    $("scenario-title").textContent = m.title || "";
    const when = `${m.date_utc.replace("T", " ").replace("+00:00", " UTC")} \u00b7 seed ${m.seed}`
      + (m.overrides.length ? ` \u00b7 --set ${m.overrides.join(" ")}` : "");
    $("mission-when").textContent = when;
    if (m.description) $("mission-line").title = m.description;
    $("about-scenario").textContent = [m.title, m.description].filter((x) => x).join(" ")
      || "No scenario was named when the page was written.";
  })();

  // Header: the mode, its title and sentence from the mode table, what the sequencer awaits.
  function header(s, status) {
    const m = D.modes[s.mode] || { title: "unknown mode", sentence: "", look: "" };
    const badge = $("mode-badge");
    if (s.mode !== lastMode || status !== lastStatus || stale) {
      $("mode-name").textContent = modeLabel(s.mode);
      const amber = status === "complete" && judgedAmber();
      const bgc = status === "aborted" ? "#b71c1c" : amber ? AMBER
        : status === "complete" ? "#1b5e20" : modeColour(s.mode);
      badge.style.background = bgc; badge.style.color = textOn(bgc);
      $("status-badge").textContent = status === "aborted" ? "ABORTED"
        : amber ? "COMPLETE, AS JUDGED" : status === "complete" ? "COMPLETE" : "";
      badge.title = amber ? `complete, as the sequencer judged: \u26a0 ${D.ending.judged.first_warning}` : "";
      badge.dataset.status = status || "";
      badge.dataset.tone = status === "flying" ? "" : (amber ? "amber" : status || "");
      $("mode-title").textContent = m.title.charAt(0).toUpperCase() + m.title.slice(1);
      $("mode-sentence").textContent = m.sentence;
      $("mode-look").textContent = m.look ? `Look: ${m.look}` : "";
      if (s.mode !== lastMode && lastMode) announce(`${modeLabel(s.mode)}: ${m.title}`);
      lastMode = s.mode;
    }
    $("clock").textContent = `t = ${t.toFixed(1)} s`;
    const ev = inForce(WAITING, t);
    let now = ev && ev.waiting ? `Now: waiting for ${ev.waiting}` : "";
    if (s.mode === "1") now += " (the Mode 1 sun-acquisition controller, not drawn in the patent's "
      + "diagram, drives the control amplifiers)";
    if (status === "aborted") now = `Aborted at ${D.ending.t_s.toFixed(1)} s: ${D.ending.reason}`;
    if (status === "complete") now = judgedAmber()
      ? `The sequencer has ended the mission: complete, as it judged. \u26a0 ${D.ending.judged.first_warning}`
      : "The sequencer has ended the mission: complete.";
    if ($("mode-now").textContent !== now) $("mode-now").textContent = now;
  }

  // The header keeps one height through the flight: the tallest any mode's texts make it
  // (its title, sentence, what to look for, the longest "waiting for" of the mode), so that
  // no panel moves at a mode change. Measured again after a resize or a new journal.
  let headerStale = true;
  function holdHeaderHeight() {
    const row = $("mode-row"), ids = ["mode-title", "mode-sentence", "mode-now", "mode-look"];
    const kept = ids.map((id) => $(id).textContent), look = $("mode-look").hidden;
    row.style.minHeight = "";
    $("mode-look").hidden = false;
    let tallest = 0;
    const flown = new Set(D.timeline.map((r) => r.mode));
    for (const name in D.modes) {
      if (flown.size && !flown.has(name)) continue;
      const m = D.modes[name];
      const nows = WAITING.filter((e) => e.mode === name).map((e) => `Now: waiting for ${e.waiting}`);
      const now = nows.reduce((a, b) => (b.length > a.length ? b : a), "")
        + (name === "1" ? " (the Mode 1 sun-acquisition controller, not drawn in the patent's "
          + "diagram, drives the control amplifiers)" : "");
      $("mode-title").textContent = m.title.charAt(0).toUpperCase() + m.title.slice(1);
      $("mode-sentence").textContent = m.sentence;
      $("mode-now").textContent = now;
      $("mode-look").textContent = m.look ? `Look: ${m.look}` : "";
      tallest = Math.max(tallest, row.getBoundingClientRect().height);
    }
    ids.forEach((id, k) => { $(id).textContent = kept[k]; });
    $("mode-look").hidden = look;
    row.style.minHeight = `${Math.ceil(tallest)}px`;
    headerStale = false;
  }
  window.addEventListener("resize", () => { headerStale = true; });
  ON_JOURNAL.push(() => { headerStale = true; });

  // A mission the sequencer completed while the summary warns: amber, never green.
  const AMBER = "#9a6700";
  function judgedAmber() {
    return !!(D.ending && D.ending.judged && D.ending.judged.tone === "amber");
  }

  // The ending: a banner once the mission has ended (complete or aborted).
  function ending(status) {
    const el = $("ending");
    if (status === lastStatus && !stale) return;
    const amber = status === "complete" && judgedAmber();
    if (lastStatus && status !== lastStatus && status !== "flying") announce(status === "aborted"
      ? `Mission aborted: ${D.ending.reason}` : amber
        ? `Mission complete, as the sequencer judged: ${D.ending.judged.first_warning}` : "Mission complete");
    lastStatus = status;
    el.hidden = status === "flying";
    $("mode-look").hidden = status !== "flying";
    el.className = amber ? "judged" : status || "unknown";
    el.dataset.status = status || "";
    if (status === "flying") return;
    const e = D.ending;
    if (!e) { el.textContent = "The record ends here (no summary given: how the mission ended is not known)."; return; }
    const used = e.propellant_kg === null || e.propellant_kg === undefined ? "" :
      ` \u00b7 propellant used ${e.propellant_kg.toFixed(3)} kg`
      + (e.propellant_remaining_kg === null || e.propellant_remaining_kg === undefined ? ""
        : ` (${e.propellant_remaining_kg.toFixed(3)} kg left)`);
    const err = e.true_error_arcsec === null || e.true_error_arcsec === undefined ? ""
      : ` \u00b7 true error ${fmtSep(e.true_error_arcsec)}`;
    const head = document.createElement("b");
    if (amber) head.textContent = `Mission complete on ${e.target}, as the sequencer judged`;
    else if (status === "complete") head.textContent = `Mission complete on ${e.target}`;
    else if (status === "aborted") head.textContent = `Mission ABORTED in ${modeLabel(e.mode)} at ${e.t_s.toFixed(1)} s`;
    else head.textContent = `Mission ended: ${e.status}`;
    const body = document.createElement("span");
    body.textContent = (status === "aborted" ? `: ${e.reason}` : "") + err
      + (status === "aborted" && e.target ? ` from ${e.target}` : "") + used;
    el.replaceChildren(head, body);
    if (amber) {
      const first = document.createElement("div");
      first.className = "first-warning";
      first.textContent = `\u26a0 ${e.judged.first_warning}`;
      el.appendChild(first);
    }
    if (D.warnings.length) {
      const wn = document.createElement("div");
      wn.textContent = `\u26a0 ${D.warnings.length} warning${D.warnings.length > 1 ? "s" : ""} of the summary: `
        + "in the event log at the time each happened, \u26a0 above the time slider";
      el.appendChild(wn);
    }
  }

  function announce(text) {
    if (text === lastAnnounced) return;
    lastAnnounced = text;
    $("announce").textContent = text;
  }

  // Registers 23 and 24 as written, register 23's words above the truth (a two-row table).
  const WORDS = [["sf_roll", "SFr", "scale factor, roll", false],
    ["sf_yaw", "SFy", "scale factor, yaw", false],
    ["roll_into_pitch", "r\u2192p", "cross-coupling, roll into pitch", true],
    ["roll_into_yaw", "r\u2192y", "cross-coupling, roll into yaw", true],
    ["yaw_into_pitch", "y\u2192p", "cross-coupling, yaw into pitch", true],
    ["yaw_into_roll", "y\u2192r", "cross-coupling, yaw into roll", true]];
  function registersLine() {
    const w = inForce(D.registers["23"], t), p = inForce(D.registers["24"], t);
    const el = $("registers-line");
    const key = `${w ? w.t_s : ""}|${p ? p.t_s : ""}`;
    if (el.dataset.key === key) return;
    el.dataset.key = key;
    el.replaceChildren();
    const row = () => el.insertRow(), cell = (r, text, cls, title) => {
      const c = r.insertCell(); c.textContent = text; if (cls) c.className = cls;
      if (title) c.title = title; return c;
    };
    const r1 = row(), r2 = row();
    if (!D.registers.known) {
      cell(r1, "reg. 23/24: not in the telemetry (replay with --summary)");
      return;
    }
    cell(r1, `reg. 23${WORD_MARK[w.source] || ""}${w.source === "withheld" ? " (withheld)" : ""}`, "head");
    const truth = D.truth23, written = w.source !== "start" && w.source !== "withheld";
    cell(r2, truth ? "true" : "", "head");
    let flagged = 0;
    const as = (x) => `${fmt(x * ARCSEC_PER_RAD, 1)}\u2033`;
    // A word no calibration has written holds the power-on value: not a measurement, so not
    // shown as one beside the truth ("not calibrated", and why).
    const aborted = D.ending && D.ending.status === "aborted" && t >= D.ending.t_s - 1e-9;
    const why = aborted ? `Mode ${D.ending.mode} aborted` : "not written yet";
    for (const [k, label, long, cc] of WORDS) {
      const val = w[k], never = w.source === "journal" ? (w.written || []).indexOf(k) < 0
        : w.source === "start";
      const c1 = never ? cell(r1, `${label} not cal.`, "word not-calibrated",
        `${long}: not calibrated (${why}); the register holds its power-on value ${cc ? as(val) : val.toFixed(6)}`)
        : cell(r1, `${label} ${cc ? as(val) : val.toFixed(6)}`, "word", long);
      if (truth && k in truth.words) {
        const tv = truth.words[k];
        const off = written && (w.written || []).indexOf(k) >= 0 && Math.abs(val - tv) > truth.flag_above;
        const c2 = cell(r2, `${" ".repeat(label.length)} ${cc ? as(tv) : tv.toFixed(6)}`, "word",
          `${long}: the true value of the scenario's gyros`);
        if (off) {
          flagged += 1;
          for (const c of [c1, c2]) c.classList.add("far-off");
          c1.textContent = "\u26a0" + c1.textContent;
          c1.title = `${long}: far from the truth (over a half turn this error moves the pointing by more than the settle threshold)`;
        }
      } else cell(r2, "");
    }
    el.dataset.flagged = flagged;
    cell(r1, p ? `reg. 24 (${p.target}): roll ${fmt(p.roll_deg, 4)}\u00b0` : "reg. 24: empty", "r24");
    cell(r2, p ? `yaw ${fmt(p.yaw_deg, 4)}\u00b0` : "", "r24");
  }

  // Truth beside belief: the true error, CPU 22's, the body rates, the star in the slit.
  function truthLine(s) {
    const star = starInSlit(t);
    const parts = [`true error to ${TARGETS[s.target].name}: ${fmtSep(s.trueErr)}`,
      s.cpuPointing === null ? "CPU 22: no pointing error computed in this mode"
        : `CPU 22 judges ${fmtSep(s.cpuPointing)}`,
      `body rates ${s.rateDeg.map((r) => fmtRate(r)).join(" ")} \u00b0/s`,
      `slit: ${star || (s.starPresent ? "a star" : "empty")}`];
    const text = parts.join(" \u00b7 ");
    const el = $("truth-line");
    if (el.dataset.text !== text) {
      el.dataset.text = text;
      $("truth-error").textContent = parts[0];
      $("truth-cpu").textContent = parts[1];
      $("truth-rates").textContent = parts[2];
      $("truth-star").textContent = parts[3];
      const far = s.cpuPointing !== null && s.trueErr > 10 * Math.max(s.cpuPointing, D.config.settle_threshold_arcsec);
      el.classList.toggle("far-off", far);
    }
  }

  // Event log: each row a button (keyboard: Tab, Enter), click to jump.
  const list = $("events"), items = [];
  const KIND_WORD = { switch: "Switches: ", action: "Action: ", warning: "\u26a0 Warning: ", fault: "", abort: "",
    ground_command: "Ground: " };
  let listed = [];  // the entries the list shows
  function eventItem(e, k) {
    const li = document.createElement("li");
    const b = document.createElement("button");
    b.type = "button"; b.className = `ev kind-${e.kind}`;
    const tt = document.createElement("span"); tt.className = "t"; tt.textContent = e.t_s.toFixed(1);
    const tx = document.createElement("span"); tx.className = "what";
    tx.textContent = (KIND_WORD[e.kind] || "") + e.text;
    const why = document.createElement("span"); why.className = "why";
    why.textContent = e.kind === "switch" ? `why: ${e.reason}${e.waiting ? `; then waits for ${e.waiting}` : ""}`
      : `why: ${e.reason}`;
    if (e.detail) b.title = e.detail;
    b.append(tt, tx, why);
    b.addEventListener("click", () => seek(e.t_s));
    li.dataset.k = k; li.dataset.kind = e.kind;
    li.appendChild(b);
    return li;
  }
  /** The list made the journal's log: rows added at the end, or made anew if earlier ones changed. */
  function listEvents() {
    const same = listed.length <= D.events.length && listed.every((e, k) => e.t_s === D.events[k].t_s
      && e.text === D.events[k].text && e.kind === D.events[k].kind);
    if (!same) { list.replaceChildren(); items.length = 0; listed = []; currentEvent = -2; }
    for (let k = listed.length; k < D.events.length; k++) {
      const li = eventItem(D.events[k], k);
      list.appendChild(li); items.push(li);
    }
    if (listed.length !== D.events.length) currentEvent = -2;
    listed = D.events.slice();
  }
  listEvents();

  function eventLog() {
    let cur = -1;
    for (let k = 0; k < D.events.length; k++) if (D.events[k].t_s <= t + 1e-9) cur = k;
    if (cur === currentEvent) return;
    currentEvent = cur;
    items.forEach((li, k) => {
      li.className = k < cur ? "past" : k === cur ? "current" : "future";
      if (k === cur) li.setAttribute("aria-current", "true"); else li.removeAttribute("aria-current");
    });
    if (cur >= 0) {
      const li = items[cur], box = list.getBoundingClientRect(), r = li.getBoundingClientRect();
      if (r.top < box.top || r.bottom > box.bottom) list.scrollTop += r.top - box.top - box.height / 3;
    }
  }

  // The traces' legend, in the page (not drawn in the canvas): one key per colour.
  (function legend() {
    const el = $("traces-legend"), seen = {};
    for (const st of TRACES.legend) for (const [name, colour, dashed, key] of st.series) {
      const k = key || name;
      if (seen[k]) continue;
      seen[k] = true;
      const s = document.createElement("span");
      s.className = "key";
      const sw = document.createElement("i"); sw.className = dashed ? "swatch dashed" : "swatch";
      sw.style.borderColor = colour;
      s.append(sw, document.createTextNode(k));
      el.appendChild(s);
    }
    for (const [text, colour] of [[`settle ${D.config.settle_threshold_arcsec}\u2033`, "#2e7d32"],
      [`hand-over ${D.config.handover_arcsec}\u2033`, "#8d6e00"]]) {
      const s = document.createElement("span"); s.className = "key";
      const sw = document.createElement("i"); sw.className = "swatch dashed"; sw.style.borderColor = colour;
      s.append(sw, document.createTextNode(text)); el.appendChild(s);
    }
    const f = document.createElement("span"); f.className = "key fault-key"; f.textContent = "\u2591 fault acting";
    el.appendChild(f);
  })();

  // Controls: the scrubber over the mode strip, with the faults, warnings and the ending.
  const strip = $("mode-strip"), marks = $("strip-marks");
  const frac = (x) => (x - T0) / Math.max(T1 - T0, 1e-9);
  const pos = (x) => `${100 * frac(x)}%`;
  const edge = (d, x) => { if (frac(x) > 0.98) d.classList.add("at-end"); else if (frac(x) < 0.02) d.classList.add("at-start"); };
  let stripAt = 0;
  function buildStrip() {
    stripAt = performance.now();
    scrub.min = T0; scrub.max = T1; scrub.step = D.config.interval_s;
    strip.replaceChildren(); marks.replaceChildren();
    for (const m of D.timeline) {
      const d = document.createElement("div");
      d.style.width = `${100 * (Math.min(m.end_s, T1) - m.start_s) / Math.max(T1 - T0, 1e-9)}%`;
      d.style.background = modeColour(m.mode);
      d.title = `${modeLabel(m.mode)}: ${(D.modes[m.mode] || {}).title || ""} (${m.start_s.toFixed(1)}\u2013${m.end_s.toFixed(1)} s)`;
      strip.appendChild(d);
    }
    for (const f of D.faults) {
      const d = document.createElement("div");
      d.className = "fault-band";
      d.style.left = pos(f.start_s);
      d.style.width = `max(3px, ${100 * ((f.end_s === null ? T1 : f.end_s) - f.start_s) / Math.max(T1 - T0, 1e-9)}%)`;
      d.title = `fault: ${f.text} (${f.start_s.toFixed(1)} s${f.end_s === null ? " to the end" : `\u2013${f.end_s.toFixed(1)} s`})`;
      d.dataset.fault = f.kind;
      marks.appendChild(d);
    }
    for (const w of D.warnings) {
      const d = document.createElement("div");
      d.className = "warning-mark"; d.style.left = pos(w.t_s); d.title = w.text; d.textContent = "\u26a0";
      edge(d, w.t_s);
      marks.appendChild(d);
    }
    if (D.ending && (D.ending.status === "aborted" || D.ending.status === "complete")) {
      const d = document.createElement("div");
      const amber = D.ending.status === "complete" && judgedAmber();
      d.className = `end-mark ${amber ? "judged" : D.ending.status}`; d.style.left = pos(D.ending.t_s);
      d.title = D.ending.status === "aborted" ? `aborted at ${D.ending.t_s.toFixed(1)} s: ${D.ending.reason}`
        : amber ? `complete, as the sequencer judged: ${D.ending.judged.first_warning}` : "mission complete";
      d.textContent = D.ending.status === "aborted" ? "\u2716" : amber ? "\u26a0" : "\u2714";
      edge(d, D.ending.t_s);
      marks.appendChild(d);
    }
  }
  buildStrip();
  scrub.addEventListener("input", () => seek(+scrub.value));
  playBtn.addEventListener("click", () => (playing ? pause() : play()));
  speedSel.addEventListener("change", () => { speed = +speedSel.value; });
  $("btn-prev").addEventListener("click", () => prevMode());
  $("btn-next").addEventListener("click", () => nextMode());
  $("btn-back").addEventListener("click", () => seek(t - 10));
  $("btn-fwd").addEventListener("click", () => seek(t + 10));
  $("zoom-mode").addEventListener("change", (e) => { TRACES.setZoom(e.target.checked, t); redraw(); });
  const help = $("help");
  const openHelp = () => { if (!help.open) help.showModal(); $("btn-help-close").focus(); };
  const closeHelp = () => { if (help.open) help.close(); };
  $("btn-help").addEventListener("click", openHelp);
  $("btn-help-close").addEventListener("click", closeHelp);
  for (const n of D.notes) { const li = document.createElement("li"); li.textContent = n; $("notes").appendChild(li); }

  function prevMode() {
    const b = landings.filter((x) => x < t - 1e-6);
    seek(b.length ? b[b.length - 1] : T0);
  }
  function nextMode() {
    const b = landings.find((x) => x > t + 1e-6);
    seek(b === undefined ? T1 : b);
  }
  function stepSpeed(dir) {
    const opts = Array.from(speedSel.options).map((o) => +o.value);
    const k = Math.max(0, Math.min(opts.length - 1, opts.indexOf(speed) + dir));
    speed = opts[k]; speedSel.value = String(speed);
  }

  // The 3-D view and the sky map, small at 1280x720, enlarge in place over the page.
  function enlarge(id) {
    for (const el of document.querySelectorAll(".panel.enlarged")) {
      if (el.id !== id) el.classList.remove("enlarged");
    }
    const panel = id && document.getElementById(id);
    if (panel) panel.classList.toggle("enlarged");
    for (const b of document.querySelectorAll("button.enlarge")) {
      const on = document.getElementById(b.dataset.panel).classList.contains("enlarged");
      b.setAttribute("aria-pressed", on ? "true" : "false");
      b.textContent = `${on ? "\u2921" : "\u2922"} ${b.dataset.panel === "sky-panel" ? "m" : "v"}`;

    }
    redraw();
  }
  for (const b of document.querySelectorAll("button.enlarge")) {
    b.addEventListener("click", () => enlarge(b.dataset.panel));
  }

  window.addEventListener("keydown", (e) => {
    if (help.open) return;  // the dialog has the keys (Escape closes it)
    if (e.key === "Escape" && document.querySelector(".panel.enlarged")) {
      e.preventDefault(); enlarge(null); return;
    }
    const tag = e.target && e.target.tagName;
    if (tag === "SELECT" || (tag === "INPUT" && e.target.type !== "range")) return;
    if ((tag === "BUTTON" || tag === "INPUT") && (e.key === " " || e.key === "Enter")) return;
    if (tag === "INPUT" && e.key.startsWith("Arrow")) return;  // the scrubber moves itself
    const i = rowAt(t);
    const handled = {
      " ": () => (playing ? pause() : play()),
      "ArrowLeft": () => seek(t - (e.shiftKey ? 10 : 1)),
      "ArrowRight": () => seek(t + (e.shiftKey ? 10 : 1)),
      ",": () => seek(T_MS[Math.max(0, i - 1)] / 1000),
      ".": () => seek(T_MS[Math.min(N - 1, i + 1)] / 1000),
      "[": prevMode, "PageUp": prevMode, "]": nextMode, "PageDown": nextMode,
      "Home": () => seek(T0), "End": () => seek(T1),
      "+": () => stepSpeed(1), "=": () => stepSpeed(1), "-": () => stepSpeed(-1),
      "?": openHelp,
      "v": () => enlarge("vehicle-panel"), "m": () => enlarge("sky-panel"),
    }[e.key];
    if (handled) { e.preventDefault(); handled(); }
  });

  function redraw() {
    const t0 = performance.now(), parts = timing.parts;
    const i = rowAt(t), s = rowState(i), status = statusAt(t);
    let a = performance.now();
    const lap = (name) => { const b = performance.now(); parts[name] = b - a; a = b; };
    if (headerStale) holdHeaderHeight();
    header(s, status); ending(status); stale = false;
    registersLine(); truthLine(s); eventLog(); lap("text");
    DIAGRAM.update(s, t); lap("diagram");
    VEHICLE.draw(s, t); lap("vehicle");
    SKY.draw(s, t, modeStartRow(i)); lap("sky");
    TRACES.draw(s, t); lap("traces");
    if (LIVE) {  // the footer reviews the recording: named, its play hidden while following
      $("controls-name").hidden = false;
      if (playBtn.hidden !== follow) playBtn.hidden = follow;
    }
    if (+scrub.value !== t) scrub.value = t;
    const vt = `${t.toFixed(1)} s, ${modeLabel(s.mode)}${status === "flying" || !status ? "" : `, ${status}`}`;
    if (scrub.getAttribute("aria-valuetext") !== vt) scrub.setAttribute("aria-valuetext", vt);
    timing.lastDrawMs = performance.now() - t0;
    timing.draws += 1;
  }

  /** Show mission time ``ts`` [s], coerced to a number and clamped; NaN/infinite: ignored.
   *  On a live page, a time before the newest row stops following it. */
  function seek(ts) {
    const v = Number(ts);
    if (Number.isFinite(v)) {
      t = Math.max(T0, Math.min(T1, v));
      if (LIVE) follow = t >= T1 - 1e-9;
      redraw();
    }
    return state();
  }

  /** A live page: show the newest row, and go on showing it as rows arrive. */
  function live() { follow = true; pause(); t = T1; redraw(); return state(); }

  // A live page: new rows move the clock when it follows; one drawing per animation frame.
  let drawPending = false;
  function soon() {
    if (drawPending) return;
    drawPending = true;
    requestAnimationFrame(() => { drawPending = false; redraw(); });
  }
  ON_ROWS.push(() => {
    modeRuns();
    if (follow) t = T1;
    if (performance.now() - stripAt > 1000) { findLandings(); buildStrip(); }
    soon();
  });
  ON_JOURNAL.push(() => {
    WAITING = D.events.filter((e) => e.waiting !== undefined && e.waiting !== null);
    findLandings(); listEvents(); buildStrip(); stale = true;
    soon();
  });

  function frame(now) {
    if (!playing) return;
    if (lastFrame !== null) {
      t = Math.min(T1, t + (now - lastFrame) / 1000 * speed);
      redraw();
      if (t >= T1) { pause(); if (LIVE) follow = true; return; }
    }
    lastFrame = now;
    requestAnimationFrame(frame);
  }

  function play(sp) {
    if (sp) { speed = +sp; speedSel.value = String(speed); }
    if (playing) return;
    if (t >= T1) t = T0;
    follow = false;
    playing = true; lastFrame = null; playBtn.textContent = "pause \u23f8";
    playBtn.setAttribute("aria-pressed", "true");
    requestAnimationFrame(frame);
  }

  function pause() { playing = false; playBtn.textContent = "play \u25B6"; playBtn.setAttribute("aria-pressed", "false"); }

  /** What the page shows, in the documented form (the telemetry row at or before t). */
  function state() {
    const i = rowAt(t), mask = runValue(C.runs.switches, i), sw = {};
    for (let k = 1; k <= 19; k++) sw[`S${k}`] = switchClosed(mask, k);
    const s = rowState(i);
    return { t_s: t, mode: s.mode, switches: sw,
      selector: AXIS_NAMES[+C.selector[i]],
      counters_pulses: { "14": EXACT.counter14[i], "16": EXACT.counter16[i], "18": EXACT.counter18[i] },
      row_t_s: T_MS[i] / 1000, target: TARGETS[targetAt(T_MS[i] / 1000)].name,
      status: statusAt(t), true_error_arcsec: s.trueErr,
      body_rate_deg_s: { roll: s.rateDeg[0], pitch: s.rateDeg[1], yaw: s.rateDeg[2] },
      gyro_output_deg_s: Number.isNaN(s.gyroDeg[0]) ? null
        : { roll: s.gyroDeg[0], pitch: s.gyroDeg[1], yaw: s.gyroDeg[2] },
      tracker_star: starInSlit(t), faults_active: faultsAt(t).map((f) => f.kind) };
  }

  window.addEventListener("resize", () => redraw());
  return { seek: seek, redraw: redraw, play: play, pause: pause, state: state, timing: timing,
    isPlaying: () => playing, speed: () => speed, landings: () => landings.slice(),
    live: live, isFollowing: () => follow };
})();

window.allsky = {
  /** Show mission time t_s [s] (a number or numeric string, clamped to the record; anything
   *  else leaves the time as it is); returns state(). */
  seek: APP.seek,
  /** {t_s, mode, switches {S1..S19}, selector, counters_pulses {14, 16, 18}, row_t_s, target,
   *  status, true_error_arcsec, body_rate_deg_s {roll, pitch, yaw} (the truth),
   *  gyro_output_deg_s {roll, pitch, yaw} (what the gyros say; null when not recorded),
   *  tracker_star, faults_active} at the time shown; S7/S8 are selectors, always true (their contact is
   *  ``selector``). */
  state: APP.state,
  /** Play at ``speed`` times real time (default: the speed selected). */
  play: APP.play,
  pause: APP.pause,
  isPlaying: APP.isPlaying,
  /** First and last telemetry time [s], and the mode timeline. */
  range: () => [T0, T1],
  timeline: () => D.timeline.map((m) => Object.assign({}, m)),
  /** The targets in flight order: name, start_s, end_s [s]. */
  targets: () => TARGETS.map((x) => ({ name: x.name, start_s: x.start_s, end_s: x.end_s })),
  events: () => D.events.map((e) => Object.assign({}, e)),
  /** The Moon and the planets at mission time t_s [s] (geocentric, as the sky map draws
   *  them): [{name, ra_deg, dec_deg, magnitude, phase, in_window, flown}]. */
  bodies: (t_s) => bodiesAt(Number(t_s)),
  timing: APP.timing,
  ready: false,
};
if (LIVE) {
  /** A live page: show the newest row and follow it (moving the clock back stops that). */
  window.allsky.live = APP.live;
  window.allsky.isFollowing = APP.isFollowing;
}
if (LIVE) APP.live(); else APP.seek(T0);
window.allsky.ready = true;
/** [ms] from the start of navigation to the page's first full drawing. */
window.allsky.readyAt_ms = performance.now();
