"""Dispersions: scenario keys drawn at random per mission seed (Monte Carlo inputs).

A scenario's ``[dispersions]`` table (empty in the packaged default), or a
file given by ``--disperse`` holding such a table, names scenario keys and
the distribution each is drawn from::

    [dispersions]
    gyro.drift_deg_h = { dist = "normal", sigma = 0.5 }           # mean: the scenario's value
    gyro.scale_factor_error_ppm = { dist = "normal", mean = 0, sigma = [1000, 2000, 1000] }
    gyro.misalignment_arcsec = { dist = "uniform", half_width = 100 }  # diagonal stays 0
    vehicle.inertia_kg_m2 = { dist = "normal", sigma = 0.05, relative = true, shared = true }
    jets.thrust_n = { dist = "uniform", low = 0.2, high = 0.3 }
    mission.date_utc = { dist = "uniform", low = 2026-01-01T00:00:00Z, high = 2027-01-01T00:00:00Z }
    target = { dist = "sphere" }                                     # RA/Dec uniform on the sky
    # target = { dist = "choice", stars = ["Vega", "Arcturus", "Rigel"] }

Numbers (a real key, vector or matrix):

* ``dist = "normal"``: ``sigma`` (>= 0), optional ``mean`` (default: the
  scenario's value);
* ``dist = "uniform"``: ``low`` and ``high``, or ``half_width`` (>= 0) about
  ``mean`` (default: the scenario's value);
* parameters carry the key's unit; each is a number (the same for every
  element) or an array of the key's shape (element by element);
* ``relative = true``: the distribution is of a factor multiplying the
  scenario's value (``mean`` defaults to 1, parameters are dimensionless);
* ``shared = true``: one draw for all elements (e.g. an inertia scale that
  keeps the principal axes); otherwise each element is drawn independently;
* ``gyro.misalignment_arcsec``: the diagonal is never drawn (it stays 0);
  ``vehicle.inertia_kg_m2``: the upper triangle is drawn and mirrored.

``mission.date_utc``: ``dist = "uniform"`` with ``low`` and ``high``
(date-times), or ``half_width_days`` about the scenario's date. ``target``:
``dist = "sphere"`` (RA uniform in [0, 360) deg, sin Dec uniform in [-1, 1])
or ``dist = "choice"`` with ``stars`` (catalog names, drawn with equal
probability). ``dist = "none"`` removes a dispersion inherited from the
scenario (in a ``--disperse`` file or a ``--set``).

Seeding: the draw of key K for mission seed S comes from
``numpy.random.default_rng([S, 2, crc32(K)])`` (streams 0 and 1 of the
mission seed are the ejection and the legs' noise). It depends on S and K
only, so run i of a campaign (seed = base + i) is reproduced alone by
``allsky run --set mission.seed=S``, and adding or removing one dispersion
leaves the draws of the others unchanged.

A draw is validated like any scenario value: a draw that breaks a rule
(a negative thrust, an inertia that is not positive definite) raises
:class:`~allsky.config.scenario.ConfigError` naming the key and the drawn value.
"""

import difflib
import math
import zlib
from collections.abc import Mapping
from datetime import datetime, timedelta

import numpy as np

from allsky.config import scenario as config
from allsky.config.scenario import ConfigError

#: Stream number of the dispersion draws under the mission seed.
DISPERSION_STREAM = 2
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

    Both spellings of a key are accepted: ``gyro.drift_deg_h = {...}`` (TOML
    nests it as ``gyro = {drift_deg_h = {...}}``) and ``"gyro.drift_deg_h" =
    {...}``. An entry replaces the same key's entry in ``base``; an entry with
    ``dist = "none"`` removes it. Entries are checked later, by :func:`validate`.
    """
    if not isinstance(incoming, Mapping):
        raise ConfigError("dispersions", incoming,
                          f"must be a table of KEY = {_EXAMPLE} entries, "
                          f"not {config._type_name(incoming)}")
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
    """Check the merged ``[dispersions]`` entries against the validated scenario ``values``.

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
    shape = _shape(values[key])
    if shape is None:
        raise ConfigError(where, rule="cannot be dispersed: not a real number, vector or "
                          "matrix")
    return shape


def _shape(v):
    """Shape of a real number, vector or matrix value; None for anything else."""
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
    """Every key a ``[dispersions]`` table may name, for these scenario values."""
    out = [k for k, v in values.items()
           if k not in NOT_DISPERSIBLE and not k.startswith("target.") and _shape(v) is not None]
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
        return _validate_date(where, entry)
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
    return {"dist": dist,
            "stars": [config.star_name(f"{where}.stars", s) for s in stars]}


