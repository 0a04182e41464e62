"""The mission replay: one self-contained HTML page that plays a flown mission.

:func:`replay_data` turns a telemetry table (and, when given, the mission
summary and the scenario) into compact JSON: the columns the page shows
(as the telemetry schema, :data:`allsky.sim.recorder.COLUMNS`, says to
carry each), the block diagram's layout (:mod:`allsky.apps.diagram_layout`,
boxes named from :data:`allsky.hardware.blocks.BLOCKS`), the wiring table
(:data:`allsky.hardware.wiring.SWITCHES`), the mode table's titles and
sentences, the mission's journal (the summary's ``events``) and the event
log made from it (:mod:`allsky.apps.events`), the sky (Sun, catalog, every
target with the times it was flown, tracker slit) and the word registers 23
and 24 as the journal recorded each write, so a mission that recycles shows
each calibration and each target's programmed angles in turn; from the
journal and the summary also the star in the tracker's slit, each injected
fault (with the diagram boxes it acts on), the ending, the warnings and
register 23's true words, and who flew what (:func:`describe_scenario`).
:func:`render_html` inlines the page's style and scripts
(``replay_page/``) and the data into one file; :func:`write_replay` writes
it. The page makes no network request: a Content-Security-Policy allows
only its own inline script and style.

Exactness. The switch bank, selectors S7/S8, counters, drift counters,
registers, valves and mode are kept at every telemetry row, as integers
(delta-coded, a run of equal deltas written once as ``[delta, count]``);
the continuous signals (attitude, rates, sensor outputs, amplifier
voltages) are rounded to well below what the page can draw (quaternion
1e-5, angles 0.1 arcsec) and, for missions longer than
:data:`MAX_CONTINUOUS_ROWS` rows, kept every few rows. ``window.allsky.state()``
reports the row at or before the time shown.

``allsky run --html PATH`` and ``allsky replay TELEMETRY [--summary JSON]
--html PATH`` call :func:`write_replay`; docs/replay.md describes the page.
"""

import hashlib
import html
import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from allsky.apps import diagram_layout as layout
from allsky.apps import events as event_words
from allsky.hardware import blocks, wiring
from allsky.sequencer import modes
from allsky.sim import recorder
from allsky.sim.telemetry import COLUMNS, INDEX
from allsky.vocabulary import AXES, FAULT_KIND

#: Version of the page's data block.
DATA_FORMAT = 3
#: Rows above which the continuous columns are thinned (the exact ones never are).
MAX_CONTINUOUS_ROWS = 60_000
#: Continuous columns: name -> scale (stored as round(value * scale), delta-encoded), as
#: the telemetry schema says.
CONTINUOUS = {c.name: c.replay for c in COLUMNS if isinstance(c.replay, float)}
#: Integer columns kept exactly at every row (delta-encoded).
EXACT = tuple(c.name for c in COLUMNS if c.replay == recorder.EXACT)
#: Flag columns kept as runs ``[[first row, value], ...]``.
RUNS = tuple(c.name for c in COLUMNS if c.replay == recorder.RUNS)
#: The page's parts, inlined in this order.
STYLE_FILES = ("replay.css",)
SCRIPT_FILES = ("util.js", "diagram.js", "vehicle3d.js", "skymap.js", "traces.js", "main.js")
#: The live page's additions (``allsky serve``): its controls, their style and script.
GROUND_HTML, GROUND_STYLE, GROUND_SCRIPT = "ground.html", "ground.css", "ground.js"


def _delta(ints) -> list:
    """Deltas of an integer series, runs of three or more equal deltas as ``[delta, count]``."""
    d = np.diff(np.asarray(ints, dtype=np.int64), prepend=np.int64(0))
    if len(d) == 0:
        return []
    starts = np.r_[0, np.flatnonzero(d[1:] != d[:-1]) + 1]
    counts = np.diff(np.r_[starts, len(d)])
    out = []
    for start, count in zip(starts.tolist(), counts.tolist()):
        value = int(d[start])
        if count >= 3:
            out.append([value, count])
        else:
            out.extend([value] * count)
    return out


