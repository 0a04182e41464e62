"""The journal in words: a line an entry, for the report, the stops, the replay.

The journal (:mod:`allsky.sim.journal`, the summary's ``events``) records
what happened as numbers and names; :func:`event_text` says each entry in a
line, :func:`page_log` turns the journal into the replay page's event log
(what happened, why, what the sequencer waits for next), and
:func:`register_history` into the words registers 23 and 24 held over time.
Nothing here reconstructs the flight: every line is an entry of the journal.

:func:`mode_sentence` explains a mode from the mode table; :data:`LOOK_FOR`
says where on the replay page a mode shows best.
"""

import numpy as np

from allsky.computer import word_registers as wr
from allsky.hardware.wiring import BY_NUMBER
from allsky.sequencer import modes
from allsky.sim import board
from allsky.units import RAD2ARCSEC
from allsky.vocabulary import CROSS_COUPLING_KEYS

#: Where to look on the page while a mode flies (presentation text, by mode name).
LOOK_FOR = {
    "1": "3-D view and sensor traces: the vehicle swings its +x axis (the sun sensor) onto "
         "the Sun and the sun sensor's pitch and yaw errors fall to zero.",
    "2": "Sky map: rolling about the Sun line, the tracker's slit sweeps a ring of sky until "
         "a star of the magnitude window (Canopus) falls into it; S16+S18 open and S12 "
         "hands the roll to the tracker.",
    "3": "Drift counters 13/15/17: the optics hold the vehicle still while the gyros' drift "
         "is counted; then S1-S3 feed it back through drift DACs 7/9/11.",
    "4": "Counter 14 and the sky map: a full 360 deg roll about the Sun line; the star "
         "coming back into the slit marks the whole turn.",
    "5": "Counter 18 and the 3-D view: the star is pitched onto the tracker boresight (S13), "
         "then the vehicle yaws 360 deg about the star line until the Sun comes back.",
    "6-1": "Counter 14, CPU 22 and register 24: the vehicle rolls about the Sun line by the "
           "programmed roll, counted by the gyros and corrected with register 23.",
    "6-2": "3-D view and sky map: the vehicle yaws by the programmed yaw onto the target; "
           "the Sun and star leave the sensors and the gyros alone hold the attitude.",
    "hold": "CPU 22 errors: the gyros alone hold the target; any drift left shows here.",
    "direct": "3-D view and CPU 22 errors: from the target it holds, the vehicle rolls by the "
              "programmed turn on the gyros alone (no optics), then Mode 6-2 yaws onto the "
              "next target.",
    "standby": "CPU 22 errors: the gyros alone hold the target until the ground commands "
               "otherwise; any drift left shows here.",
    "dither": "Sensor traces: small sinusoidal turns in roll and yaw; the gyro counts are "
              "compared with the optics to measure the scale factors.",
}


#: What each numeral the journal's register entries name is.
REGISTER_NAMES = board.BLOCKS


def mode_sentence(name, exit_text=None) -> str:
    """One sentence explaining mode ``name``: what it waits for, and how it ends.

    ``exit_text`` is how the mode ended in this flight (its ``mode_end``
    entry's ``exit``); None, or an abort, gives the mode table's words.
    """
    mode = modes.BY_NAME[name]
    waits = [s.what for s in mode.steps if isinstance(s, modes.Wait)]
    text = f"The sequencer waits for {', then '.join(waits)}" if waits else "No waits"
    end = exit_text if exit_text and not exit_text.startswith("aborted") else mode.exit
    if "{" in end:  # an exit text not filled from a scenario: keep its words only
        end = end.split("{")[0].rstrip(" (")
    return f"{text}; it ends with: {end}."


def switch_words(close, open_) -> str:
    """``close S12; open S16, S18``: switch numbers ``close`` and ``open_`` in words."""
    parts = []
    for verb, group in (("close", close), ("open", open_)):
        if group:
            parts.append(f"{verb} " + ", ".join(f"S{k}" for k in sorted(group)))
    return "; ".join(parts)


def _value(e) -> str:
    if e["register"] == "23" and e["word"] in CROSS_COUPLING_KEYS:
        # [rad] in the register; in arcsec, the unit of every table that shows it
        return f"{e['value'] * RAD2ARCSEC:+.2f} arcsec"
    if e["unit"] == "-":
        return f"{e['value']:.7g}"
    pulses = f" ({e['pulses']:+d} pulses)" if "pulses" in e else ""
    return f"{e['value']:+.4f} {e['unit']}{pulses}"


