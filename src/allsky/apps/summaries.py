"""Mission summaries read back from a file (``allsky run --json``) and checked.

``allsky plot --summary`` and ``allsky replay --summary`` read a summary
written earlier; a file that is not one (another JSON document, a summary
edited by hand, a damaged one) must be refused in one line naming the file
and the first field that is wrong, never reach the figures or the page as a
value they cannot take. :data:`SHAPE` is what those readers use of a
summary (:meth:`allsky.sim.mission.Mission.summary`), as data; fields they do
not use are not checked, and fields absent from an older summary may be
absent.
"""

import json
import math
from pathlib import Path

from allsky.config import ConfigError
from allsky.config.toml_io import os_reason, read_bounded
from allsky.vocabulary import AXES, CROSS_COUPLING_KEYS, SCALE_FACTOR_AXES

#: Format of the summary JSON files allsky writes (their ``format`` key). A file without
#: the key was written before summaries carried one and is read as this format; a file of
#: another format is refused.
SUMMARY_FORMAT = 1


def summary_text(summary) -> str:
    """The JSON text of mission ``summary`` as ``--json`` writes it: ``format`` first."""
    return json.dumps({"format": SUMMARY_FORMAT, **summary}, indent=2) + "\n"


#: [bytes] Largest summary file read (a mission's summary is a few kB; one of many
#: targets some tens of kB).
SUMMARY_MAX_BYTES = 16 * 2**20

# The shape language: a type name, a tuple of alternatives, a dict of fields (each
# optional, unless its name ends in "!"), ("list", shape), ("map", key names, shape).
NUMBER, TEXT, FLAG, NONE = "number", "text", "flag", "none"
_AXES3 = AXES
_CROSS = CROSS_COUPLING_KEYS
_WORDS = {"drift_deg_h": ("map", _AXES3, NUMBER), "scale_factor": ("map", SCALE_FACTOR_AXES,
                                                                    NUMBER),
          "cross_coupling": ("map", _CROSS, NUMBER)}
#: The words, each present: the figures and the page read all three of a table given.
_WORDS_ALL = {f"{k}!": v for k, v in _WORDS.items()}
_HOLD = ({"drift_arcsec_per_min": ("map", _AXES3, NUMBER)}, NONE)
_TARGET = ({"name": (TEXT, NONE), "star": (TEXT, NONE), "ra_deg": NUMBER,
            "dec_deg": NUMBER, "start_s": (NUMBER, NONE), "end_s": (NUMBER, NONE),
            "programmed_roll_deg": (NUMBER, NONE), "programmed_yaw_deg": (NUMBER, NONE),
            "pointing_error_arcsec": (NUMBER, NONE), "hold": _HOLD,
            "locked_star": (TEXT, NONE)}, NONE)
#: What the figures and the replay page read of a summary.
SHAPE = {
    "status!": TEXT, "abort_reason": (TEXT, NONE),
    "modes!": ("list", {"mode!": TEXT, "start_s!": NUMBER, "end_s!": NUMBER, "exit!": TEXT}),
    "target!": _TARGET, "targets": (("list", _TARGET), NONE),
    "calibration": (_WORDS_ALL, NONE), "calibration_applied": FLAG,
    "truth": (_WORDS_ALL, NONE), "hold": _HOLD,
    "propellant_kg": (NUMBER, NONE), "mission_time_s": (NUMBER, NONE),
    "reference_star": (TEXT, NONE), "locked_star": (TEXT, NONE),
    "seed": (NUMBER, NONE),
    "end": ({"t_s": NUMBER, "mode": (TEXT, NONE),
             "true_pointing_error_arcsec": (NUMBER, NONE), "propellant_kg": (NUMBER, NONE),
             "propellant_remaining_kg": (NUMBER, NONE)}, NONE),
    "events": ("list", {"kind!": TEXT, "t_s!": NUMBER, "mode": (TEXT, NONE)}),
    "faults": (("list", {}), NONE),
    "warnings": (("list", TEXT), NONE),
}
#: The statuses a summary can have.
STATUSES = ("running", "complete", "aborted")


def _fits(value, kind) -> bool:
    if kind == NUMBER:
        return (isinstance(value, int | float) and not isinstance(value, bool)
                and math.isfinite(value) and abs(value) < 1e300)
    if kind == TEXT:
        return isinstance(value, str)
    if kind == FLAG:
        return isinstance(value, bool)
    if kind == NONE:
        return value is None
    return False


def _describe(kind) -> str:
    if isinstance(kind, tuple) and kind and kind[0] in ("list", "map"):
        return "a list" if kind[0] == "list" else "an object"
    if isinstance(kind, tuple):
        return " or ".join(_describe(k) for k in kind)
    if isinstance(kind, dict):
        return "an object"
    return {NUMBER: "a finite number", TEXT: "text", FLAG: "true or false",
            NONE: "null"}[kind]