def undelta(encoded) -> np.ndarray:
    """The integer series :func:`_delta` encoded, as the page decodes it.

    ``encoded`` is the list of deltas, a run of equal deltas as ``[delta, count]``.
    """
    parts = [np.full(e[1], e[0], dtype=np.int64) if isinstance(e, list)
             else np.array([e], dtype=np.int64) for e in encoded]
    return np.cumsum(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)


def _runs(values) -> list:
    return [[i, float(v) if v % 1 else int(v)] for i, v in event_words.runs(values)]


def _encode_columns(table) -> dict:
    """The telemetry columns the page needs, compact (see the module docstring)."""
    n = len(table)
    stride = max(1, math.ceil(n / MAX_CONTINUOUS_ROWS))
    t_ms = np.round(table[:, INDEX["time"]] * 1000.0).astype(np.int64)
    cont_rows = np.arange(0, n, stride)
    # Columns a file of an earlier telemetry format lacks (NaN) are left out.
    recorded = {c.name for c in COLUMNS if not np.isnan(table[:, INDEX[c.name]]).any()}
    out = {"n": n, "t_ms": _delta(t_ms), "stride": stride,
           "exact": {c: _delta(np.round(table[:, INDEX[c]])) for c in EXACT if c in recorded},
           "runs": {c: _runs(table[:, INDEX[c]]) for c in RUNS if c in recorded},
           "cont": {c: {"scale": s, "d": _delta(np.round(table[cont_rows, INDEX[c]] * s))}
                    for c, s in CONTINUOUS.items() if c in recorded},
           "selector": "".join("012"[int(v)] for v in table[:, INDEX["s7_s8"]]),
           "valves": ["".join("012"[int(v) + 1] for v in table[:, INDEX[c]])
                      for c in ("valve_roll", "valve_pitch", "valve_yaw")]}
    return out


def encode_rows(table) -> dict:
    """Rows of telemetry encoded as the page's ``columns`` (a live page appends them).

    ``table`` holds the rows, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    return _encode_columns(np.asarray(table, dtype=np.float64))


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
                          "numerals": list(b.numerals), "plain": layout.PLAIN[numeral],
                          "shaded": numeral in layout.SHADED}
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
            "extent": layout.EXTENT, "two_line_titles": layout.TWO_LINE_TITLES,
            "plain_wheels": layout.PLAIN_WHEELS}


def _targets(cfg, summary, timeline, t_end_s) -> list:
    """Every target begun, in flight order: name, direction, when it was flown.

    The summary's ``targets`` (or its one ``target``), as the mission
    recorded them; without a summary, the scenario's, each begun as the
    telemetry's mode column first shows a new Mode 6-1 after a Mode 6-2 (or
    hold). A target ends where the next begins, or with the record.
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
    count = len(records) if records else min(len(starts), len(specs))
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
    """The target being flown at mission time ``t_s`` [s]: the last one begun by then.

    ``targets`` are the page's targets in flight order, each with its
    ``start_s`` [s] (the first is returned before any has begun).
    """
    current = targets[0]
    for tgt in targets:
        if tgt["start_s"] <= t_s + 1e-9:
            current = tgt
    return current


def _sky(cfg, summary, targets, span_s=None) -> dict:
    """Sun, catalog, bodies, targets and tracker slit for the sky map and the 3-D view."""
    return sky_data(cfg, summary, targets, span_s)


#: [s] the step of the moving bodies' places in the page, which interpolates between them
#: (the Moon moves 0.09 deg in it, and departs from the straight line by under 0.01")
BODY_STEP_S = 600.0