def runs(values) -> list:
    """Runs of equal value in ``values``: ``[(first index, value), ...]``, in order.

    The one implementation of "runs of equal mode" (and of any telemetry
    column the replay sends as runs).
    """
    values = np.asarray(values)
    if len(values) == 0:
        return []
    starts = np.r_[0, np.flatnonzero(values[1:] != values[:-1]) + 1]
    return [(int(i), values[i]) for i in starts]


def switch_edges(events, k) -> list:
    """Switch ``k``'s moves ``[(t_s, closed), ...]``, from the journal's entries.

    ``events`` are the journal's entries in order (the summary's ``events``).
    The bank starts open; each entry that closes or opens switch ``k`` is one
    edge, at its exact frame's time.
    """
    out = []
    for e in events:
        if e["kind"] == "switch":
            if k in e["close"]:
                out.append((float(e["t_s"]), True))
            elif k in e["open"]:
                out.append((float(e["t_s"]), False))
    return out


def event_text(e) -> str:
    """Journal entry ``e`` (a dict, docs/journal.md) in one line of words."""
    kind = e["kind"]
    if kind == "mode_start":
        return f"Mode {e['mode']} begins: {e['title']}"
    if kind == "mode_end":
        return f"Mode {e['mode']} ends: {e['exit']}"
    if kind == "switch":
        return f"switches: {switch_words(e['close'], e['open'])} ({e['step']})"
    if kind == "action":
        return f"action: {e['text']}"
    if kind == "register":
        name = REGISTER_NAMES[e["register"]]
        if e["register"] == board.CPU:
            text = f"{name} cleared"
        elif e["register"] in board.RATE_COMMANDS.values():
            text = f"{name} turns {e['word']} {'positive' if e['value'] > 0 else 'negative'}"
        else:
            text = f"{name} {e['word']} = {_value(e)}"
        if "counted_pulses" in e and e["counted_pulses"] != e["pulses"]:
            text += f", not the {e['counted_pulses']:+d} pulses counted (full scale)"
        if e.get("by", board.SEQUENCER) != board.SEQUENCER:
            text += f" (by {e['by']})"
        return text
    if kind == "star_lock":
        if e["star"] is None:
            return f"tracker: {e['previous']} leaves the slit"
        where = f" at cone angle {e['cone_angle_deg']:+.2f} deg"
        use = " (in use)" if e.get("in_use") else ""
        return f"tracker: {e['star']} in the slit{where}{use}"
    if kind == "lock_rejected":
        return (f"tracker: {e['star']} refused at cone angle {e['cone_angle_deg']:+.2f} deg, "
                f"{abs(e['cone_angle_deg'] - e['reference_cone_angle_deg']):.2f} deg from "
                f"the reference star's (check {e['check_deg']:g} deg)")
    if kind == "lock_dropped":
        return (f"tracker: {e['star']} dropped, the slit at {e['magnitude']:+.2f} mag, brighter "
                f"than the gate ({e['gate_magnitude']:+.2f} mag)")
    if kind == "saturation":
        state = "" if e["active"] else " ends"
        if e["what"] == "drift_dac_clip":
            return (f"drift DAC {e['block']} ({e['axis']}) at full scale{state}: applies "
                    f"{e['applied_deg_h']:+.4f} deg/h of the {e['counted_deg_h']:+.4f} counted")
        if e["what"] == "counter_overflow":
            return f"counter {e['block']} ({e['axis']}) overflowed"
        if e["what"] == "wheel_momentum_limit":
            return (f"wheel {e['wheel'] + 1} at its momentum limit{state} "
                    f"({e['momentum_n_m_s']:+.3f} of {e['limit_n_m_s']:g} N m s)")
        return "jets unload the wheels" if e["active"] else "unloading ends"
    if kind == "fault":
        return f"fault: {e['text']} {'begins' if e['active'] else 'ends'}"
    if kind == "abort":
        return f"ABORTED: {e['reason']}"
    if kind == "ground_command":
        return f"ground command: {e['text']}"
    if kind == "eclipse":
        if e["phase"] == "sunlit":
            return "orbit: the vehicle leaves the Earth's shadow, fully sunlit"
        return (f"orbit: the vehicle enters the {e['phase']} "
                f"({100 * e['sunlit_fraction']:.0f} % of the Sun's disk in view)")
    if kind == "occultation":
        return f"orbit: the Earth {'hides' if e['active'] else 'no longer hides'} {e['body']}"
    if kind == "earth_glare":
        if not e["active"]:
            return "tracker: the sunlit Earth leaves the slit"
        held = f", {e['star']} lost" if e.get("star") else ""
        return (f"tracker: blinded by the sunlit Earth in the slit "
                f"({e['surface_brightness_mag_arcsec2']:.1f} mag/arcsec^2){held}")
    return kind


