"""A scenario's ``[dispersions]`` table: merging its entries and checking them.

The syntax of the entries, the seeding and the draws are in
:mod:`allsky.config.dispersions`; this module is the part that loading a
scenario needs (it runs before any draw, on the merged table).
"""

import difflib
import math
from collections.abc import Mapping
from datetime import timedelta

from allsky.config.checkers import (
    boolean,
    star_name,
    utc_datetime,
)
from allsky.config.cross_rules import last_start_utc
from allsky.config.rules import (
    EPHEMERIS_START_UTC,
    NON_NEGATIVE,
    ConfigError,
    as_float,
    check_conds,
    number,
    real_array,
    type_name,
)
from allsky.config.toml_io import iso_utc

#: Keys that hold a number, vector or matrix but are never drawn, and why.
NOT_DISPERSIBLE = {
    "mission.seed": "it is the run's identity: a campaign sets it (base seed + run index)",
    "ejection.attitude": "the ejection attitude is already random per mission.seed",
}
DATE_KEY = "mission.date_utc"
TARGET_KEY = "target"
#: Parameters of each kind of entry: dist -> (allowed, required groups (one of each)).
_NUMBER_PARAMS = {
    "normal": ({"dist", "mean", "sigma", "relative", "shared"}, (("sigma",),)),
    "uniform": ({"dist", "mean", "low", "high", "half_width", "relative", "shared"},
                (("low", "high"), ("half_width",))),
}
_DATE_PARAMS = {"uniform": ({"dist", "low", "high", "half_width_days"},
                            (("low", "high"), ("half_width_days",)))}
_TARGET_PARAMS = {"sphere": ({"dist"}, ((),)), "choice": ({"dist", "stars"}, (("stars",),))}
_EXAMPLE = '{ dist = "normal", sigma = 0.5 }'


# ---------------------------------------------------------------------------
# Merging (tables of a scenario, a --disperse file and --set overrides)
# ---------------------------------------------------------------------------

def merge(base: dict, incoming) -> dict:
    """Merge a ``[dispersions]`` table over ``base`` (flat ``{key: entry}``), in place.

    ``incoming`` is the table as read from TOML.

    Both spellings of a key are accepted: ``gyro.drift_deg_h = {...}`` (TOML
    nests it as ``gyro = {drift_deg_h = {...}}``) and ``"gyro.drift_deg_h" =
    {...}``. An entry replaces the same key's entry in ``base``; an entry with
    ``dist = "none"`` removes it. Entries are checked later, by :func:`validate`.
    """
    if not isinstance(incoming, Mapping):
        raise ConfigError("dispersions", incoming,
                          f"must be a table of KEY = {_EXAMPLE} entries, "
                          f"not {type_name(incoming)}")
    for key, entry in _flatten(incoming):
        if isinstance(entry, Mapping) and entry.get("dist") == "none":
            base.pop(key, None)
        else:
            base[key] = entry
    return base


def _flatten(table):
    for k, v in table.items():
        nested = (k != TARGET_KEY and "." not in k and isinstance(v, Mapping)
                  and "dist" not in v)
        if nested:  # a section: gyro = { drift_deg_h = {...}, ... }
            for name, entry in v.items():
                yield f"{k}.{name}", entry
        else:
            yield k, v


# ---------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------

def validate(table: Mapping, values: Mapping) -> dict:
    """Check merged ``[dispersions]`` entries against validated scenario ``values``.

    Parameters
    ----------
    table : mapping
        ``{key: entry}`` as merged by :func:`merge`.
    values : mapping
        The scenario's validated values by dotted key (``gyro.drift_deg_h`` -> tuple).

    Returns
    -------
    dict
        ``{key: entry}`` with numbers as floats (arrays as nested lists), dates as
        ISO-8601 UTC text and star names in their catalog spelling; only the
        parameters given.
    """
    return {key: _validate_entry(key, entry, values) for key, entry in table.items()}


def _kind(key, values):
    """'target', 'date' or the shape of a numeric key; ConfigError otherwise."""
    where = f"dispersions.{key}"
    if key == TARGET_KEY:
        return "target"
    if key == DATE_KEY:
        return "date"
    if key in NOT_DISPERSIBLE:
        raise ConfigError(where, rule=f"cannot be dispersed: {NOT_DISPERSIBLE[key]}")
    if key not in values or key.startswith("target."):
        near = difflib.get_close_matches(key, dispersible_keys(values), n=3, cutoff=0.6)
        hint = ("nearest: " + ", ".join(near)) if near else "see docs/montecarlo.md"
        raise ConfigError(where, rule=f"not a dispersible scenario key; {hint}")
    shape = value_shape(values[key])
    if shape is None:
        raise ConfigError(where, rule="cannot be dispersed: not a real number, vector or "
                          "matrix")
    return shape


def value_shape(v):
    """Shape of a real number, vector or matrix value; None for anything else.

    ``v`` is a validated value: a float, or (nested) tuples of floats.
    """
    def real(x):
        return isinstance(x, float)
    if real(v):
        return ()
    if isinstance(v, tuple) and v and all(real(x) for x in v):
        return (len(v),)
    if (isinstance(v, tuple) and v and all(isinstance(r, tuple) and r for r in v)
            and all(real(x) for r in v for x in r) and len({len(r) for r in v}) == 1):
        return (len(v), len(v[0]))
    return None