def body_tracks(cfg, span_s) -> list:
    """The Moon and the planets over ``span_s`` [s] from ``cfg``'s date, for the page.

    Each: ``name``, ``mag`` and ``phase`` at the start, ``win`` (inside the
    tracker's magnitude window), ``flown`` (the tracker sees the bodies:
    ``star_tracker.moving_bodies``), and ``ra``, ``dec`` [deg] every
    :data:`BODY_STEP_S` from 0 (``step_s``). The places are geocentric: from
    a low orbit the Moon is up to 1 deg elsewhere (the tracker flies the
    place seen from the vehicle), a planet under 0.001 deg.
    """
    from allsky.sim import sky_rows
    from allsky.vehicle import bodies, sky

    date = cfg.mission.date_utc
    lo, hi = cfg.star_tracker.magnitude_window
    flown = sky_rows.bodies_flown(cfg)
    n = math.ceil(span_s / BODY_STEP_S) + 1
    out = []
    for b in bodies.bodies(date):
        ra, dec = [], []
        for k in range(n):
            r = bodies.from_earth_km(b.name, date, k * BODY_STEP_S)
            a, d = sky.unit_to_radec(r)
            ra.append(round(float(a), 4))
            dec.append(round(float(d), 4))
        out.append({"name": b.name, "mag": round(float(b.magnitude), 2),
                    "phase": round(float(b.phase), 3), "win": bool(lo <= b.magnitude <= hi),
                    "flown": flown, "step_s": BODY_STEP_S, "ra": ra, "dec": dec})
    return out


def sky_data(cfg, summary, targets, span_s=None) -> dict:
    """Sun, stars, bodies, ``targets``, slit; ``summary`` names the stars (or None).

    ``cfg`` is the scenario flown: its date (the Sun, the catalog, the Moon
    and the planets over ``span_s`` [s]; None: the longest mission the
    scenario allows and an hour), the tracker's magnitude window, reference
    star and slit, the sun sensor's cone.
    """
    from allsky.sim.mission import orbit_span_s
    from allsky.vehicle import sky

    date = cfg.mission.date_utc
    lo, hi = cfg.star_tracker.magnitude_window
    s0, sdot = sky.sun_motion(date)  # the Sun the frame loop flew with
    reference = (summary or {}).get("reference_star") or cfg.star_tracker.reference_star
    stars = [{"name": s["name"], "ra": round(s["ra_deg"], 3), "dec": round(s["dec_deg"], 3),
              "mag": s["magnitude"], "win": s["in_window"]}
             for s in sky.catalog(date, (lo, hi), reference)]
    return {"sun0": [float(v) for v in s0], "sun_rate": [float(v) for v in sdot],
            "targets": [{k: t[k] for k in ("name", "vec", "start_s", "end_s")}
                        for t in targets],
            "reference": reference, "locked": (summary or {}).get("locked_star"),
            "stars": stars, "window": [lo, hi], "date_utc": date.isoformat(),
            "bodies": body_tracks(cfg, orbit_span_s(cfg) if span_s is None else span_s),
            "slit_long_half_deg": float(cfg.star_tracker.fov_long_half_deg),
            "slit_narrow_half_deg": float(cfg.star_tracker.fov_narrow_half_deg),
            "sun_cone_half_deg": float(cfg.sun_sensor.presence_half_angle_deg)}


def _registers(events) -> dict:
    """Registers 23 and 24 as the journal recorded each write (:func:`register_history`).

    Register 23's entries carry ``source``: "start" (neutral at ejection),
    "withheld" (made neutral, ``calibration.apply`` false) or "journal".
    Without a journal (no summary) nothing is known of them.
    """
    if events is None:
        return {"23": [{"t_s": 0.0, "source": "start",
                        **event_words.register_history([])["23"][0]}], "24": [],
                "known": False}
    history = event_words.register_history(events)
    words23 = [{**w, "source": "start" if w["by"] is None else
                ("withheld" if w["by"] == "withhold_calibration" else "journal")}
               for w in history["23"]]
    # The words a calibration has written by each entry (since the last withholding).
    writes = [e for e in events if e["kind"] == "register" and e["register"] == "23"]
    cleared = -math.inf
    for w in words23:
        if w["source"] == "withheld":
            cleared = w["t_s"]
        w["written"] = [] if w["source"] != "journal" else sorted(
            {e["word"] for e in writes if cleared < e["t_s"] <= w["t_s"]})
    return {"23": words23, "24": history["24"], "known": True}


