"""The replay's event log and mode texts, from the mode table and the telemetry.

The telemetry records the switch bank once per row (the ``switches``
bitmask) but not why it moved. :func:`events` finds each change of the
bank and matches it, in order, to the :class:`~allsky.sequencer.modes.Operate`
steps of the modes flown: the reason of a switch action is the wait of the
mode table that ended before it (or the start of its mode). Steps that fall
inside one telemetry interval show as one change and are matched together.
The named actions (:class:`~allsky.sequencer.modes.Do`) are placed beside
the switch action they precede, or at the start or end of their mode.

:func:`mode_sentence` writes the one-sentence explanation of a mode from
its waits and its exit text; :data:`LOOK_FOR` says where on the page the
mode shows best.
"""

import numpy as np

from allsky.hardware.wiring import BY_NUMBER
from allsky.sequencer import modes
from allsky.sim.telemetry import INDEX

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
    "dither": "Sensor traces: small sinusoidal turns in roll and yaw; the gyro counts are "
              "compared with the optics to measure the scale factors.",
}


def mode_sentence(name, exit_text=None) -> str:
    """One sentence explaining mode ``name``: what it waits for, and how it ends."""
    mode = modes.BY_NAME[name]
    waits = [s.what for s in mode.steps if isinstance(s, modes.Wait)]
    text = f"The sequencer waits for {', then '.join(waits)}" if waits else "No waits"
    end = exit_text if exit_text and not exit_text.startswith("aborted") else mode.exit
    if "{" in end:  # an exit text not filled from a scenario: keep its words only
        end = end.split("{")[0].rstrip(" (")
    return f"{text}; it ends with: {end}."


def _switch_words(close, open_) -> str:
    parts = []
    for verb, group in (("close", close), ("open", open_)):
        if group:
            parts.append(f"{verb} " + ", ".join(f"S{k}" for k in sorted(group)))
    return "; ".join(parts)


def _plan_operations(plan):
    """Each Operate step of ``plan``, in order, with its reason and what follows it.

    Returns a list of dicts: mode, close, open (sets), reason (the wait or
    start before it), actions (texts of the Do steps just before it), next_wait
    (the wait that follows it in its mode, or "").
    """
    out = []
    for name in plan:
        steps = modes.BY_NAME[name].steps
        reason, actions = f"start of Mode {name}", []
        for i, step in enumerate(steps):
            if isinstance(step, modes.Do):
                actions.append(modes.action_text(step))
            elif isinstance(step, modes.Wait):
                reason, actions = f"after \u00ab{step.what}\u00bb (Mode {name})", []
            else:
                nxt = next((s.what for s in steps[i + 1:] if isinstance(s, modes.Wait)), "")
                out.append({"mode": name, "close": set(step.close), "open": set(step.open_),
                            "reason": reason, "actions": actions, "next_wait": nxt})
                actions = []
    return out


def _apply(mask, ops):
    for op in ops:
        for k in op["close"]:
            mask |= 1 << (k - 1)
        for k in op["open"]:
            mask &= ~(1 << (k - 1))
    return mask


def _mode_actions(name):
    """Do steps of a mode before its first wait, and after its last wait."""
    steps = modes.BY_NAME[name].steps
    kinds = [isinstance(s, modes.Wait) for s in steps]
    first = kinds.index(True) if True in kinds else len(steps)
    last = len(steps) - 1 - kinds[::-1].index(True) if True in kinds else len(steps)
    # Actions followed by a switch step before the first wait are logged with that step.
    ops = [i for i, s in enumerate(steps[:first]) if isinstance(s, modes.Operate)]
    head = [modes.action_text(s) for i, s in enumerate(steps[:first])
            if isinstance(s, modes.Do) and not (ops and i < ops[-1])]
    tail = [modes.action_text(s) for s in steps[last + 1:] if isinstance(s, modes.Do)]
    return head, tail


def mode_runs(table):
    """Runs of equal mode code: ``[(first row, mode name), ...]``."""
    code = table[:, INDEX["mode"]]
    names = {round(c, 6): n for n, c in modes.MODE_CODE.items()}
    cuts = np.r_[0, np.flatnonzero(np.diff(code) != 0) + 1] if len(code) else []
    return [(int(i), names.get(round(float(code[i]), 6), "?")) for i in cuts]


def _pair_runs(table, timeline):
    """Each timeline record with the first row that shows it, in flight order.

    Runs of the mode column are matched to the records in order. A record
    with no run of its own (a mode of no duration, such as "reacquire", one
    shorter than the telemetry interval, or a mode flown again at once) gets
    the first row after its start. Returns ``[(row, record), ...]``; without
    a timeline, the runs alone, each as a record with its mode only.
    """
    runs = mode_runs(table)
    if not timeline:
        return [(row, {"mode": name}) for row, name in runs]
    t = table[:, INDEX["time"]]
    out, p = [], 0
    for rec in timeline:
        if p < len(runs) and runs[p][1] == rec["mode"]:
            out.append((runs[p][0], rec))
            p += 1
        else:  # the first row after its start (a row at the very start is the mode before)
            out.append((min(int(np.searchsorted(t, rec["start_s"], side="right")),
                            len(t) - 1), rec))
    for row, name in runs[p:]:  # rows the timeline does not cover
        out.append((row, {"mode": name}))
    return out