def dispersible_keys(values: Mapping) -> list:
    """Every key a ``[dispersions]`` table may name, for these scenario values.

    ``values`` are the validated scenario's values by dotted key.
    """
    out = [k for k, v in values.items()
           if k not in NOT_DISPERSIBLE and not k.startswith("target.")
           and value_shape(v) is not None]
    return [DATE_KEY, TARGET_KEY, *out]


def _validate_entry(key, entry, values):
    where = f"dispersions.{key}"
    kind = _kind(key, values)
    if not isinstance(entry, Mapping):
        raise ConfigError(where, entry, f"must be a table such as {_EXAMPLE}")
    table = {"target": _TARGET_PARAMS, "date": _DATE_PARAMS}.get(kind, _NUMBER_PARAMS)
    dist = entry.get("dist")
    names = list(table)
    if dist is None:
        raise ConfigError(f"{where}.dist", rule=f"missing: {_quoted(names)}")
    if dist not in table:
        raise ConfigError(f"{where}.dist", dist, f"must be {_quoted(names)} for {key}")
    allowed, groups = table[dist]
    for p in entry:
        if p not in allowed:
            raise ConfigError(f"{where}.{p}", rule=f'unknown parameter for dist = "{dist}"; '
                              f"valid: {', '.join(sorted(allowed - {'dist'}))}")
    need = ", or ".join(" and ".join(g) for g in groups)
    if sum(any(p in entry for p in g) for g in groups) > 1:
        raise ConfigError(where, rule=f'dist = "{dist}": give {need}, not both')
    if not any(all(p in entry for p in g) for g in groups):
        raise ConfigError(where, rule=f'dist = "{dist}" needs {need}')
    if kind == "target":
        return _validate_target(where, dist, entry)
    if kind == "date":
        return _validate_date(where, entry, values)
    return _validate_number(where, entry, kind)


def _quoted(names):
    q = [f'"{n}"' for n in names]
    return q[0] if len(q) == 1 else f"{', '.join(q[:-1])} or {q[-1]}"


def _validate_target(where, dist, entry):
    if dist == "sphere":
        return {"dist": dist}
    stars = entry["stars"]
    if not isinstance(stars, list) or not stars:
        raise ConfigError(f"{where}.stars", stars, "must be a non-empty array of star names")
    return {"dist": dist, "stars": [star_name(f"{where}.stars", s) for s in stars]}


def _validate_date(where, entry, values):
    """Dates that every draw can fly: the mission, started at any of them, ends inside
    the ephemeris range (:func:`allsky.config.schema.last_start_utc`)."""
    first, last = EPHEMERIS_START_UTC, last_start_utc(values)
    span = f"{iso_utc(first)}..{iso_utc(last)}"
    out = {"dist": "uniform"}
    if "half_width_days" in entry:
        hw = number(NON_NEGATIVE)(f"{where}.half_width_days", entry["half_width_days"])
        date = values[DATE_KEY]
        most = min(date - first, last - date) / timedelta(days=1)
        if hw > most:
            raise ConfigError(f"{where}.half_width_days", hw,
                              f"must be <= {most:.6g}: the drawn dates must lie within {span}, "
                              f"where a mission starting on them ends inside the ephemeris")
        out["half_width_days"] = hw
        return out
    lo = utc_datetime(f"{where}.low", entry["low"])
    hi = utc_datetime(f"{where}.high", entry["high"])
    if hi < lo:
        raise ConfigError(f"{where}.high", entry["high"], f"must be >= low ({iso_utc(lo)})")
    if hi > last:
        raise ConfigError(f"{where}.high", entry["high"],
                          f"must be <= {iso_utc(last)}: a mission starting then would end "
                          "after the ephemeris range (see mission.date_utc)")
    return {**out, "low": iso_utc(lo), "high": iso_utc(hi)}


def _validate_number(where, entry, shape):
    out = {"dist": entry["dist"]}
    for flag in ("relative", "shared"):
        if flag in entry:
            out[flag] = boolean(f"{where}.{flag}", entry[flag])
    for p in ("mean", "sigma", "low", "high", "half_width"):
        if p in entry:
            out[p] = _param(f"{where}.{p}", entry[p], shape,
                            NON_NEGATIVE if p in ("sigma", "half_width") else None)
    if "low" in out and any(h < lo for lo, h in zip(
            _flat(out["low"], shape), _flat(out["high"], shape), strict=True)):
        raise ConfigError(f"{where}.high", entry["high"], "must be >= low (element by element)")
    return out


def _flat(x, shape) -> list:
    """A parameter of :func:`_param` (a number, or nested lists of ``shape``), flattened."""
    if isinstance(x, list):
        return [y for row in x for y in row] if len(shape) == 2 else list(x)
    return [x] * math.prod(shape)


def _param(key, v, shape, cond):
    """A number, or an array of the key's shape; returned as a float or nested lists."""
    if isinstance(v, list) and shape:
        arr = real_array(key, v, shape)
        flat = [x for row in arr for x in row] if len(shape) == 2 else list(arr)
        if cond is not None:
            for i, x in enumerate(flat):
                check_conds((cond,), key, x, v, where=f"element {i} ")
        return [list(row) for row in arr] if len(shape) == 2 else list(arr)
    if isinstance(v, list):
        raise ConfigError(key, v, "must be a number (the key is a single number)")
    x, why = as_float(v)
    if why:
        raise ConfigError(key, v, f"{why}, or an array of the key's shape {list(shape)}"
                          if shape else why)
    check_conds((cond,) if cond is not None else (), key, x, x)
    return x