def describe_scenario(path=None, overrides=()) -> dict:
    """Who flew what: a scenario's name, its description and the overrides given.

    Parameters
    ----------
    path : str or path-like, optional
        The scenario file, or a packaged scenario's name; None for the
        packaged default. The description is the file's leading comment
        lines, as the packaged scenarios write it.
    overrides : iterable of str
        The ``--set KEY=VALUE`` overrides flown over it.
    """
    from allsky.config.faults import packaged_or_path
    from allsky.config.schema import DEFAULT_SCENARIO_PATH

    file = Path(packaged_or_path(path) if path is not None else DEFAULT_SCENARIO_PATH)
    name = "default" if path is None else file.stem
    lines = []
    try:
        with open(file, encoding="utf-8") as f:
            for line in f:
                if not line.startswith("#"):
                    break
                lines.append(line.lstrip("#").strip())
    except OSError:
        pass
    title = lines[0] if lines else ""
    return {"name": name, "title": title, "description": " ".join(x for x in lines[1:] if x),
            "overrides": [str(o) for o in overrides]}


def _mission(cfg, summary, scenario) -> dict:
    """The mission's identity for the page: scenario, date, seed, vehicle."""
    return mission_data(cfg, summary, scenario)


def mission_data(cfg, summary, scenario) -> dict:
    """Who flew what (``scenario``), the date and seed (``summary``'s, else ``cfg``'s)."""
    scenario = dict(scenario or {"name": None, "title": "", "description": "",
                                 "overrides": []})
    seed = (summary or {}).get("seed", cfg.mission.seed)
    return {**scenario, "date_utc": cfg.mission.date_utc.isoformat(), "seed": int(seed)}


def _ending(summary, journal, t_end_s) -> dict:
    """How the mission ended, from the summary and the journal (None without a summary).

    ``status`` is the sequencer's ("complete", "aborted", or what an
    interrupted flight reports), ``t_s`` when it took effect (the abort's
    journal time, or the end of the flight), ``reason`` the abort's, and the
    truth at the end (the summary's ``end``): target, true pointing error,
    body rates, propellant used and left; ``judged`` is how every display
    words it (:func:`allsky.apps.verdict.judge`: a mission complete with
    warnings is "complete, as the sequencer judged", in amber).
    """
    from allsky.apps.verdict import judge

    if not summary:
        return None
    end = summary.get("end") or {}
    abort = next((e for e in journal if e["kind"] == "abort"), None)
    t_s = abort["t_s"] if abort else end.get("t_s", summary.get("mission_time_s", t_end_s))
    return {"status": summary.get("status"), "t_s": float(min(t_s, t_end_s)),
            "reason": summary.get("abort_reason") or (abort or {}).get("reason"),
            "mode": end.get("mode") or (abort or {}).get("mode"),
            "target": end.get("target"),
            "true_error_arcsec": end.get("true_pointing_error_arcsec"),
            "body_rate_deg_s": end.get("body_rate_deg_s"),
            "propellant_kg": end.get("propellant_kg", summary.get("propellant_kg")),
            "propellant_remaining_kg": end.get("propellant_remaining_kg"),
            "judged": judge(summary)}


def _warnings(summary, cfg) -> list:
    """The summary's warnings, each at the time it is about, from its journal."""
    from allsky.config.faults import describe
    from allsky.sim.braking import flight_warning
    from allsky.sim.journal import Journal
    from allsky.sim.results import timed_warnings

    if not summary or "events" not in summary or "targets" not in summary:
        return []
    out = timed_warnings(summary, Journal(summary["events"]), describe,
                         float(cfg.sequencer.settle_threshold_arcsec))
    braking = flight_warning(cfg, cfg.jets.propellant_kg - summary["propellant_kg"])
    return ([{"t_s": 0.0, "text": braking}] if braking is not None else []) + out


def fault_boxes(fault) -> list:
    """The diagram boxes a fault acts on: ``fault`` is a ``[[faults]]`` entry (dict).

    The vocabulary's :data:`~allsky.vocabulary.FAULT_KIND` names the block
    numerals a kind acts on; a fault with an axis acts on that axis's block
    (the pitch gyro is gyro 2), a counter upset on its register. Each numeral
    is drawn in the box whose block holds it; the tank (no numeral) in the
    vehicle's box.
    """
    kind = FAULT_KIND[fault["kind"]]
    numerals = list(kind.blocks)
    if fault.get("axis") in AXES and len(numerals) == 3:
        numerals = [numerals[AXES.index(fault["axis"])]]
    if fault.get("register") is not None:
        numerals = [str(fault["register"])]
    out = []
    for numeral in numerals:
        box = next((n for n in layout.BOXES if numeral and numeral in
                    _first_numeral_block(n).numerals), layout.VEHICLE_BOX)
        if box not in out:
            out.append(box)
    return out


