"""The mission replay: one self-contained HTML page that plays a flown mission.

:func:`replay_data` turns a telemetry table (and, when given, the mission
summary and the scenario) into compact JSON: the columns the page shows,
the block diagram's layout (:mod:`allsky.apps.diagram_layout`, boxes named
from :data:`allsky.hardware.blocks.BLOCKS`), the wiring table
(:data:`allsky.hardware.wiring.SWITCHES`), the mode table's titles and
sentences, the event log (:mod:`allsky.apps.replay_events`), the sky (Sun,
catalog, every target with the times it was flown, tracker slit) and the
word registers 23 and 24: one entry per write, so a mission that recycles
shows each calibration and each target's programmed angles in turn.
:func:`render_html` inlines the page's style and scripts
(``replay_page/``) and the data into one file; :func:`write_replay` writes
it. The page makes no network request: a Content-Security-Policy allows
only its own inline script and style.

Exactness. The switch bank, selectors S7/S8, counters, drift counters,
registers, valves and mode are kept at every telemetry row, as integers;
the continuous signals (attitude, rates, sensor outputs, amplifier
voltages) are rounded to well below what the page can draw (quaternion
1e-5, angles 0.1 arcsec) and, for missions longer than
:data:`MAX_CONTINUOUS_ROWS` rows, kept every few rows. ``window.allsky.state()``
reports the row at or before the time shown.

``allsky run --html PATH`` and ``allsky replay TELEMETRY [--summary JSON]
--html PATH`` call :func:`write_replay`; docs/replay.md describes the page.
"""

import hashlib
import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from allsky import units
from allsky.apps import diagram_layout as layout
from allsky.apps import replay_events
from allsky.computer import calibration_sequencer as cal19
from allsky.computer import cpu
from allsky.computer import word_registers as wr
from allsky.hardware import blocks, wiring
from allsky.sequencer import modes
from allsky.sim.telemetry import INDEX

#: Version of the page's data block.
DATA_FORMAT = 2
#: Rows above which the continuous columns are thinned (the exact ones never are).
MAX_CONTINUOUS_ROWS = 60_000
#: Continuous columns: name -> scale (stored as round(value * scale), delta-encoded).
CONTINUOUS = {
    "q_w": 1e5, "q_x": 1e5, "q_y": 1e5, "q_z": 1e5,
    "rate_x": units.RAD2ARCSEC, "rate_y": units.RAD2ARCSEC, "rate_z": units.RAD2ARCSEC,
    "sun_pitch": 10.0, "sun_yaw": 10.0, "tracker_yaw": 10.0, "tracker_pitch": 10.0,
    "error_roll": 10.0, "error_pitch": 10.0, "error_yaw": 10.0,
    "corrected_roll": 10.0, "corrected_yaw": 10.0, "intermediate_pitch": 10.0,
    "amp31": 1e4, "amp32": 1e4, "amp33": 1e4, "propellant": 1e5,
}
#: Integer columns kept exactly at every row (delta-encoded).
EXACT = ("counter14", "counter16", "counter18", "drift_counter13", "drift_counter15",
         "drift_counter17", "register25", "register26", "register27")
#: Flag columns kept as runs ``[[first row, value], ...]``.
RUNS = ("mode", "switches", "sun_present", "star_present", "overflow")
#: The page's parts, inlined in this order.
STYLE_FILES = ("replay.css",)
SCRIPT_FILES = ("util.js", "diagram.js", "vehicle3d.js", "skymap.js", "traces.js", "main.js")


def _delta(ints) -> list:
    ints = np.asarray(ints, dtype=np.int64)
    return np.diff(ints, prepend=np.int64(0)).tolist()


def _runs(values) -> list:
    values = np.asarray(values)
    if len(values) == 0:
        return []
    starts = np.r_[0, np.flatnonzero(values[1:] != values[:-1]) + 1]
    return [[int(i), float(values[i]) if values[i] % 1 else int(values[i])] for i in starts]