def worth_a_line(e) -> bool:
    """Whether journal entry ``e`` is worth a line of a log.

    All are but a counter cleared to zero (its action has a line) and a
    mode's successful end (the next mode's start says it).
    """
    if e["kind"] == "register":
        return not (e.get("pulses") == 0 and e["value"] == 0.0 and "counted_pulses" not in e
                    and e["register"] not in ("23", "24"))
    return not (e["kind"] == "mode_end" and e["status"] != "aborted")


def page_log(events) -> list:
    """The replay page's event log, one row per journal entry worth a line.

    ``events`` are the journal's entries, in order (the summary's ``events``).

    Each row: ``t_s``, ``kind``, ``mode``, ``text``, ``reason`` and, for
    switch operations and mode starts, ``waiting`` (what the sequencer waits
    for next); switch rows also ``close``, ``open`` and ``detail`` (what the
    switches connect). Register writes of counters cleared to zero are left
    out (the action that clears them has its row).
    """
    out = []
    previous_end = None
    for e in events:
        kind, mode = e["kind"], e["mode"]
        row = {"t_s": e["t_s"], "kind": kind, "mode": mode, "text": event_text(e)}
        if kind == "mode_start":
            row.update(kind="mode", text=f"Mode {mode} begins: {e['title']}",
                       reason=(f"Mode {previous_end['mode']} ended: {previous_end['exit']}"
                               if previous_end else "ejection: the mission starts"),
                       waiting=e.get("waits_for", ""))
        elif kind == "mode_end":
            previous_end = e
            if e["status"] != "aborted":
                continue
            row.update(kind="abort", text=f"Mode {mode} aborted", reason=e["exit"])
        elif kind == "switch":
            row.update(text=switch_words(e["close"], e["open"]), reason=e["step"],
                       close=e["close"], open=e["open"], waiting=e.get("waits_for", ""),
                       detail="; ".join(f"S{k}: {BY_NUMBER[k].text}"
                                        for k in sorted(e["close"] + e["open"])))
        elif kind == "action":
            row.update(text=e["text"], reason=f"a step of Mode {mode}")
        elif kind == "register":
            if not worth_a_line(e):
                continue
            row["reason"] = f"written in Mode {mode}"
        elif kind == "abort":
            continue  # the aborted mode's row says it
        elif kind == "ground_command":
            row.update(text=e["text"], reason="commanded from the ground")
        else:
            row["reason"] = {"star_lock": "the star tracker",
                             "lock_rejected": "the tracker's cone-angle check",
                             "lock_dropped": "the tracker's bright gate",
                             "saturation": "a saturation", "fault": "an injected fault",
                             "eclipse": "the Earth's shadow (the orbit)",
                             "occultation": "the Earth's disk (the orbit)",
                             "earth_glare": "the sunlit Earth in the slit (the orbit)"}[kind]
        out.append(row)
    return out


def register_history(events) -> dict:
    """Registers 23 and 24 over time, from the journal's register writes.

    ``events`` are the journal's entries, in order (the summary's ``events``).

    Returns ``{"23": [...], "24": [...]}``: for register 23, each write's
    time, the action that wrote it (``by``; None for the neutral words at
    ejection) and every word then in force (``sf_roll`` ... ``yaw_into_roll``);
    for register 24, each load's time, the programmed roll and yaw [deg] and
    the target they were loaded for.
    """
    neutral = wr.neutral_computed()
    words = {name: float(neutral[slot]) for name, slot in wr.WORD23.items()}
    r23 = [{"t_s": 0.0, "by": None, **words}]
    r24, target, pending, action = [], None, {}, None
    for e in events:
        if e["kind"] == "mode_start":
            target = e.get("target")
        if e["kind"] == "action":
            action = e["action"]
        if e["kind"] != "register":
            continue
        if e["register"] == "23":
            words = {**words, e["word"]: e["value"]}
            if r23[-1]["t_s"] == e["t_s"] and r23[-1]["by"] == action:
                r23[-1] = {"t_s": e["t_s"], "by": action, **words}
            else:
                r23.append({"t_s": e["t_s"], "by": action, **words})
        elif e["register"] == "24":
            pending[e["word"]] = e["value"]
            if {"roll", "yaw"} <= set(pending):
                r24.append({"t_s": e["t_s"], "roll_deg": pending["roll"],
                            "yaw_deg": pending["yaw"], "target": target})
                pending = {}
    return {"23": r23, "24": r24}
