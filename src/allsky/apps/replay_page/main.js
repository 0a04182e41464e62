// main.js: the mission clock, header, event log, controls, keys and window.allsky.
const APP = (function () {
  let t = T0, playing = false, speed = 50, lastFrame = null, currentEvent = -1, lastMode = "";
  const $ = (id) => document.getElementById(id);
  const scrub = $("scrub"), playBtn = $("btn-play"), speedSel = $("speed");
  const boundaries = D.timeline.map((m) => m.start_s).concat([T1]);
  const modeStarts = [];  // [row, name] of each run of the mode column
  for (const [row, code] of C.runs.mode) modeStarts.push([row, modeName(code)]);
  const timing = { lastDrawMs: 0, draws: 0, parts: {} };

  function modeStartRow(i) {
    let r = 0;
    for (const [row] of modeStarts) if (row <= i) r = row;
    return r;
  }

  // Header: the mode, its title and sentence from the mode table, what the sequencer awaits.
  function header(s) {
    const m = D.modes[s.mode] || { title: "unknown mode", sentence: "", look: "" };
    if (s.mode !== lastMode) {
      lastMode = s.mode;
      $("mode-name").textContent = s.mode === "hold" ? "Hold" : `Mode ${s.mode}`;
      $("mode-badge").style.background = modeColour(s.mode);
      $("mode-title").textContent = m.title.charAt(0).toUpperCase() + m.title.slice(1);
      $("mode-sentence").textContent = m.sentence;
      $("mode-look").textContent = m.look ? `Look: ${m.look}` : "";
    }
    $("clock").textContent = `t = ${t.toFixed(1)} s`;
    const ev = inForce(D.events.filter((e) => e.waiting !== undefined && e.waiting !== null), t);
    const rec = D.timeline.find((r) => r.start_s <= t + 1e-9 && t <= r.end_s + 1e-9);
    let now = ev && ev.waiting ? `Now: waiting for ${ev.waiting}` : "";
    if (rec && rec.exit.startsWith("aborted") && t >= rec.end_s - 1.0) now = `Mission ${rec.exit}`;
    if (s.mode === "1") now += " (the Mode 1 sun-acquisition controller, not drawn in the patent's "
      + "diagram, drives the control amplifiers)";
    $("mode-now").textContent = now;
  }

  function registersLine(s) {
    const w = inForce(D.registers["23"], t), p = inForce(D.registers["24"], t);
    const as = (v) => `${fmt(v * 206264.806, 1)}\u2033`;
    let text = D.registers.known
      ? `reg. 23${WORD_MARK[w.source] || ""}: SF roll ${w.sf_roll.toFixed(6)}, SF yaw ${w.sf_yaw.toFixed(6)}, roll\u2192pitch ${as(w.roll_into_pitch)}, `
        + `roll\u2192yaw ${as(w.roll_into_yaw)}, yaw\u2192pitch ${as(w.yaw_into_pitch)}, yaw\u2192roll ${as(w.yaw_into_roll)}`
      : "reg. 23/24: not in the telemetry (replay with --summary)";
    if (D.registers.known) text += p ? ` \u00b7 reg. 24 (${p.target}): roll ${fmt(p.roll_deg, 4)}\u00b0, yaw ${fmt(p.yaw_deg, 4)}\u00b0` : " \u00b7 reg. 24: empty";
    if ($("registers-line").textContent !== text) $("registers-line").textContent = text;
  }

  // Event log.
  const list = $("events"), items = [];
  D.events.forEach((e, k) => {
    const li = document.createElement("li");
    const tt = document.createElement("span"); tt.className = "t"; tt.textContent = e.t_s.toFixed(1);
    const tx = document.createElement("span"); tx.className = `kind-${e.kind}`;
    tx.textContent = e.kind === "switch" ? `Switches: ${e.text}` : e.kind === "action" ? `Action: ${e.text}` : e.text;
    const why = document.createElement("span"); why.className = "why";
    why.textContent = e.kind === "switch" ? `why: ${e.reason}${e.waiting ? `; then waits for ${e.waiting}` : ""}`
      : `why: ${e.reason}`;
    if (e.detail) li.title = e.detail;
    li.append(tt, tx, why);
    li.dataset.k = k;
    li.addEventListener("click", () => seek(e.t_s));
    list.appendChild(li); items.push(li);
  });

  function eventLog() {
    let cur = -1;
    for (let k = 0; k < D.events.length; k++) if (D.events[k].t_s <= t + 1e-9) cur = k;
    if (cur === currentEvent) return;
    currentEvent = cur;
    items.forEach((li, k) => { li.className = k < cur ? "past" : k === cur ? "current" : "future"; });
    if (cur >= 0) {
      const li = items[cur], box = list.getBoundingClientRect(), r = li.getBoundingClientRect();
      if (r.top < box.top || r.bottom > box.bottom) list.scrollTop += r.top - box.top - box.height / 3;
    }
  }

  // Controls.
  scrub.min = T0; scrub.max = T1; scrub.step = D.config.interval_s;
  const strip = $("mode-strip");
  for (const m of D.timeline) {
    const d = document.createElement("div");
    d.style.width = `${100 * (m.end_s - m.start_s) / Math.max(T1 - T0, 1e-9)}%`;
    d.style.background = modeColour(m.mode);
    d.title = `Mode ${m.mode}: ${(D.modes[m.mode] || {}).title || ""}`;
    strip.appendChild(d);
  }
  scrub.addEventListener("input", () => seek(+scrub.value));
  playBtn.addEventListener("click", () => (playing ? pause() : play()));
  speedSel.addEventListener("change", () => { speed = +speedSel.value; });
  $("btn-prev").addEventListener("click", () => prevMode());
  $("btn-next").addEventListener("click", () => nextMode());
  $("btn-back").addEventListener("click", () => seek(t - 10));
  $("btn-fwd").addEventListener("click", () => seek(t + 10));
  $("btn-help").addEventListener("click", () => { $("help").hidden = !$("help").hidden; });
  $("btn-help-close").addEventListener("click", () => { $("help").hidden = true; });
  for (const n of D.notes) { const li = document.createElement("li"); li.textContent = n; $("notes").appendChild(li); }

  function prevMode() {
    const b = boundaries.filter((x) => x < t - 0.05);
    seek(b.length ? b[b.length - 1] : T0);
  }
  function nextMode() {
    const b = boundaries.find((x) => x > t + 0.05);
    seek(b === undefined ? T1 : b);
  }
  function stepSpeed(dir) {
    const opts = Array.from(speedSel.options).map((o) => +o.value);
    const k = Math.max(0, Math.min(opts.length - 1, opts.indexOf(speed) + dir));
    speed = opts[k]; speedSel.value = String(speed);
  }

  window.addEventListener("keydown", (e) => {
    if (e.target && (e.target.tagName === "SELECT" || e.target.tagName === "INPUT") && e.key !== " ") {
      if (e.target.tagName === "SELECT") return;
    }
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
      "?": () => { $("help").hidden = !$("help").hidden; },
      "Escape": () => { $("help").hidden = true; },
    }[e.key];
    if (handled) { e.preventDefault(); handled(); }
  });

  function redraw() {
    const t0 = performance.now(), parts = timing.parts;
    const i = rowAt(t), s = rowState(i);
    let a = performance.now();
    const lap = (name) => { const b = performance.now(); parts[name] = b - a; a = b; };
    header(s); registersLine(s); eventLog(); lap("text");
    DIAGRAM.update(s, t); lap("diagram");
    VEHICLE.draw(s, t); lap("vehicle");
    SKY.draw(s, t, modeStartRow(i)); lap("sky");
    TRACES.draw(s, t); lap("traces");
    if (+scrub.value !== t) scrub.value = t;
    timing.lastDrawMs = performance.now() - t0;
    timing.draws += 1;
  }

  /** Show mission time ``ts`` [s], coerced to a number and clamped; NaN/infinite: ignored. */
  function seek(ts) {
    const v = Number(ts);
    if (Number.isFinite(v)) {
      t = Math.max(T0, Math.min(T1, v));
      redraw();
    }
    return state();
  }

  function frame(now) {
    if (!playing) return;
    if (lastFrame !== null) {
      t = Math.min(T1, t + (now - lastFrame) / 1000 * speed);
      redraw();
      if (t >= T1) { pause(); return; }
    }
    lastFrame = now;
    requestAnimationFrame(frame);
  }

  function play(s) {
    if (s) { speed = +s; speedSel.value = String(speed); }
    if (playing) return;
    if (t >= T1) t = T0;
    playing = true; lastFrame = null; playBtn.textContent = "pause";
    requestAnimationFrame(frame);
  }

  function pause() { playing = false; playBtn.textContent = "play \u25B6"; }

  /** What the page shows, in the documented form (the telemetry row at or before t). */
  function state() {
    const i = rowAt(t), mask = runValue(C.runs.switches, i), sw = {};
    for (let k = 1; k <= 19; k++) sw[`S${k}`] = switchClosed(mask, k);
    return { t_s: t, mode: modeName(runValue(C.runs.mode, i)), switches: sw,
      selector: AXIS_NAMES[+C.selector[i]],
      counters_pulses: { "14": EXACT.counter14[i], "16": EXACT.counter16[i], "18": EXACT.counter18[i] },
      row_t_s: T_MS[i] / 1000, target: TARGETS[targetAt(T_MS[i] / 1000)].name };
  }

  window.addEventListener("resize", () => redraw());
  return { seek: seek, redraw: redraw, play: play, pause: pause, state: state, timing: timing,
    isPlaying: () => playing, speed: () => speed };
})();

window.allsky = {
  /** Show mission time t_s [s] (a number or numeric string, clamped to the record; anything
   *  else leaves the time as it is); returns state(). */
  seek: APP.seek,
  /** {t_s, mode, switches {S1..S19}, selector, counters_pulses {14, 16, 18}, row_t_s, target}
   *  at the time shown; S7/S8 are selectors, always true (their contact is ``selector``). */
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
  timing: APP.timing,
  ready: false,
};
APP.seek(T0);
window.allsky.ready = true;
/** [ms] from the start of navigation to the page's first full drawing. */
window.allsky.readyAt_ms = performance.now();