def _encode_columns(table) -> dict:
    """The telemetry columns the page needs, compact (see the module docstring)."""
    n = len(table)
    stride = max(1, math.ceil(n / MAX_CONTINUOUS_ROWS))
    t_ms = np.round(table[:, INDEX["time"]] * 1000.0).astype(np.int64)
    cont_rows = np.arange(0, n, stride)
    out = {"n": n, "t_ms": _delta(t_ms), "stride": stride,
           "exact": {c: _delta(np.round(table[:, INDEX[c]])) for c in EXACT},
           "runs": {c: _runs(table[:, INDEX[c]]) for c in RUNS},
           "cont": {c: {"scale": s, "d": _delta(np.round(table[cont_rows, INDEX[c]] * s))}
                    for c, s in CONTINUOUS.items()},
           "selector": "".join("012"[int(v)] for v in table[:, INDEX["s7_s8"]]),
           "valves": ["".join("012"[int(v) + 1] for v in table[:, INDEX[c]])
                      for c in ("valve_roll", "valve_pitch", "valve_yaw")]}
    return out


def _first_numeral_block(numeral):
    return next(b for b in blocks.BLOCKS if b.numerals and b.numerals[0] == numeral)


def _switches_between(a, b) -> list:
    """Numbers of the switches from block ``a`` to block ``b`` (wiring table)."""
    src = set(_first_numeral_block(a).numerals)
    dst = set(_first_numeral_block(b).numerals)
    return [s.number for s in wiring.SWITCHES
            if src & set(s.source.split("/")) and dst & set(s.destination.split("/"))]


def _edge(box, side):
    x, y, w, h = box
    return {"left": (x, y + h / 2), "right": (x + w, y + h / 2), "top": (x + w / 2, y + h),
            "bottom": (x + w / 2, y)}[side]


def diagram() -> dict:
    """The block diagram as data: boxes, frames, and lines with their switches."""
    boxes = {}
    for numeral, box in layout.BOXES.items():
        b = _first_numeral_block(numeral)
        boxes[numeral] = {"box": box, "label": b.label, "name": b.name,
                          "numerals": list(b.numerals), "module": b.modules[0]
                          if b.modules else "", "shaded": numeral in layout.SHADED}
    frames = {n: {"box": f, "label": _first_numeral_block(n).label}
              for n, f in layout.FRAMES.items()}
    lines = []
    for a, b, route in layout.ARROWS:
        A, B = layout.BOXES[a], layout.BOXES[b]
        if route == "h":
            right = A[0] < B[0]
            pts = [_edge(A, "right" if right else "left"), _edge(B, "left" if right else "right")]
        else:
            up = A[1] < B[1]
            pts = [_edge(A, "top" if up else "bottom"), _edge(B, "bottom" if up else "top")]
        lines.append({"from": a, "to": b, "points": pts, "switches": _switches_between(a, b)})
    for a, b, pts, _ in layout.ROUTES:
        lines.append({"from": a, "to": b, "points": [list(p) for p in pts],
                      "switches": _switches_between(a, b)})
    for a, b, pts, text in layout.VEHICLE_LINES:
        lines.append({"from": a, "to": b, "points": [list(p) for p in pts], "switches": [],
                      "text": text, "vehicle": True})
    switches = [{"n": s.number, "text": s.text, "label": wiring.label(s.number),
                 "axis": s.axis, "selector": s.selector, "coupled": s.coupled_with}
                for s in wiring.SWITCHES]
    return {"boxes": boxes, "frames": frames, "lines": lines, "switches": switches,
            "extent": layout.EXTENT}


def _mode_steps(action):
    """Mode name -> args of its ``Do(action)`` steps, for the modes that have one."""
    out = {}
    for m in modes.MODE_TABLE:
        found = [s.args for s in m.steps if isinstance(s, modes.Do) and s.action == action]
        if found:
            out[m.name] = found
    return out


