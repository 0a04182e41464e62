"""Scenario keys drawn at random per mission seed: the Monte Carlo dispersions.

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

Entries are merged and checked when the scenario loads
(:mod:`allsky.config.dispersion_table`): a date range must let a mission
started on any of its dates end inside the ephemeris range. A draw is
validated like any scenario value: a draw that breaks a rule (a negative
thrust, an inertia that is not positive definite, a number past the float
range) raises :class:`~allsky.config.rules.ConfigError` naming the key and
the drawn value; :func:`draw` and :func:`disperse` raise nothing else.
"""

import math
import zlib
from collections.abc import Mapping
from datetime import datetime, timedelta

import numpy as np

from allsky import xmath
from allsky.config.dispersion_table import DATE_KEY, TARGET_KEY, value_shape
from allsky.config.faults import is_fault_key
from allsky.config.rules import ConfigError
from allsky.config.scenario import scenario_from_dict
from allsky.config.toml_io import iso_utc, toml_value

#: Stream number of the dispersion draws under the mission seed.
DISPERSION_STREAM = 2


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
    # A draw past the float range becomes inf or nan, which the scenario's rules refuse.
    with np.errstate(over="ignore", invalid="ignore"):
        return _draw_number_of(key, e, value, seed)


def standard_normals(rng, n) -> np.ndarray:
    """``n`` N(0, 1) deviates from ``rng``'s uniforms, by Box and Muller's transform.

    NumPy's own normal deviates take a logarithm or an exponential from the
    C library now and then, whose last bit depends on the CPU; these are
    computed with the exact arithmetic of :mod:`allsky.xmath`.
    """
    u = rng.random(2 * ((n + 1) // 2))
    out = []
    for k in range(0, u.size, 2):
        r = math.sqrt(-2.0 * xmath.log(1.0 - float(u[k])))
        angle = 2.0 * math.pi * float(u[k + 1])
        out += [r * xmath.cos(angle), r * xmath.sin(angle)]
    return np.array(out[:n])


def _draw_number_of(key, e, value, seed):
    base = np.array(value, dtype=float)
    free = _free_mask(key, base.shape)
    n = 1 if e.get("shared") else int(free.sum())
    rng = rng_for(seed, key)
    rel = bool(e.get("relative"))
    mean = np.broadcast_to(np.asarray(e["mean"], dtype=float) if "mean" in e
                           else (1.0 if rel else base), base.shape)
    if e["dist"] == "normal":
        sigma = np.broadcast_to(np.asarray(e["sigma"], dtype=float), base.shape)
        draw = mean[free] + sigma[free] * standard_normals(rng, n)
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
    try:
        if "half_width_days" in e:
            hw = timedelta(days=e["half_width_days"])
            lo, hi = value - hw, value + hw
        else:
            lo, hi = datetime.fromisoformat(e["low"]), datetime.fromisoformat(e["high"])
        span_us = (hi - lo) // timedelta(microseconds=1)
        return iso_utc(lo + timedelta(microseconds=round(rng.random() * span_us)))
    except OverflowError:  # past the calendar (a spec the loader would have refused)
        raise ConfigError(DATE_KEY, rule=f"no date can be drawn from {dict(e)} about "
                          f"{iso_utc(value)}: past the calendar") from None


def _draw_target(e, seed):
    rng = rng_for(seed, TARGET_KEY)
    if e["dist"] == "choice":
        return {"star": e["stars"][int(rng.integers(len(e["stars"])))]}
    u = rng.random(2)
    return {"ra_deg": 360.0 * float(u[0]),
            "dec_deg": math.degrees(xmath.asin(2.0 * float(u[1]) - 1.0))}


def _draw_fault(key, e, seed):
    """Whether fault ``faults.N`` flies in this run (1.0 or 0.0), and its drawn onset [s]."""
    u = rng_for(seed, key).random(2)
    out = {"present": 1.0 if u[0] < e["probability"] else 0.0}
    if "low" in e:
        out["start_s"] = e["low"] + (e["high"] - e["low"]) * float(u[1])
    return out


def _kept_faults(faults, drawn):
    """The ``[[faults]]`` a run flies: those drawn present, with their drawn onsets."""
    out = []
    for i, f in enumerate(faults):
        d = drawn.get(f"faults.{i + 1}")
        if d is None:
            out.append(f)
        elif d["present"] and "start_s" in d:  # the drawn onset replaces the file's
            out.append({**{k: v for k, v in f.items() if k not in ("start_s", "start_mode")},
                        "start_s": d["start_s"]})
        elif d["present"]:
            out.append(f)
    return out


def draw(cfg, seed=None) -> dict:
    """The values of the scenario's dispersions for mission seed ``seed``.

    ``cfg`` is a validated :class:`~allsky.config.scenario.Scenario`; ``seed``
    defaults to its own ``mission.seed``.

    Returns ``{key: value}`` in scenario form: a float, a list (nested for a
    matrix), an ISO-8601 date-time for ``mission.date_utc``, and for
    ``target`` ``{"star": name}`` or ``{"ra_deg": ..., "dec_deg": ...}``.
    """
    seed = int(cfg.mission.seed if seed is None else seed)
    out = {}
    for key, e in spec(cfg).items():
        if key == TARGET_KEY:
            out[key] = _draw_target(e, seed)
        elif is_fault_key(key):
            out[key] = _draw_fault(key, e, seed)
        elif key == DATE_KEY:
            out[key] = _draw_date(e, cfg.mission.date_utc, seed)
        else:
            sec, name = key.split(".")
            out[key] = _draw_number(key, e, getattr(getattr(cfg, sec), name), seed)
    return out


def spec(cfg) -> dict:
    """The dispersions of scenario ``cfg`` as plain ``{key: entry}`` (empty when none)."""
    return cfg.as_dict().get("dispersions", {})


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
    data["faults"] = _kept_faults(data.get("faults", []), drawn)
    for key, v in drawn.items():
        if key == TARGET_KEY:
            data["target"] = dict(v)
        elif not is_fault_key(key):
            sec, name = key.split(".")
            data[sec][name] = v
    try:
        return scenario_from_dict(data), drawn
    except ConfigError as e:
        raise e.with_rule(f"{e.rule} (drawn for mission.seed = {seed})") from None


def flat_inputs(cfg, drawn: Mapping) -> dict:
    """Drawn values as flat columns: ``gyro.drift_deg_h[0]``, ``target.ra_deg``, ...

    ``drawn`` is :func:`draw`'s result for scenario ``cfg``; the columns
    follow from ``drawn`` alone (``cfg`` is taken, as by :func:`input_columns`,
    for the caller's convenience). Only the drawn elements of a matrix appear
    (not the misalignment diagonal, only the inertia upper triangle).
    """
    out = {}
    for key, v in drawn.items():
        if key == TARGET_KEY:
            out.update({f"target.{k}": x for k, x in v.items()})
        elif is_fault_key(key):
            out.update({f"{key}.{k}": x for k, x in v.items()})
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
    """Names :func:`flat_inputs` gives for scenario ``cfg``'s dispersions, in order."""
    cols = []
    for key, e in spec(cfg).items():
        if key == TARGET_KEY:
            cols += ["target.star"] if e["dist"] == "choice" else ["target.ra_deg",
                                                                   "target.dec_deg"]
        elif is_fault_key(key):
            cols += [f"{key}.present"] + ([f"{key}.start_s"] if "low" in e else [])
        elif key == DATE_KEY:
            cols.append(key)
        else:
            sec, name = key.split(".")
            shape = value_shape(getattr(getattr(cfg, sec), name))
            if not shape:
                cols.append(key)
                continue
            free = _free_mask(key, shape)
            cols += [key + "".join(f"[{i}]" for i in idx)
                     for idx in zip(*np.nonzero(free), strict=True)]
    return cols


def format_drawn(seed: int, drawn: Mapping) -> str:
    """Values ``drawn`` (:func:`draw`) for mission ``seed``, as ``allsky run`` shows."""
    lines = [f"Dispersions drawn for mission.seed = {seed}"]
    for key, v in drawn.items():
        if key == TARGET_KEY:
            text = ", ".join(f"{k} = {x!r}" for k, x in v.items())
            lines.append(f"  target: {text}")
        else:
            lines.append(f"  {key} = {toml_value(v)}")
    return "\n".join(lines)