def events(table, timeline):
    """The event log: mode changes, switch actions with their reasons, named actions.

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry (:data:`allsky.sim.telemetry.COLUMNS`).
    timeline : list of dict
        ``mode``, ``start_s``, ``end_s``, ``exit`` per mode flown (the summary's
        ``modes``), each mode as often as it was flown.

    Returns
    -------
    list of dict
        ``t_s`` (the first row showing the event), ``kind`` ("mode", "switch"
        or "action"), ``mode``, ``text``, ``reason``; switch events also
        ``close`` and ``open`` (switch numbers) and ``waiting`` (what the
        sequencer waits for next, "" if nothing).
    """
    t = table[:, INDEX["time"]]
    masks = table[:, INDEX["switches"]].astype(np.int64)
    out = []
    before = None  # the record flown before
    pairs = _pair_runs(table, timeline)
    for seq, (row, rec) in enumerate(pairs):
        name = rec["mode"]
        reason = (f"Mode {before['mode']} ended: {before['exit']}"
                  if before is not None and "exit" in before
                  else f"Mode {before['mode']} ended" if before is not None
                  else "ejection: the mission starts")
        before = rec
        title = modes.MODE_TITLE.get(name, "unknown mode")
        first_wait = next((s.what for s in modes.BY_NAME[name].steps
                           if isinstance(s, modes.Wait)), "") if name in modes.BY_NAME else ""
        out.append({"t_s": float(t[row]), "kind": "mode", "mode": name,
                    "text": f"Mode {name} begins: {title}", "reason": reason,
                    "waiting": first_wait, "seq": seq})
        if name in modes.BY_NAME:
            head, tail = _mode_actions(name)
            for a in head:
                out.append({"t_s": float(t[row]), "kind": "action", "mode": name, "text": a,
                            "reason": f"start of Mode {name}", "seq": seq})
            if "end_s" in rec and not rec["exit"].startswith("aborted"):
                # the last row of the mode: the actions come before the next mode's start
                k = min(max(int(np.searchsorted(t, rec["end_s"] + 1e-9)) - 1, row), len(t) - 1)
                for a in tail:
                    out.append({"t_s": float(t[k]), "kind": "action", "mode": name,
                                "text": a, "reason": f"end of Mode {name}", "seq": seq})
    plan = [r["mode"] for r in timeline] or [n for _, n in mode_runs(table)]
    ops = _plan_operations([n for n in plan if n in modes.BY_NAME])
    mode_at = mode_runs(table)
    p, previous = 0, 0
    for i in np.flatnonzero(np.r_[masks[0] != 0, masks[1:] != masks[:-1]]):
        new = int(masks[i])
        close = {k for k in range(1, 20) if new >> (k - 1) & 1 and not previous >> (k - 1) & 1}
        open_ = {k for k in range(1, 20) if previous >> (k - 1) & 1 and not new >> (k - 1) & 1}
        match = None
        for s in range(p, min(p + 4, len(ops))):
            for e in range(s, min(s + 3, len(ops))):
                if _apply(previous, ops[s:e + 1]) == new:
                    match = (s, e)
                    break
            if match:
                break
        row_mode = [n for r, n in mode_at if r <= i][-1]
        shown = [k for k, (r, _) in enumerate(pairs) if r <= i] or [0]
        seq = shown[-1]
        if match:
            group = ops[match[0]:match[1] + 1]
            p = match[1] + 1
            # the step's own mode (one of no duration shares its row with the next)
            row_mode = group[0]["mode"]
            seq = next((k for k in reversed(shown) if pairs[k][1]["mode"] == row_mode), seq)
            reasons = "; ".join(dict.fromkeys(g["reason"] for g in group))
            for g in group:
                for a in g["actions"]:
                    out.append({"t_s": float(t[i]), "kind": "action", "mode": g["mode"],
                                "text": a, "reason": g["reason"], "seq": seq})
            waiting = group[-1]["next_wait"]
        else:
            reasons = (f"no switch step of the mode table matches; a named action of "
                       f"Mode {row_mode}")
            waiting = ""
        text = _switch_words(close, open_)
        detail = "; ".join(f"S{k}: {BY_NUMBER[k].text}" for k in sorted(close | open_))
        out.append({"t_s": float(t[i]), "kind": "switch", "mode": row_mode, "text": text,
                    "reason": reasons, "detail": detail, "close": sorted(close),
                    "open": sorted(open_), "waiting": waiting, "seq": seq})
        previous = new
    # In time order; at one row, in flight order (a mode of no duration before the next).
    order = {"mode": 0, "action": 1, "switch": 2}
    out.sort(key=lambda e: (e["t_s"], e["seq"], order[e["kind"]]))
    for e in out:
        del e["seq"]
    return out