def _targets(cfg, summary, timeline, t_end_s) -> list:
    """Every target begun, in flight order: name, direction, when it was flown.

    The summary's ``targets`` (or its one ``target``) when given, with their
    start times; else the scenario's, each begun by the first mode flown
    after the last target's Mode 6-2 (and hold). A target ends where the
    next begins, or with the record.
    """
    from allsky.sim import mission
    from allsky.vehicle import sky

    specs = mission.target_specs(cfg)
    records = (summary or {}).get("targets") or ([summary["target"]] if summary and
                                                 summary.get("target") else [])
    starts, flown = [timeline[0]["start_s"] if timeline else 0.0], False
    for r in timeline:
        if flown and r["mode"] not in (modes.TARGET_MODES[-1], modes.HOLD_MODE):
            starts.append(r["start_s"])
        flown = r["mode"] in (modes.TARGET_MODES[-1], modes.HOLD_MODE)
    count = max(len(records), min(len(starts), len(specs)))
    out = []
    for k in range(count):
        rec = dict(records[k]) if k < len(records) else {}
        spec = ({"star": rec["star"]} if "star" in rec else
                {"ra_deg": rec["ra_deg"], "dec_deg": rec["dec_deg"]} if "ra_deg" in rec
                else specs[min(k, len(specs) - 1)])
        vec = (sky.star_direction_inertial(spec["star"], cfg.mission.date_utc) if "star" in spec
               else sky.radec_to_unit(spec["ra_deg"], spec["dec_deg"]))
        start = rec.get("start_s", starts[k] if k < len(starts) else starts[-1])
        out.append({"index": k, "name": rec.get("name") or mission.target_name(spec),
                    "vec": [float(v) for v in vec], "start_s": float(start),
                    "programmed_roll_deg": rec.get("programmed_roll_deg"),
                    "programmed_yaw_deg": rec.get("programmed_yaw_deg")})
    for k, tgt in enumerate(out):
        tgt["end_s"] = float(out[k + 1]["start_s"] if k + 1 < len(out) else t_end_s)
    return out


def target_at(targets, t_s) -> dict:
    """The target being flown at mission time ``t_s`` [s]: the last one begun by then."""
    current = targets[0]
    for tgt in targets:
        if tgt["start_s"] <= t_s + 1e-9:
            current = tgt
    return current


def _sky(cfg, summary, targets) -> dict:
    """Sun, catalog, targets and tracker slit for the sky map and the 3-D view."""
    from allsky.sim import mission
    from allsky.vehicle import sky

    date = cfg.mission.date_utc
    lo, hi = cfg.star_tracker.magnitude_window
    params = mission.build_params(cfg)  # the Sun the mission flew with
    s0, sdot = params.sun0_inertial, params.sun_rate_inertial
    reference = (summary or {}).get("reference_star") or cfg.star_tracker.reference_star
    stars = [{"name": s["name"], "ra": round(s["ra_deg"], 3), "dec": round(s["dec_deg"], 3),
              "mag": s["magnitude"], "win": s["in_window"]}
             for s in sky.catalog(date, (lo, hi), reference)]
    return {"sun0": [float(v) for v in s0], "sun_rate": [float(v) for v in sdot],
            "targets": [{k: t[k] for k in ("name", "vec", "start_s", "end_s")}
                        for t in targets],
            "reference": reference, "locked": (summary or {}).get("locked_star"),
            "stars": stars, "window": [lo, hi], "date_utc": date.isoformat(),
            "slit_long_half_deg": float(cfg.star_tracker.fov_long_half_deg),
            "slit_narrow_half_deg": float(cfg.star_tracker.fov_narrow_half_deg),
            "sun_cone_half_deg": float(cfg.sun_sensor.presence_half_angle_deg)}


#: Register 23 word -> its slot (:mod:`allsky.computer.word_registers`), in page order.
WORD23 = {"sf_roll": wr.SF_ROLL, "sf_yaw": wr.SF_YAW, "roll_into_pitch": wr.ROLL_INTO_PITCH,
          "roll_into_yaw": wr.ROLL_INTO_YAW, "yaw_into_pitch": wr.YAW_INTO_PITCH,
          "yaw_into_roll": wr.YAW_INTO_ROLL}