def _faults(cfg, summary, journal, t_end_s) -> list:
    """Each injected fault as the journal recorded it: onset, end, the boxes it acts on."""
    specs = (summary or {}).get("faults") or cfg.as_dict().get("faults") or []
    out = {}
    for e in journal:
        if e["kind"] != "fault":
            continue
        k = e["fault"]
        if e["active"]:
            spec = specs[k] if k < len(specs) else {"kind": e["fault_kind"]}
            out[k] = {"index": k, "kind": e["fault_kind"], "text": e["text"],
                      "start_s": float(e["t_s"]), "end_s": None, "mode": e["mode"],
                      "boxes": fault_boxes({**spec, "kind": e["fault_kind"]}),
                      "axis": spec.get("axis")}
        elif k in out:
            out[k]["end_s"] = float(e["t_s"])
    return sorted(out.values(), key=lambda f: (f["start_s"], f["index"]))


def _tracker(journal) -> list:
    """The star in the tracker's slit over time, from the journal's ``star_lock`` entries."""
    return [{"t_s": float(e["t_s"]), "star": e["star"], "in_use": bool(e.get("in_use")),
             "cone_angle_deg": e.get("cone_angle_deg")}
            for e in journal if e["kind"] == "star_lock"]


def _truth23(summary, cfg) -> dict:
    """Register 23's true words (the scenario's gyros) and how far off a word is flagged.

    A word is flagged when its error, over a half turn (180 deg), would move
    the pointing by more than the sequencer's settle threshold: an error of
    ``settle_threshold_arcsec / 648000`` in a scale or cross-coupling factor.
    """
    truth = (summary or {}).get("truth")
    if not truth:
        return None
    words = {f"sf_{a}": truth["scale_factor"][a] for a in truth["scale_factor"]}
    words.update(truth["cross_coupling"])
    return {"words": {k: float(v) for k, v in words.items()},
            "flag_above": float(cfg.sequencer.settle_threshold_arcsec) / (180.0 * 3600.0)}


def _vehicle(cfg, table) -> dict:
    """The vehicle's actuators: jets, or reaction wheels (from the scenario or the record)."""
    wheel_cols = [INDEX[f"wheel_h_{a}"] for a in "xyz"]
    h = table[:, wheel_cols]
    return vehicle_data(cfg, bool(np.nan_to_num(np.abs(h)).max(initial=0.0) > 0.0))


def vehicle_data(cfg, flown_wheels=False) -> dict:
    """The vehicle's actuators: the scenario's, or wheels if ``flown_wheels``.

    ``cfg`` is the scenario flown (its ``actuators`` and ``wheels`` sections).
    """
    if cfg.actuators.kind != "wheels" and not flown_wheels:
        return {"kind": "jets"}
    return {"kind": "wheels", "axes": [list(map(float, a)) for a in cfg.wheels.axes],
            "max_momentum_n_m_s": float(np.max(cfg.wheels.max_momentum_n_m_s)),
            "unload_fraction": float(cfg.wheels.unload_fraction)}


def _timeline(table, summary, cfg) -> list:
    """The mode timeline: the summary's, or the telemetry's runs of mode code."""
    if summary and summary.get("modes"):
        return [dict(r) for r in summary["modes"]]
    t = table[:, INDEX["time"]]
    runs = mode_runs(table)
    out = []
    for k, (row, name) in enumerate(runs):
        end = t[runs[k + 1][0]] if k + 1 < len(runs) else t[-1]
        mode = modes.BY_NAME.get(name)
        exit_text = mode.exit.format(cfg=cfg) if mode else ""
        out.append({"mode": name, "start_s": float(t[row]), "end_s": float(end),
                    "exit": exit_text})
    return out


def mode_runs(table):
    """Runs of equal mode code in the telemetry: ``[(first row, mode name), ...]``.

    ``table`` is the telemetry, in :data:`allsky.sim.telemetry.COLUMNS` order.
    """
    names = {round(c, 6): n for n, c in modes.MODE_CODE.items()}
    return [(i, names.get(round(float(c), 6), "?"))
            for i, c in event_words.runs(table[:, INDEX["mode"]])]