def _validate_date(where, entry):
    out = {"dist": "uniform"}
    if "half_width_days" in entry:
        hw = config.number(config.NON_NEGATIVE)(f"{where}.half_width_days",
                                                 entry["half_width_days"])
        out["half_width_days"] = hw
        return out
    lo = config.utc_datetime(f"{where}.low", entry["low"])
    hi = config.utc_datetime(f"{where}.high", entry["high"])
    if hi < lo:
        raise ConfigError(f"{where}.high", entry["high"], f"must be >= low ({config._iso_utc(lo)})")
    return {**out, "low": config._iso_utc(lo), "high": config._iso_utc(hi)}


def _validate_number(where, entry, shape):
    out = {"dist": entry["dist"]}
    for flag in ("relative", "shared"):
        if flag in entry:
            out[flag] = config.boolean(f"{where}.{flag}", entry[flag])
    for p in ("mean", "sigma", "low", "high", "half_width"):
        if p in entry:
            out[p] = _param(f"{where}.{p}", entry[p], shape,
                            config.NON_NEGATIVE if p in ("sigma", "half_width") else None)
    if "low" in out:
        lo, hi = np.broadcast_to(out["low"], shape), np.broadcast_to(out["high"], shape)
        if np.any(hi < lo):
            raise ConfigError(f"{where}.high", entry["high"], "must be >= low (element by element)")
    return out


def _param(key, v, shape, cond):
    """A number, or an array of the key's shape; returned as a float or nested lists."""
    if isinstance(v, list) and shape:
        arr = config._array(key, v, shape)
        flat = [x for row in arr for x in row] if len(shape) == 2 else list(arr)
        if cond is not None:
            for i, x in enumerate(flat):
                config._apply((cond,), key, x, v, where=f"element {i} ")
        return config._thaw(arr)
    if isinstance(v, list):
        raise ConfigError(key, v, "must be a number (the key is a single number)")
    x, why = config._as_float(v)
    if why:
        raise ConfigError(key, v, f"{why}, or an array of the key's shape {list(shape)}"
                          if shape else why)
    config._apply((cond,) if cond is not None else (), key, x, x)
    return x


# ---------------------------------------------------------------------------
# Drawing
# ---------------------------------------------------------------------------

def rng_for(seed: int, key: str) -> np.random.Generator:
    """The generator of key ``key``'s draw for mission seed ``seed``."""
    return np.random.default_rng([int(seed), DISPERSION_STREAM, zlib.crc32(key.encode())])


def _free_mask(key, shape):
    """Elements that are drawn: not the misalignment diagonal, the inertia upper triangle."""
    if key == "gyro.misalignment_arcsec":
        return ~np.eye(shape[0], dtype=bool)
    if key == "vehicle.inertia_kg_m2":
        return np.triu(np.ones(shape, dtype=bool))
    return np.ones(shape, dtype=bool)


def _draw_number(key, e, value, seed):
    base = np.array(value, dtype=float)
    free = _free_mask(key, base.shape)
    n = 1 if e.get("shared") else int(free.sum())
    rng = rng_for(seed, key)
    rel = bool(e.get("relative"))
    mean = np.broadcast_to(np.asarray(e["mean"], dtype=float) if "mean" in e
                           else (1.0 if rel else base), base.shape)
    if e["dist"] == "normal":
        sigma = np.broadcast_to(np.asarray(e["sigma"], dtype=float), base.shape)
        draw = mean[free] + sigma[free] * rng.standard_normal(n)
    else:
        if "half_width" in e:
            hw = np.broadcast_to(np.asarray(e["half_width"], dtype=float), base.shape)
            lo, hi = mean - hw, mean + hw
        else:
            lo = np.broadcast_to(np.asarray(e["low"], dtype=float), base.shape)
            hi = np.broadcast_to(np.asarray(e["high"], dtype=float), base.shape)
        draw = lo[free] + (hi[free] - lo[free]) * rng.random(n)
    out = base.copy()
    out[free] = base[free] * draw if rel else draw
    if key == "vehicle.inertia_kg_m2":
        out = np.triu(out) + np.triu(out, 1).T
    return out.tolist() if out.ndim else float(out)


def _draw_date(e, value, seed):
    rng = rng_for(seed, DATE_KEY)
    if "half_width_days" in e:
        hw = timedelta(days=e["half_width_days"])
        lo, hi = value - hw, value + hw
    else:
        lo, hi = datetime.fromisoformat(e["low"]), datetime.fromisoformat(e["high"])
    span_us = (hi - lo) // timedelta(microseconds=1)
    return config._iso_utc(lo + timedelta(microseconds=round(rng.random() * span_us)))