def problem(value, shape, where="") -> str | None:
    """The first way ``value`` differs from ``shape`` (:data:`SHAPE`), or None.

    ``where`` is ``value``'s place in the summary, which the answer names.
    """
    if isinstance(shape, tuple) and shape and shape[0] == "list":
        if not isinstance(value, list):
            return f"{where or 'it'} is not a list"
        for k, item in enumerate(value):
            found = problem(item, shape[1], f"{where}[{k}]")
            if found:
                return found
        return None
    if isinstance(shape, tuple) and shape and shape[0] == "map":
        if not isinstance(value, dict):
            return f"{where} is not an object"
        for key in shape[1]:
            if key not in value:
                return f"{where}.{key} is missing"
            if not _fits(value[key], shape[2]):
                return f"{where}.{key} is not {_describe(shape[2])}"
        return None
    if isinstance(shape, tuple):  # alternatives
        for alt in shape:
            if (isinstance(alt, dict) and isinstance(value, dict)) or (
                    isinstance(alt, tuple) and alt and alt[0] == "list"
                    and isinstance(value, list)):
                return problem(value, alt, where)
            if isinstance(alt, str) and _fits(value, alt):
                return None
        return f"{where or 'it'} is not {_describe(shape)}"
    if isinstance(shape, dict):
        if not isinstance(value, dict):
            return f"{where or 'it'} is not an object"
        for field, sub in shape.items():
            key = field.rstrip("!")
            name = f"{where}.{key}" if where else key
            if key not in value:
                if field.endswith("!"):
                    return f"{name} is missing"
                continue
            found = problem(value[key], sub, name)
            if found:
                return found
        return None
    return None if _fits(value, shape) else f"{where} is not {_describe(shape)}"


def check(summary) -> str | None:
    """What makes ``summary`` unusable as a mission summary, or None."""
    found = problem(summary, SHAPE)
    if found:
        return found
    if summary["status"] not in STATUSES:
        return f"status {summary['status']!r} is not one of {', '.join(STATUSES)}"
    from allsky.sequencer.modes import MODE_TABLE
    from allsky.vocabulary import EVENT_KIND

    for k, e in enumerate(summary.get("events") or []):
        if e["kind"] not in EVENT_KIND:
            return f"events[{k}].kind {e['kind']!r} is not a journal kind"
    names = {m.name for m in MODE_TABLE}
    for k, r in enumerate(summary["modes"]):
        if r["mode"] not in names:
            return f"modes[{k}].mode {r['mode']!r} is not a mode"
    for k, t in enumerate([summary["target"]] + list(summary.get("targets") or [])):
        if t is not None and t.get("star") is None and not {"ra_deg", "dec_deg"} <= set(t):
            where = "target" if k == 0 else f"targets[{k - 1}]"
            return f"{where} has neither a star nor ra_deg and dec_deg"
        if t is not None and t.get("star") is not None:
            from allsky.vehicle import sky

            try:
                sky.star(t["star"])
            except (KeyError, ValueError):
                where = "target" if k == 0 else f"targets[{k - 1}]"
                return f"{where}.star {t['star']!r} is not a catalog star"
    return None


def read_summary(path) -> dict:
    """The mission summary in ``path``, checked (:func:`check`).

    Raises
    ------
    ConfigError
        One line naming the file: unreadable, over :data:`SUMMARY_MAX_BYTES`,
        not UTF-8 JSON, or not a mission summary (the first field that is not).
    """
    shown = repr(str(path))
    try:
        data = read_bounded(Path(path), SUMMARY_MAX_BYTES, "summary file")
    except (OSError, ValueError) as e:
        why = os_reason(e) if isinstance(e, OSError) else str(e)
        raise ConfigError(None, rule=f"summary {shown}: {why}") from None
    try:
        summary = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ConfigError(None, rule=f"summary {shown}: not UTF-8 text (byte "
                                     f"0x{data[e.start]:02x} at offset {e.start})") from None
    except (ValueError, RecursionError) as e:
        raise ConfigError(None, rule=f"summary {shown} is not JSON "
                                     f"({' '.join(str(e).split())[:120]})") from None
    if isinstance(summary, dict) and "format" in summary and (
            type(summary["format"]) is not int or summary["format"] != SUMMARY_FORMAT):
        raise ConfigError(None, rule=f"summary {shown} is of format {summary['format']!r}; "
                                     f"this allsky reads summaries of format {SUMMARY_FORMAT}")
    why = check(summary)
    if why:
        raise ConfigError(None, rule=f"summary {shown} is not an allsky mission summary "
                                     f"(allsky run --json): {why}")
    return summary