def _config(cfg, table) -> dict:
    t = table[:, INDEX["time"]]
    interval = float(np.median(np.diff(t))) if len(t) > 1 else float(cfg.mission.frame_s)
    return config_data(cfg, interval)


def config_data(cfg, interval_s) -> dict:
    """The scenario's numbers the page uses; ``interval_s`` [s] between telemetry rows.

    ``cfg`` is the scenario flown (electronics, sequencer, jets, frame period).
    """
    el = cfg.electronics
    interval = float(interval_s)
    return {"pulse_weight_arcsec": float(el.vfc_pulse_weight_arcsec),
            "register_lsb_arcsec": float(el.register_lsb_arcsec),
            "register_bits": int(el.register_bits), "drift_dac_bits": int(el.drift_dac_bits),
            "drift_lsb_arcsec_s": float(el.vfc_pulse_weight_arcsec / cfg.sequencer.drift_count_s),
            "rate_command_deg_s": float(el.rate_command_deg_s),
            "settle_threshold_arcsec": float(cfg.sequencer.settle_threshold_arcsec),
            "handover_arcsec": float(cfg.sequencer.handover_arcsec),
            "frame_s": float(cfg.mission.frame_s), "interval_s": round(interval, 6),
            "min_on_time_s": float(cfg.jets.min_on_time_s),
            "propellant_kg": float(cfg.jets.propellant_kg),
            "cpu_modes": list(modes.cpu_modes())}


def replay_data(table, summary=None, cfg=None, scenario=None) -> dict:
    """Everything the replay page shows, as JSON-serialisable data.

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry, :data:`allsky.sim.telemetry.COLUMNS` order, at least one row.
    summary : dict, optional
        The mission summary (:meth:`allsky.sim.mission.Mission.summary`): the
        timeline's exit texts, the journal (event log, registers 23 and 24,
        the star in the slit, faults), the targets and when each was flown,
        the ending, the warnings, register 23's true words.
    cfg : allsky.config.Scenario, optional
        The scenario flown (default: the packaged default): the date (Sun and
        stars), the tracker's slit and magnitude window, pulse and LSB weights,
        the actuators.
    scenario : dict, optional
        Who flew what (:func:`describe_scenario`): name, description, overrides.
    """
    if cfg is None:
        from allsky.config import load_scenario

        cfg = load_scenario(None, [])
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 2 or len(table) == 0:
        raise ValueError("the replay needs a telemetry table with at least one row")
    timeline = _timeline(table, summary, cfg)
    config = _config(cfg, table)
    t_end_s = float(table[-1, INDEX["time"]])
    journal = (summary or {}).get("events")
    flown = journal_data(cfg, summary, timeline, t_end_s)
    targets, locked = flown.pop("targets"), flown.pop("locked")
    sky = _sky(cfg, summary, targets, t_end_s)
    sky["locked"] = locked
    return {"format": DATA_FORMAT, "columns": _encode_columns(table), **flown,
            "diagram": diagram(), "sky": sky, "config": config,
            "mission": _mission(cfg, summary, scenario), "vehicle": _vehicle(cfg, table),
            "notes": notes(config, journal is not None)}


