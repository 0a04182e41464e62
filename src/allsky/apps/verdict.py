"""How a mission ended, as every display states it: one judgement, one wording.

The sequencer judges a mission *complete* when its last mode exits; the
summary's ``warnings`` say where what really happened disagrees (a vehicle
declared on target while it turns, a true error thousands of times the
computer's). A display that shows "complete" in green over such warnings
tells the reader the wrong side of belief and truth, so each display (the
report's first line, the replay page's badge and banner, the live page, the
notebook's repr) takes its words and tone from :func:`judge`:

========== =================================== ========
tone       label                               when
========== =================================== ========
``ok``     complete                            complete, no warning
``amber``  complete, as the sequencer judged   complete, with warnings
``failed`` aborted                             aborted
``open``   not finished                        stopped before the end
========== =================================== ========

:func:`unwritten` names the register words a calibration never wrote (an
abort before the mode that stores them): their values are the power-on
words, not a measurement, and a display shows "not calibrated (Mode N
aborted)" rather than an error against the truth.
"""

from allsky.sim.journal import DRIFT_DAC
from allsky.vocabulary import AXES, CROSS_COUPLING_KEYS, SCALE_FACTOR_AXES

#: The label a mission the sequencer completed but whose summary has warnings carries.
JUDGED = "complete, as the sequencer judged"
#: Label of each tone (``judge``'s ``tone``).
LABELS = {"ok": "complete", "amber": JUDGED, "failed": "aborted", "open": "not finished"}
#: Colour of each tone on the pages (text on white): green, amber, red, grey.
COLOURS = {"ok": "#1a7f37", "amber": "#9a6700", "failed": "#cf222e", "open": "#57606a"}
#: Register 23's words (the journal's ``word``) by the summary's calibration entry.
WORD_OF = {**{("scale_factor", a): f"sf_{a}" for a in SCALE_FACTOR_AXES},
           **{("cross_coupling", k): k for k in CROSS_COUPLING_KEYS}}


def judge(summary) -> dict:
    """The judgement of mission ``summary`` that every display shows.

    ``summary`` is :meth:`allsky.sim.mission.Mission.summary`'s.

    Returns
    -------
    dict
        ``status`` (the sequencer's: ``complete``, ``aborted``, ``running``),
        ``tone`` (``ok``, ``amber``, ``failed``, ``open``), ``label`` (in
        words, :data:`LABELS`), ``warnings`` (how many) and ``first_warning``
        (its text, or None).
    """
    status = summary.get("status")
    warnings = summary.get("warnings") or []
    first = warnings[0] if warnings else None
    if isinstance(first, dict):  # the page's timed form
        first = first.get("text")
    if status == "complete":
        tone = "amber" if warnings else "ok"
    elif status == "aborted":
        tone = "failed"
    else:
        tone = "open"
    return {"status": status, "tone": tone, "label": LABELS[tone], "warnings": len(warnings),
            "first_warning": first}


def strict_failure(summary) -> str | None:
    """Why ``--strict`` fails mission ``summary``, or None: it passes.

    As :func:`allsky.fly` with ``strict=True``: any warning fails it, and so
    does an abort or a flight stopped before its end.
    """
    j = judge(summary)
    if j["tone"] == "ok":
        return None
    if j["warnings"]:
        more = f" (and {j['warnings'] - 1} more)" if j["warnings"] > 1 else ""
        return f"mission {j['label']}, with a warning{more}: {j['first_warning']}"
    if j["tone"] == "failed":
        return f"mission aborted: {summary.get('abort_reason')}"
    return "mission not finished"


def _why_unwritten(summary) -> str:
    aborted = [r for r in summary.get("modes") or () if str(r["exit"]).startswith("aborted")]
    if aborted:
        return f"Mode {aborted[-1]['mode']} aborted"
    if summary.get("status") == "running":
        return "stopped before it was stored"
    return "never stored"


def unwritten(summary) -> dict:
    """The calibration entries of mission ``summary`` no mode wrote, in words.

    A word of register 23 is written when the journal has its ``register``
    entry (``register`` 23, ``word`` ``sf_roll`` ...); a drift when its drift
    DAC (7, 9, 11) was written. The summary's value of an entry never
    written is the power-on word.

    Returns
    -------
    dict
        ``(section, key) -> text`` with ``section`` one of ``drift_deg_h``,
        ``scale_factor``, ``cross_coupling`` and ``key`` its axis or factor,
        ``text`` "not calibrated (Mode 5 aborted)". Empty when every entry
        was written, or when the summary has no journal (``events``) to tell.
    """
    events = summary.get("events")
    if not events or summary.get("calibration") is None:
        return {}
    written = {(e["register"], e["word"]) for e in events if e.get("kind") == "register"}
    text = f"not calibrated ({_why_unwritten(summary)})"
    out = {}
    for i, a in enumerate(AXES):
        if (DRIFT_DAC[i], a) not in written:
            out[("drift_deg_h", a)] = text
    for entry, word in WORD_OF.items():
        if ("23", word) not in written:
            out[entry] = text
    return out