#: Register 23 words each calibration writes: a turn's axis, or "all" (the dither).
WORDS_WRITTEN = {"roll": ("sf_roll", "roll_into_pitch", "roll_into_yaw"),
                 "yaw": ("sf_yaw", "yaw_into_pitch", "yaw_into_roll"), "all": tuple(WORD23)}


def _words(w) -> dict:
    return {name: float(w[slot]) for name, slot in WORD23.items()}


def _counted_words(table, record, axis, cfg):
    """Register 23's words of ``axis`` from the counters at the turn's last row, or None.

    Calibration sequencer 19 reads counters 14/16/18 at the last frame of the
    turn; the last telemetry row is at most one interval earlier, so these
    words differ from the stored ones by the few pulses counted in between.
    The true angle is the whole number of turns counted (one, or with
    ``sequencer.recovery`` the nearest whole number), of the counter's sign.
    """
    t = table[:, INDEX["time"]]
    i = int(np.searchsorted(t, record["end_s"] + 1e-6, side="right")) - 1
    code = modes.MODE_CODE[record["mode"]]
    if i < 0 or t[i] < record["start_s"] - 1e-6 or abs(table[i, INDEX["mode"]] - code) > 1e-6:
        return None
    counts = np.array([table[i, INDEX[c]] for c in ("counter14", "counter16", "counter18")])
    counts_arcsec = counts * cfg.electronics.vfc_pulse_weight_arcsec
    turned = counts_arcsec[0 if axis == "roll" else 2]
    if turned == 0.0:
        return None
    turns = (max(1, round(abs(turned) / cal19.FULL_TURN_ARCSEC)) if cfg.sequencer.recovery
             else 1)
    w = wr.neutral_computed()
    calibrate = cpu.calibrate_roll if axis == "roll" else cpu.calibrate_yaw
    calibrate(w, counts_arcsec, math.copysign(turns * cal19.FULL_TURN_ARCSEC, turned))
    return _words(w)


def _registers(summary, timeline, cfg, table, targets) -> dict:
    """Register 23's calibration words and register 24's angles, with when they were written.

    Every calibration flown writes its words when its mode ends (a mission
    that recycles calibrates once per target). The words the summary holds
    are the last ones written; each earlier one is computed from the
    counters (:func:`_counted_words`). ``source`` says which: "start"
    (neutral at ejection), "summary", "counters", "withheld" (neutral,
    ``calibration.apply`` false) or "later" (an earlier dither analysis,
    whose estimates the summary does not keep: the last one's words shown).
    """
    words = [{"t_s": 0.0, "source": "start", **_words(wr.neutral_computed())}]
    if summary is None:
        return {"23": words, "24": [], "known": False}
    cal = summary.get("calibration")
    applied = summary.get("calibration_applied", True)
    stored = None
    if cal and applied:
        sf, cc = cal["scale_factor"], cal["cross_coupling"]
        stored = {"sf_roll": sf["roll"], "sf_yaw": sf["yaw"], **cc}
    writers = {name: [a[0] if a else "all" for a in args]
               for name, args in {**_mode_steps("calibration_sequencer"),
                                  **_mode_steps("dither_analysis")}.items()}
    withholders = _mode_steps("withhold_calibration")
    flown = [r for r in timeline if not r["exit"].startswith("aborted")]
    last = {axis: max((k for k, r in enumerate(flown) if axis in writers.get(r["mode"], ())),
                      default=None) for axis in WORDS_WRITTEN}
    for k, r in enumerate(flown):
        if r["mode"] in withholders and not applied:
            words.append({**words[-1], "t_s": r["start_s"], "source": "withheld",
                          **_words(wr.neutral_computed())})
        for axis in writers.get(r["mode"], ()):
            if stored is not None and k == last[axis]:
                new, source = stored, "summary"
            elif axis == "all":
                new, source = stored, "later"
            else:
                new, source = _counted_words(table, r, axis, cfg), "counters"
            if new is not None:
                words.append({**words[-1], "t_s": r["end_s"], "source": source,
                              **{w: new[w] for w in WORDS_WRITTEN[axis]}})
    # Register 24 is loaded at the start of each Mode 6-1 with the angles of its target.
    loaders = _mode_steps("load_register_24")
    programmed = []
    for r in timeline:
        tgt = target_at(targets, r["start_s"])
        if r["mode"] in loaders and tgt["programmed_roll_deg"] is not None:
            programmed.append({"t_s": r["start_s"], "roll_deg": tgt["programmed_roll_deg"],
                               "yaw_deg": tgt["programmed_yaw_deg"], "target": tgt["name"]})
    return {"23": words, "24": programmed, "known": True}