def _draw_target(e, seed):
    rng = rng_for(seed, TARGET_KEY)
    if e["dist"] == "choice":
        return {"star": e["stars"][int(rng.integers(len(e["stars"])))]}
    u = rng.random(2)
    return {"ra_deg": 360.0 * float(u[0]),
            "dec_deg": math.degrees(math.asin(2.0 * float(u[1]) - 1.0))}


def draw(cfg, seed=None) -> dict:
    """The values of the scenario's dispersions for mission seed ``seed``.

    Returns ``{key: value}`` in scenario form: a float, a list (nested for a
    matrix), an ISO-8601 date-time for ``mission.date_utc``, and for
    ``target`` ``{"star": name}`` or ``{"ra_deg": ..., "dec_deg": ...}``.
    """
    seed = int(cfg.mission.seed if seed is None else seed)
    out = {}
    for key, e in spec(cfg).items():
        if key == TARGET_KEY:
            out[key] = _draw_target(e, seed)
        elif key == DATE_KEY:
            out[key] = _draw_date(e, cfg.mission.date_utc, seed)
        else:
            sec, name = key.split(".")
            out[key] = _draw_number(key, e, getattr(getattr(cfg, sec), name), seed)
    return out


def spec(cfg) -> dict:
    """The scenario's dispersions as plain ``{key: entry}`` (empty when none)."""
    try:
        section = cfg.dispersions
    except AttributeError:
        return {}
    return {k: config._thaw(v) for k, v in section._values.items()}


def disperse(cfg, seed=None):
    """The scenario for mission seed ``seed`` with its dispersions drawn.

    Parameters
    ----------
    cfg : Scenario
        A validated scenario; its values are the centres of the dispersions.
    seed : int, optional
        Mission seed (default: the scenario's own).

    Returns
    -------
    (Scenario, dict)
        The scenario with ``mission.seed`` set, the drawn values in place and
        no dispersions left; and the drawn values (:func:`draw`). A scenario
        without dispersions, at its own seed, comes back unchanged.

    Raises
    ------
    ConfigError
        When a drawn value breaks its key's rule.
    """
    seed = int(cfg.mission.seed if seed is None else seed)
    drawn = draw(cfg, seed)
    if not drawn and seed == cfg.mission.seed:
        return cfg, drawn
    data = cfg.as_dict()
    data["mission"]["seed"] = seed
    data["dispersions"] = {}
    for key, v in drawn.items():
        if key == TARGET_KEY:
            data["target"] = dict(v)
        else:
            sec, name = key.split(".")
            data[sec][name] = v
    try:
        return config.scenario_from_dict(data), drawn
    except ConfigError as e:
        raise ConfigError(e.key, e._given, f"{e.rule} (drawn for mission.seed = {seed})"
                          ) from None


def flat_inputs(cfg, drawn: Mapping) -> dict:
    """Drawn values as flat columns: ``gyro.drift_deg_h[0]``, ``target.ra_deg``, ...

    Only the drawn elements of a matrix appear (not the misalignment diagonal,
    only the inertia upper triangle).
    """
    out = {}
    for key, v in drawn.items():
        if key == TARGET_KEY:
            out.update({f"target.{k}": x for k, x in v.items()})
        elif isinstance(v, list):
            arr = np.array(v, dtype=float)
            free = _free_mask(key, arr.shape)
            for idx in zip(*np.nonzero(free), strict=True):
                out[key + "".join(f"[{i}]" for i in idx)] = v[idx[0]] if len(idx) == 1 \
                    else v[idx[0]][idx[1]]
        else:
            out[key] = v
    return out


def input_columns(cfg) -> list:
    """The names :func:`flat_inputs` gives for this scenario's dispersions, in order."""
    cols = []
    for key, e in spec(cfg).items():
        if key == TARGET_KEY:
            cols += ["target.star"] if e["dist"] == "choice" else ["target.ra_deg",
                                                                   "target.dec_deg"]
        elif key == DATE_KEY:
            cols.append(key)
        else:
            sec, name = key.split(".")
            shape = _shape(getattr(getattr(cfg, sec), name))
            if not shape:
                cols.append(key)
                continue
            free = _free_mask(key, shape)
            cols += [key + "".join(f"[{i}]" for i in idx)
                     for idx in zip(*np.nonzero(free), strict=True)]
    return cols


def format_drawn(seed: int, drawn: Mapping) -> str:
    """The drawn values as text lines, for ``allsky run``."""
    lines = [f"Dispersions drawn for mission.seed = {seed}"]
    for key, v in drawn.items():
        if key == TARGET_KEY:
            text = ", ".join(f"{k} = {x!r}" for k, x in v.items())
            lines.append(f"  target: {text}")
        else:
            lines.append(f"  {key} = {config._toml_value(v)}")
    return "\n".join(lines)