def journal_data(cfg, summary, timeline, t_end_s) -> dict:
    """What the page shows from the journal and the summary: the parts a flight grows.

    ``cfg`` is the scenario flown, ``summary`` the mission's summary (None:
    not known), ``timeline`` its mode timeline (:func:`replay_data` takes
    it from the summary or the telemetry; a live session adds the mode in
    flight) and ``t_end_s`` [s] the last telemetry row's time. Keys:
    ``timeline``, ``modes`` (title, sentence and where to look, with the exit
    texts flown), ``events`` (the event log with the warnings), ``journal``,
    ``registers``, ``truth23``, ``summary``, ``ending``, ``warnings``,
    ``faults``, ``tracker``, ``targets`` (each begun, when it was flown) and
    ``locked`` (the star tracker 105 held).
    """
    mode_info = {}
    for m in modes.MODE_TABLE:
        exit_text = next((r["exit"] for r in timeline if r["mode"] == m.name and r["exit"]),
                         m.exit.format(cfg=cfg))
        mode_info[m.name] = {"code": m.code, "title": m.title,
                             "sentence": event_words.mode_sentence(m.name, exit_text),
                             "look": event_words.LOOK_FOR.get(m.name, "")}
    info = {k: summary.get(k) for k in ("status", "abort_reason", "propellant_kg",
                                        "mission_time_s", "seed", "locked_star",
                                        "reference_star")} if summary else None
    if summary:
        info["pointing_error_arcsec"] = (summary.get("target") or {}).get(
            "pointing_error_arcsec")
    targets = _targets(cfg, summary, timeline, t_end_s)
    journal = (summary or {}).get("events")
    registers = _registers(journal)
    warnings = _warnings(summary, cfg)
    log = event_words.page_log(journal or [])
    log += [{"t_s": w["t_s"], "kind": "warning", "mode": _mode_at(timeline, w["t_s"]),
             "text": w["text"], "reason": "a warning of the summary"} for w in warnings]
    log.sort(key=lambda e: e["t_s"])  # stable: a warning after the entries of its time
    return {"timeline": timeline, "modes": mode_info, "events": log, "journal": journal or [],
            "registers": registers, "truth23": _truth23(summary, cfg), "summary": info,
            "ending": _ending(summary, journal or [], t_end_s), "warnings": warnings,
            "faults": _faults(cfg, summary, journal or [], t_end_s),
            "tracker": _tracker(journal or []) if journal is not None else None,
            "targets": [{k: t[k] for k in ("name", "vec", "start_s", "end_s")}
                        for t in targets],
            "locked": (summary or {}).get("locked_star")}


def _mode_at(timeline, t_s):
    """The mode of the timeline at ``t_s`` [s] (the last begun by then)."""
    current = timeline[0]["mode"] if timeline else None
    for r in timeline:
        if r["start_s"] <= t_s + 1e-9:
            current = r["mode"]
    return current


def notes(config, journal=True) -> list:
    """What the telemetry interval hides, in words, for the page.

    ``config`` is the page's ``config`` (``interval_s``, ``frame_s``,
    ``min_on_time_s`` [s]); ``journal`` says whether the page has the
    mission's journal (a summary was given).
    """
    dt = config["interval_s"]
    out = [(f"Telemetry is one row every {dt:g} s (the loop runs every "
            f"{config['frame_s']:g} s); the page shows the row at or before the time shown."),
           (f"Jet pulses shorter than {dt:g} s (the shortest is "
            f"{config['min_on_time_s']:g} s) fall between rows: a jet lights only when a row "
            "catches its valve open, so the lit jets are samples, not every pulse."),
           ("The switch bank drawn is the row's: a switch moves at a frame between two "
            "rows (its time, to the frame, is in the event log)."),
           ("S7/S8 step every frame or few in the CPU modes: the selector shown is the "
            "contact sampled at each row.")]
    if journal:
        out.append("The event log and registers 23 and 24 are the mission's journal: each "
                   "entry at the frame it happened, not at a telemetry row.")
    else:
        out.append("No summary was given: without its journal the page shows no event log "
                   "and no register 23 or 24 words (allsky replay ... --summary JSON).")
    return out


def _asset(name) -> str:
    return resources.files("allsky.apps").joinpath("replay_page", name).read_text("utf-8")


def _csp_hash(text) -> str:
    import base64

    return "'sha256-" + base64.b64encode(hashlib.sha256(text.encode()).digest()).decode() + "'"


def page_title(data) -> str:
    """The page's ``<title>``: the scenario, how the mission ended, date and seed.

    ``data`` is the page's data (:func:`replay_data`).
    """
    m = data.get("mission") or {}
    ending = data.get("ending") or {}
    status = {"complete": "complete", "aborted": "ABORTED"}.get(ending.get("status"), "")
    if status == "complete" and (ending.get("judged") or {}).get("tone") == "amber":
        status = "complete, as the sequencer judged"
    date = (m.get("date_utc") or "")[:10]
    what = "allsky live" if data.get("live") else "allsky replay"
    parts = [f"{what}: {m.get('name') or 'mission'}"]
    if status:
        parts.append(status)
    parts.append(", ".join(x for x in (date, f"seed {m['seed']}" if "seed" in m else "") if x))
    return " \u2014 ".join(p for p in parts if p)