def _timeline(table, summary, cfg) -> list:
    """The mode timeline: the summary's, or the telemetry's runs of mode code."""
    if summary and summary.get("modes"):
        return [dict(r) for r in summary["modes"]]
    t = table[:, INDEX["time"]]
    runs = replay_events.mode_runs(table)
    out = []
    for k, (row, name) in enumerate(runs):
        end = t[runs[k + 1][0]] if k + 1 < len(runs) else t[-1]
        mode = modes.BY_NAME.get(name)
        exit_text = mode.exit.format(cfg=cfg) if mode else ""
        out.append({"mode": name, "start_s": float(t[row]), "end_s": float(end),
                    "exit": exit_text})
    return out


def _config(cfg, table) -> dict:
    el = cfg.electronics
    t = table[:, INDEX["time"]]
    interval = float(np.median(np.diff(t))) if len(t) > 1 else float(cfg.mission.frame_s)
    return {"pulse_weight_arcsec": float(el.vfc_pulse_weight_arcsec),
            "register_lsb_arcsec": float(el.register_lsb_arcsec),
            "register_bits": int(el.register_bits), "drift_dac_bits": int(el.drift_dac_bits),
            "drift_lsb_arcsec_s": float(el.vfc_pulse_weight_arcsec / cfg.sequencer.drift_count_s),
            "rate_command_deg_s": float(el.rate_command_deg_s),
            "settle_threshold_arcsec": float(cfg.sequencer.settle_threshold_arcsec),
            "handover_arcsec": float(cfg.sequencer.handover_arcsec),
            "frame_s": float(cfg.mission.frame_s), "interval_s": round(interval, 6),
            "min_on_time_s": float(cfg.jets.min_on_time_s),
            "propellant_kg": float(cfg.jets.propellant_kg)}


def replay_data(table, summary=None, cfg=None) -> dict:
    """Everything the replay page shows, as JSON-serialisable data.

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry, :data:`allsky.sim.telemetry.COLUMNS` order, at least one row.
    summary : dict, optional
        The mission summary (:meth:`allsky.sim.mission.Mission.summary`): the
        timeline's exit texts, registers 23 and 24, the targets and when each
        was flown, the star locked.
    cfg : allsky.config.Scenario, optional
        The scenario flown (default: the packaged default): the date (Sun and
        stars), the tracker's slit and magnitude window, pulse and LSB weights.
    """
    if cfg is None:
        from allsky.config import load_scenario

        cfg = load_scenario(None, [])
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 2 or len(table) == 0:
        raise ValueError("the replay needs a telemetry table with at least one row")
    timeline = _timeline(table, summary, cfg)
    mode_info = {}
    for m in modes.MODE_TABLE:
        exit_text = next((r["exit"] for r in timeline if r["mode"] == m.name),
                         m.exit.format(cfg=cfg))
        mode_info[m.name] = {"code": m.code, "title": m.title,
                             "sentence": replay_events.mode_sentence(m.name, exit_text),
                             "look": replay_events.LOOK_FOR.get(m.name, "")}
    config = _config(cfg, table)
    info = {k: summary.get(k) for k in ("status", "abort_reason", "propellant_kg",
                                        "mission_time_s", "seed", "locked_star",
                                        "reference_star")} if summary else None
    if summary:
        info["pointing_error_arcsec"] = (summary.get("target") or {}).get(
            "pointing_error_arcsec")
    targets = _targets(cfg, summary, timeline, float(table[-1, INDEX["time"]]))
    registers = _registers(summary, timeline, cfg, table, targets)
    return {"format": DATA_FORMAT, "columns": _encode_columns(table), "timeline": timeline,
            "modes": mode_info, "events": replay_events.events(table, timeline),
            "diagram": diagram(), "sky": _sky(cfg, summary, targets),
            "registers": registers, "config": config,
            "summary": info, "notes": notes(config, registers)}


