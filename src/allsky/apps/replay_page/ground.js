// ground.js: a live session (allsky serve). The WebSocket to the page's own origin, the
// ground's controls, window.allsky.command; the replay's modules (boot) show the flight as
// its rows and journal arrive.
(function () {
  const $ = (id) => document.getElementById(id);
  let booted = null;  // what boot() returned: {app, appendColumns, setJournal}
  let waiting = null;  // the session's data until its first row has come
  let ws = null, open = false, ended = false, canCommand = false, nextId = 1;
  const pending = {};  // command id -> {resolve, reject}
  const queued = [];  // commands sent before the socket opened
  const journal = [];
  let session = {}, clients = 0, lastWindow = "";
  const result = $("g-result");

  function say(text, refused) {
    result.textContent = text;
    result.className = refused ? "refused" : "";
  }

  function wsUrl() {
    const have = booted ? `&since_s=${window.allsky.range()[1]}&journal=${journal.length}` : "";
    return `ws://${location.host}/ws${location.search}${have}`;
  }

  function connect() {
    ws = new WebSocket(wsUrl());
    ws.onopen = () => { open = true; while (queued.length) ws.send(queued.shift()); };
    ws.onmessage = (ev) => receive(JSON.parse(ev.data));
    ws.onclose = () => {
      open = false;
      if (ended) return;
      $("link-state").textContent = "connection lost: reconnecting\u2026";
      $("live-badge").className = "badge offline";
      setTimeout(connect, 1000);
    };
  }

  function ack() {
    // After the next drawing: the server sends no faster than the page shows.
    requestAnimationFrame(() => { if (open) ws.send(JSON.stringify({ type: "ack" })); });
  }

  function pageData(data, page, columns) {
    const d = Object.assign({}, data, page);
    d.sky = Object.assign({}, data.sky, { targets: page.targets, locked: page.locked });
    delete d.targets; delete d.locked;
    d.columns = columns;
    return d;
  }

  function receive(msg) {
    if (msg.type === "done" || msg.type === "refused") return answered(msg);
    if (msg.type === "ended") return endedSession(msg);
    if (msg.type === "hello") {
      canCommand = msg.can_command;
      if (msg.watch_url) { $("g-watch-url").value = msg.watch_url; $("g-share").hidden = false; }
      if (msg.remote) {
        $("g-remote").hidden = false;
        $("g-remote").textContent = "open to the network: anyone with the link can watch, or command";
      }
      for (const b of document.querySelectorAll("#ground button, #ground select, #ground input"))
        if (!["g-live", "g-watch-url"].includes(b.id)) b.disabled = !canCommand;
      if (!canCommand) say("This link watches the session; commands need the commanding link.");
      if (booted) {  // a reconnection: what was missed
        take(msg.columns, msg.journal, msg.page);
      } else {
        journal.push(...msg.journal);
        waiting = { data: msg.data, page: msg.page };
        if (msg.columns) start(msg.columns);
      }
    } else if (msg.type === "update") {
      if (!booted && waiting) {
        if (msg.journal) journal.push(...msg.journal);
        if (msg.page) waiting.page = msg.page;
        if (msg.columns) start(msg.columns);
      } else if (booted) {
        take(msg.columns, msg.journal, msg.page);
      }
    }
    if (msg.session) { session = msg.session; clients = msg.clients; status(); }
    settle();
    ack();
  }

  function start(columns) {
    booted = boot(pageData(waiting.data, waiting.page, columns));
    waiting = null;
    Object.assign(window.allsky, API);
    controls();
  }

  function take(columns, entries, page) {
    if (entries) journal.push(...entries);
    if (page) booted.setJournal(Object.assign({}, page));
    if (columns) booted.appendColumns(columns);
    if (page) { faultList(page); if (session) status(); }  // the badge reads the ending
  }

  // Commands applied whose entries have not yet reached the page's journal.
  const arriving = [];
  function settle() {
    for (let k = arriving.length - 1; k >= 0; k--) {
      const a = arriving[k];
      if (journal.some((e) => JSON.stringify(e) === a.key)) { arriving.splice(k, 1); a.resolve(a.entry); }
    }
  }

  function answered(msg) {
    const p = pending[msg.id];
    delete pending[msg.id];
    if (msg.type === "done") {
      say(`${msg.entry.text}: at ${msg.entry.t_s.toFixed(2)} s`);
      // The promise resolves once the entry is in the journal the page holds.
      if (p) { arriving.push({ key: JSON.stringify(msg.entry), entry: msg.entry, resolve: p.resolve }); settle(); }
    } else {
      say(`refused: ${msg.error}`, true);
      if (p) p.reject(new Error(msg.error));
    }
  }

  function endedSession(msg) {
    ended = true;
    session = msg.session || session;
    status();
    $("live-badge").textContent = "ENDED";
    $("live-badge").className = "badge ended";
    const written = (msg.written || []).join(", ");
    say(`The session has ended${written ? `; written: ${written}` : ""}.`);
    for (const b of document.querySelectorAll("#ground button, #ground select, #ground input"))
      if (b.id !== "g-live") b.disabled = true;
    for (const id in pending) { pending[id].reject(new Error("the session has ended")); delete pending[id]; }
  }

  function status() {
    if (ended) { $("link-state").textContent = `t = ${(session.t_s || 0).toFixed(1)} s`; return; }
    const paused = session.paused;
    const ending = booted && booted.data && booted.data.ending;
    const judged = session.status === "complete" && ending && ending.judged
      && ending.judged.tone === "amber";  // complete, with warnings: never a plain success
    $("live-badge").textContent = session.status === "running" ? (paused ? "PAUSED" : "LIVE")
      : judged ? "COMPLETE, AS JUDGED" : (session.status || "LIVE").toUpperCase();
    $("live-badge").className = `badge${paused ? " paused" : ""}${judged ? " judged" : ""}`;
    $("live-badge").title = judged ? `complete, as the sequencer judged: \u26a0 ${ending.judged.first_warning}` : "";
    const mode = session.mode ? `, Mode ${session.mode}` : "";
    $("link-state").textContent = `t = ${(session.t_s || 0).toFixed(1)} s${mode} \u00b7 \u00d7${session.speed}`
      + ` \u00b7 ${clients} watching`;
    const pb = $("g-pause");
    pb.setAttribute("aria-pressed", paused ? "true" : "false");
    pb.textContent = paused ? "resume" : "pause";
    const sp = $("g-speed");
    if (sp.value !== String(session.speed) && document.activeElement !== sp) {
      if (![...sp.options].some((o) => o.value === String(session.speed))) {
        const o = document.createElement("option"); o.value = String(session.speed);
        o.textContent = String(session.speed); sp.appendChild(o);
      }
      sp.value = String(session.speed);
    }
    const gate = $("g-gate");
    gate.setAttribute("aria-pressed", session.bright_gate ? "true" : "false");
    gate.textContent = session.bright_gate ? "bright gate: on" : "bright gate: off";
    if (session.window) {
      for (const [id, v] of [["g-win-bright", session.window[0]], ["g-win-faint", session.window[1]]])
        if (document.activeElement !== $(id) && lastWindow !== String(session.window)) $(id).value = v;
      lastWindow = String(session.window);
    }
  }

  /** Send ``cmd`` (a ground command: {kind, fields}); resolves with its journal entry. */
  function command(cmd) {
    return new Promise((resolve, reject) => {
      if (ended) { reject(new Error("the session has ended")); return; }
      const id = nextId++;
      pending[id] = { resolve: resolve, reject: reject };
      const text = JSON.stringify({ type: "command", id: id, command: cmd });
      if (open) ws.send(text); else queued.push(text);
    });
  }

  function send(cmd) {
    command(cmd).catch(() => {});  // the outcome is said in #g-result
  }

  // -- the controls ----------------------------------------------------------------
  const FIELDS = {
    axis: { label: "axis", options: () => GROUND.axes.map((a) => [a, a]) },
    sign: { label: "sign", options: () => [["1", "+"], ["-1", "\u2212"]], number: true },
    jets: { label: "jets", options: () => [["", "both (default)"], ["2", "both"], ["1", "one"]], number: true },
    size_deg_h: { label: "size [deg/h]", number: true },
    size_ppm: { label: "size [ppm]", number: true },
    offset_deg: { label: "offset [deg]", number: true },
    magnitude: { label: "magnitude [mag]", number: true },
    star: { label: "star", list: "g-stars" },
    register: { label: "register", options: () => GROUND.registers.map((r) => [r, r]) },
    bit: { label: "bit", number: true, integer: true },
    rate_kg_s: { label: "rate [kg/s]", number: true },
    torque_n_m: { label: "torque roll,pitch,yaw [N m]", vector: true },
    vent_position_m: { label: "vent at x,y,z [m]", vector: true },
    vent_direction: { label: "vent direction x,y,z", vector: true },
  };
  let GROUND = null, controlsBuilt = false;

  function faultFields() {
    const kind = GROUND.fault_kinds.find((k) => k.name === $("g-fault-kind").value);
    const box = $("g-fault-fields");
    box.replaceChildren();
    for (const [name, optional] of kind.fields.map((f) => [f, false]).concat(kind.optional.map((f) => [f, true]))) {
      const spec = FIELDS[name] || { label: name };
      const id = `g-f-${name}`;
      const label = document.createElement("label");
      label.htmlFor = id; label.textContent = ` ${spec.label}${optional ? " (optional)" : ""} `;
      let input;
      if (spec.options) {
        input = document.createElement("select");
        for (const [v, t] of spec.options()) {
          const o = document.createElement("option"); o.value = v; o.textContent = t; input.appendChild(o);
        }
      } else {
        input = document.createElement("input");
        input.type = spec.number ? "number" : "text";
        if (spec.number) input.step = "any";
        if (spec.list) input.setAttribute("list", spec.list);
        input.size = spec.vector ? 14 : 8;
      }
      input.id = id; input.dataset.field = name; input.dataset.optional = optional ? "1" : "";
      box.append(label, input);
    }
    $("g-fault-meaning").textContent = `${kind.name}: ${kind.meaning}; acts on block${kind.blocks.length > 1 ? "s" : ""} `
      + kind.blocks.filter((b) => b).join(", ") + (kind.blocks.includes("") ? " the tank" : "");
  }

  function faultCommand() {
    const cmd = { kind: "fault", fault_kind: $("g-fault-kind").value };
    for (const input of $("g-fault-fields").querySelectorAll("[data-field]")) {
      const name = input.dataset.field, spec = FIELDS[name] || {}, v = input.value.trim();
      if (v === "" && input.dataset.optional) continue;
      if (spec.vector) cmd[name] = v.split(/[\s,]+/).filter((x) => x).map(Number);
      else if (spec.number) cmd[name] = spec.integer ? parseInt(v, 10) : Number(v);
      else cmd[name] = v;
    }
    const d = $("g-fault-duration").value.trim();
    if (d !== "") cmd.duration_s = Number(d);
    return cmd;
  }

  function targetCommand(text) {
    const parts = text.trim().split(/[\s,]+/);
    if (parts.length === 2 && parts.every((p) => p !== "" && Number.isFinite(Number(p))))
      return { kind: "target", ra_deg: Number(parts[0]), dec_deg: Number(parts[1]) };
    return { kind: "target", star: text.trim() };
  }

  function faultList(page) {
    const ul = $("g-faults");
    ul.replaceChildren();
    for (const f of page.active_faults || []) {
      const li = document.createElement("li");
      li.textContent = `fault ${f.index}: ${f.text}`;
      const b = document.createElement("button");
      b.type = "button"; b.textContent = "clear"; b.disabled = !canCommand || ended;
      b.setAttribute("aria-label", `clear fault ${f.index}: ${f.text}`);
      b.addEventListener("click", () => send({ kind: "clear_fault", fault: f.index }));
      li.appendChild(b);
      ul.appendChild(li);
    }
  }

  function controls() {
    if (controlsBuilt) return;
    controlsBuilt = true;
    const D = booted.data;
    GROUND = D.ground;
    const sp = $("g-speed");
    for (const v of GROUND.speeds) {
      const o = document.createElement("option"); o.value = String(v); o.textContent = String(v); sp.appendChild(o);
    }
    sp.value = String(session.speed);
    const dl = $("g-stars");
    for (const name of GROUND.stars) { const o = document.createElement("option"); o.value = name; dl.appendChild(o); }
    const fk = $("g-fault-kind");
    for (const k of GROUND.fault_kinds) {
      const o = document.createElement("option"); o.value = k.name; o.textContent = k.name.replace(/_/g, " "); fk.appendChild(o);
    }
    fk.addEventListener("change", faultFields);
    faultFields();
    $("g-pause").addEventListener("click", () => send({ kind: session.paused ? "resume" : "pause" }));
    sp.addEventListener("change", () => send({ kind: "speed", speed: Number(sp.value) }));
    $("g-live").addEventListener("click", () => window.allsky.live());
    for (const k of ["hold", "proceed", "reacquire", "recycle"])
      $(`g-${k}`).addEventListener("click", () => send({ kind: k }));
    $("g-inject").addEventListener("click", () => send(faultCommand()));
    $("g-upload").addEventListener("click", () => send(targetCommand($("g-target").value)));
    $("g-target").addEventListener("keydown", (e) => { if (e.key === "Enter") send(targetCommand($("g-target").value)); });
    $("g-window").addEventListener("click", () => send({ kind: "tracker_window",
      magnitude_window: [Number($("g-win-bright").value), Number($("g-win-faint").value)] }));
    $("g-gate").addEventListener("click", () => send({ kind: "bright_gate",
      enabled: $("g-gate").getAttribute("aria-pressed") !== "true" }));
    const dlg = $("g-end-dialog");
    $("g-end").addEventListener("click", () => { dlg.showModal(); $("g-end-cancel").focus(); });
    $("g-end-cancel").addEventListener("click", () => dlg.close());
    $("g-end-now").addEventListener("click", () => { dlg.close(); send({ kind: "end" }); });
  }

  const API = {
    /** Send a ground command ({kind, fields}); a Promise of its journal entry. */
    command: command,
    /** The session's journal as it has reached the page. */
    journal: () => journal.map((e) => Object.assign({}, e)),
    /** The live session: t_s, mode, status, speed, paused, ended, ... */
    session: () => Object.assign({}, session, { clients: clients, connected: open, ended: ended }),
    /** May this page command (the commanding link), or only watch? */
    canCommand: () => canCommand,
  };
  window.allsky = Object.assign({ ready: false }, API);
  connect();
})();