def page_script(live=False) -> str:
    """The page's script: its modules in one scope, nothing global but window.allsky.

    The replay decodes its data block at once; a live page (``live``) runs
    ``ground.js``, which boots the same modules when the session's data has
    come over the WebSocket.
    """
    modules = "\n".join(_asset(n) for n in SCRIPT_FILES)
    if not live:
        return ("(function () {\n\"use strict\";\n"
                "const D = JSON.parse(document.getElementById(\"allsky-data\").textContent);\n"
                + modules + "\n})();\n")
    return ("(function () {\n\"use strict\";\nfunction boot(D) {\n" + modules
            + "\nreturn { app: APP, appendColumns: appendColumns, setJournal: setJournal, data: D };"
            "\n}\n"
            + _asset(GROUND_SCRIPT) + "\n})();\n")


def render_html(data, connect=None) -> str:
    """The page: template, style and scripts inlined, ``data`` as a JSON block.

    With ``connect`` (a live session's WebSocket origin, ``ws://host:port``)
    the page is the live one (:mod:`allsky.apps.serve`): the ground's
    controls and script, and a Content-Security-Policy that lets it reach
    that origin and nothing else.
    """
    live = connect is not None
    style = "\n".join(_asset(n) for n in STYLE_FILES + ((GROUND_STYLE,) if live else ()))
    script = page_script(live)
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False)
    # Inside <script>, "</" would end the block; JSON allows the escaped form.
    payload = payload.replace("</", "<\\/")
    reach = connect or "'none'"
    csp = (f"default-src 'none'; script-src {_csp_hash(script)}; style-src "
           f"{_csp_hash(style)}; img-src data:; connect-src {reach}; "
           "base-uri 'none'; form-action 'none'")
    page = _asset("replay.html")
    for key, value in (("CSP", csp), ("TITLE", html.escape(page_title(data))),
                       ("STYLE", style), ("GROUND", _asset(GROUND_HTML) if live else ""),
                       ("DATA", payload), ("SCRIPT", script)):
        page = page.replace("{{" + key + "}}", value, 1)
    return page


def write_replay(path, table, summary=None, cfg=None, option=None, scenario=None) -> Path:
    """Write the replay page of a flown mission to ``path`` (whole or not at all).

    ``table``, ``summary``, ``cfg`` and ``scenario`` are :func:`replay_data`'s;
    ``option`` names the command-line option in an
    :class:`~allsky.apps.output.OutputError`. Returns the path.
    """
    from allsky.apps.output import write_atomic

    return write_atomic(path, render_html(replay_data(table, summary, cfg, scenario)),
                        option=option)


def read_summary(path) -> dict:
    """The mission summary at ``path``, written by ``allsky run --json``.

    ConfigError if the file is not one (:func:`allsky.apps.summaries.read_summary`).
    """
    from allsky.apps.summaries import read_summary as read_checked

    return read_checked(path)


def run_from_cli(cfg, args) -> int:
    """``allsky replay TELEMETRY [--summary JSON] --html PATH``: write the page.

    ``cfg`` is the scenario the command line loaded (``--scenario``, ``--set``)
    and ``args`` the parsed command line (:mod:`allsky.apps.cli`); returns the
    exit status.
    """
    from allsky.apps.output import check_output
    from allsky.apps.telemetry_files import TelemetryError, read

    check_output("--html", args.html, suffixes=(".html", ".htm"))
    table, _ = read(args.telemetry)
    if len(table) == 0:
        raise TelemetryError(f"telemetry file {args.telemetry!r} has no rows: nothing to "
                             "replay")
    summary = read_summary(args.summary) if args.summary else None
    path = write_replay(args.html, table, summary, cfg, option="--html",
                        scenario=describe_scenario(getattr(args, "scenario", None),
                                                   getattr(args, "overrides", ())))
    if not getattr(args, "quiet", False):
        size_mb = path.stat().st_size / 1e6
        print(f"wrote replay {path} ({size_mb:.1f} MB, {len(table)} telemetry rows)")
    return 0