def notes(config, registers=None) -> list:
    """What the telemetry interval hides, in words, for the page."""
    dt = config["interval_s"]
    out = [(f"Telemetry is one row every {dt:g} s (the loop runs every "
            f"{config['frame_s']:g} s); the page shows the row at or before the time shown."),
           (f"Jet pulses shorter than {dt:g} s (the shortest is "
            f"{config['min_on_time_s']:g} s) fall between rows: a jet lights only when a row "
            "catches its valve open, so the lit jets are samples, not every pulse."),
           (f"A switch moves at a frame between two rows: its time is known to {dt:g} s; "
            "steps of the mode table inside one interval show as one change."),
           ("S7/S8 step every frame or few in the CPU modes: the selector shown is the "
            "contact sampled at each row.")]
    sources = {w["source"] for w in (registers or {}).get("23", ())}
    if "counters" in sources:
        out.append("Register 23: the summary keeps the last words written; those of an earlier "
                   "calibration are computed here from counters 14/16/18 at the last row of "
                   f"its turn, up to {dt:g} s before sequencer 19 read them (a few pulses; "
                   "marked \u2248).")
    if "later" in sources:
        out.append("Register 23: an earlier dither analysis's words are not kept; the last "
                   "analysis's are shown in their place (marked ?).")
    return out


def _asset(name) -> str:
    return resources.files("allsky.apps").joinpath("replay_page", name).read_text("utf-8")


def _csp_hash(text) -> str:
    import base64

    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def render_html(data) -> str:
    """The page: template, style and scripts inlined, ``data`` as a JSON block."""
    style = "\n".join(_asset(n) for n in STYLE_FILES)
    # One scope for the page's modules, nothing global but window.allsky.
    script = ("(function () {\n\"use strict\";\n" + "\n".join(_asset(n) for n in SCRIPT_FILES)
              + "\n})();\n")
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False)
    # Inside <script>, "</" would end the block; JSON allows the escaped form.
    payload = payload.replace("</", "<\\/")
    csp = (f"default-src 'none'; script-src {_csp_hash(script)}; style-src "
           f"{_csp_hash(style)}; img-src data:; connect-src 'none'; base-uri 'none'; "
           "form-action 'none'")
    page = _asset("replay.html")
    for key, value in (("CSP", csp), ("STYLE", style), ("DATA", payload),
                       ("SCRIPT", script)):
        page = page.replace("{{" + key + "}}", value, 1)
    return page


def write_replay(path, table, summary=None, cfg=None, option=None) -> Path:
    """Write the replay page of a flown mission to ``path`` (whole or not at all).

    ``option`` names the command-line option in an
    :class:`~allsky.apps.output.OutputError`. Returns the path.
    """
    from allsky.apps.output import write_atomic

    return write_atomic(path, render_html(replay_data(table, summary, cfg)), option=option)


def read_summary(path) -> dict:
    """A mission summary written by ``allsky run --json`` (ConfigError if not one)."""
    from allsky.apps.summaries import read_summary as read_checked

    return read_checked(path)


def run_from_cli(cfg, args) -> int:
    """``allsky replay TELEMETRY [--summary JSON] --html PATH``: write the page."""
    from allsky.apps.output import check_output
    from allsky.apps.telemetry_files import TelemetryError, read

    check_output("--html", args.html, suffixes=(".html", ".htm"))
    table, _ = read(args.telemetry)
    if len(table) == 0:
        raise TelemetryError(f"telemetry file {args.telemetry!r} has no rows: nothing to "
                             "replay")
    summary = read_summary(args.summary) if args.summary else None
    path = write_replay(args.html, table, summary, cfg, option="--html")
    if not getattr(args, "quiet", False):
        size_mb = path.stat().st_size / 1e6
        print(f"wrote replay {path} ({size_mb:.1f} MB, {len(table)} telemetry rows)")
    return 0
