"""Scenarios: TOML files, ``KEY=VALUE`` overrides, validation, a frozen result.

The packaged default (``scenarios/default.toml``, :data:`DEFAULT_SCENARIO_PATH`)
is the schema: every key it has, with the unit in the key's name, and nothing
else. A user scenario file is merged over the default, table by table and key
by key, so a file states only what it changes. A section or key the default
does not have is an error naming the nearest valid keys.

Overrides (``allsky ... --set KEY=VALUE``) are applied after the file, in
order, by the same merge. KEY is a dotted path (``gyro.drift_deg_h``,
``sequencer.timeout_s.6-1``); VALUE is in TOML value syntax
(``[800,-300,1500]``, ``2027-03-01T00:00:00Z``, ``"Vega"``, ``{ "1" = 600 }``);
a VALUE that is not TOML is taken as a plain string (``target.star=Vega``).

The target is given in exactly one of two forms: ``target.star`` (a name in
PyEphem's catalog, any case) or ``target.ra_deg`` + ``target.dec_deg`` (J2000,
degrees). A table that sets both forms is an error; setting either form (in a
file or by an override) removes the other form inherited from the default,
the file or an earlier override. In the result the unused form is ``None``.

``mission.date_utc`` may be a TOML date-time (with an offset, or local, which
is read as UTC), a TOML date (midnight UTC) or an ISO-8601 string; it becomes
a timezone-aware UTC :class:`~datetime.datetime`. ``ejection.attitude`` is
``"random"`` or a quaternion ``[w, x, y, z]`` (scalar first) rotating
inertial-frame components into body-frame components; it is normalised on
load. ``vehicle.inertia_kg_m2`` is stored exactly symmetric (the upper
triangle, after checking symmetry to a relative 1e-9).

``[dispersions]`` (empty in the default) names keys drawn at random per
mission seed for Monte Carlo campaigns (syntax and seeding:
:mod:`allsky.config.dispersions`, ``docs/montecarlo.md``); its entries are merged by
key, and ``load_scenario(..., disperse=FILE)`` merges a file's
``[dispersions]`` table over the scenario's.

Every value is checked once, here: its type (an integer is accepted where a
float is expected; a boolean or a string is never a number), finiteness, its
own rule (:data:`RULES`, one entry per key) and the rules tying keys together
(:data:`CROSS_RULES`). Anything wrong raises :class:`ConfigError` naming the
key, the value and the rule; no other exception escapes for any file content.
"""

import difflib
import functools
import math
import re
import tomllib
from collections.abc import Callable, Mapping
from datetime import UTC, date, datetime, time
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

#: The packaged default scenario; it also defines the schema.
DEFAULT_SCENARIO_PATH = Path(str(resources.files("allsky") / "scenarios" / "default.toml"))
#: The master-sequencer modes, the keys of ``sequencer.timeout_s``.
MODE_KEYS = ("1", "2", "3", "4", "5", "6-1", "6-2")
#: Dates the ephemeris is trusted for (PyEphem; the same as ``allsky.vehicle.sky.EPHEMERIS_YEARS``).
EPHEMERIS_START_UTC = datetime(1900, 1, 1, tzinfo=UTC)
EPHEMERIS_END_UTC = datetime(2100, 12, 31, 23, 59, 59, 999999, tzinfo=UTC)
#: The two forms of ``[target]``; keys the default need not contain.
TARGET_STAR_FORM = ("star",)
TARGET_RADEC_FORM = ("ra_deg", "dec_deg")

_KEY_PART = re.compile(r"[A-Za-z0-9_-]+")


class _Absent:
    """Marks a ConfigError with no value to show (pickles as this very object)."""

    def __reduce__(self):
        return "_ABSENT"


_ABSENT = _Absent()


class ConfigError(Exception):
    """A scenario that cannot be used: ``str()`` is one line, ``key = value: rule``.

    Attributes
    ----------
    key : str or None
        Dotted key path (``gyro.arw_deg_rt_h``), or None for a whole-file problem.
    value : object
        The offending value (a number as the float it became; None when none is shown).
    rule : str
        The rule that was broken, in words.
    """

    def __init__(self, key, value=_ABSENT, rule=""):
        self.key, self.rule, self._given = key, rule, value
        self.value = None if value is _ABSENT else value
        if key is None:
            text = rule
        elif value is _ABSENT:
            text = f"{_show_key(key)}: {rule}"
        else:
            text = f"{_show_key(key)} = {_show_value(value)}: {rule}"
        # One line whatever the file held (a key or a path may contain newlines).
        super().__init__(text.replace("\r", "\\r").replace("\n", "\\n"))

    def __reduce__(self):  # so that it crosses process boundaries intact
        return type(self), (self.key, self._given, self.rule)


def _show_key(key: str) -> str:
    return key if key.isprintable() else repr(key)


def _show_value(value, limit=120) -> str:
    text = value.isoformat() if isinstance(value, datetime | date | time) else repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ---------------------------------------------------------------------------
# Checkers. Each takes (key, value as read) and returns the frozen value or
# raises ConfigError. A Cond is one numeric rule: its text and its test.
# ---------------------------------------------------------------------------

class Cond(NamedTuple):
    """A rule on one number: the words shown when it fails, and the test."""

    text: str
    ok: Callable[[float], bool]


def _g(x) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


POSITIVE = Cond("must be > 0", lambda x: x > 0)
NON_NEGATIVE = Cond("must be >= 0", lambda x: x >= 0)


def at_least(lo):
    return Cond(f"must be >= {_g(lo)}", lambda x: x >= lo)


def below(hi):
    return Cond(f"must be < {_g(hi)}", lambda x: x < hi)


def in_closed(lo, hi):
    return Cond(f"must be in [{_g(lo)}, {_g(hi)}]", lambda x: lo <= x <= hi)


def in_open(lo, hi):
    return Cond(f"must be in ({_g(lo)}, {_g(hi)})", lambda x: lo < x < hi)


def in_open_closed(lo, hi):
    return Cond(f"must be in ({_g(lo)}, {_g(hi)}]", lambda x: lo < x <= hi)


def in_closed_open(lo, hi):
    return Cond(f"must be in [{_g(lo)}, {_g(hi)})", lambda x: lo <= x < hi)


def magnitude_at_most(limit):
    return Cond(f"magnitude must be <= {_g(limit)}", lambda x: abs(x) <= limit)


_TOML_TYPE_NAMES = ((bool, "a boolean"), (int, "an integer"), (float, "a float"),
                    (str, "a string"), (list, "an array"), (dict, "a table"),
                    (datetime, "a date-time"), (date, "a date"), (time, "a time"))


def _type_name(v) -> str:
    for t, name in _TOML_TYPE_NAMES:
        if isinstance(v, t):
            return name
    return type(v).__name__


def _as_float(v):
    """``(float, None)`` or ``(None, reason)``: a finite number, ints accepted, bools not."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None, f"must be a number, not {_type_name(v)}"
    try:
        x = float(v)
    except OverflowError:  # an integer too large for a float
        return None, "must be finite"
    if not math.isfinite(x):
        return None, "must be finite (not nan or inf)"
    return x, None


def _apply(conds, key, x, shown, where=""):
    for c in conds:
        if not c.ok(x):
            raise ConfigError(key, shown, f"{where}{c.text}")


def _allowed(what, conds, each=False):
    """Words for the configuration reference: ``a number; must be > 0``."""
    rules = "; ".join(("each " if each else "") + c.text.removeprefix("must be ")
                      for c in conds)
    return f"{what}, {rules}" if rules else what


def allowed(key: str) -> str:
    """What :data:`RULES` accepts for ``key``, in words (for the configuration reference)."""
    rule = RULES[key]
    return rule.allowed


def number(*conds: Cond):
    """A finite float (an integer is accepted) obeying every ``Cond``."""
    def check(key, v):
        x, why = _as_float(v)
        if why:
            raise ConfigError(key, v, why)
        _apply(conds, key, x, x)  # shown as the float it became: -1 -> -1.0
        return x
    check.allowed = _allowed("a number", conds)
    return check


def integer(*conds: Cond):
    """An integer (not a float, not a boolean) obeying every ``Cond``."""
    def check(key, v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(key, v, f"must be an integer, not {_type_name(v)}")
        _apply(conds, key, v, v)
        return v
    check.allowed = _allowed("an integer", conds)
    return check


def _array(key, v, shape):
    """Nested tuples of finite floats with the exact ``shape`` (1 or 2 dimensions)."""
    what = (f"an array of {shape[0]} numbers" if len(shape) == 1 else
            f"a {shape[0]}x{shape[1]} array ({shape[0]} arrays of {shape[1]} numbers)")
    if not isinstance(v, list) or len(v) != shape[0]:
        got = f"{len(v)} elements" if isinstance(v, list) else _type_name(v)
        raise ConfigError(key, v, f"must be {what}, not {got}")
    if len(shape) == 2:
        if not all(isinstance(r, list) and len(r) == shape[1] for r in v):
            raise ConfigError(key, v, f"must be {what}")
        return tuple(tuple(_element(key, v, x, f"[{i}][{j}]") for j, x in enumerate(row))
                     for i, row in enumerate(v))
    return tuple(_element(key, v, x, f"{i}") for i, x in enumerate(v))


def _element(key, whole, x, index):
    f, why = _as_float(x)
    if why:
        raise ConfigError(key, whole, f"element {index} {why}")
    return f


def vector(n: int, *conds: Cond):
    """An array of ``n`` finite floats, each obeying every ``Cond``."""
    def check(key, v):
        xs = _array(key, v, (n,))
        for i, x in enumerate(xs):
            _apply(conds, key, x, v, where=f"element {i} ")
        return xs
    check.allowed = _allowed(f"{n} numbers", conds, each=True)
    return check


def one_of(*choices: str):
    """One of the given strings."""
    def check(key, v):
        if not isinstance(v, str) or v not in choices:
            quoted = [f'"{c}"' for c in choices]
            raise ConfigError(key, v, f"must be {', '.join(quoted[:-1])} or {quoted[-1]}")
        return v
    check.allowed = "one of " + ", ".join(f'"{c}"' for c in choices)
    return check


def boolean(key, v):
    """``true`` or ``false``."""
    if not isinstance(v, bool):
        raise ConfigError(key, v, f"must be true or false, not {_type_name(v)}")
    return v


def utc_datetime(key, v):
    """A date-time in the ephemeris range, returned timezone-aware in UTC."""
    shown = v
    if isinstance(v, str):
        try:
            v = datetime.fromisoformat(v.strip())
        except ValueError:
            raise ConfigError(key, shown, "must be an ISO-8601 date-time such as "
                              "2026-11-22T12:00:00Z") from None
    elif isinstance(v, date) and not isinstance(v, datetime):
        v = datetime.combine(v, time(0, 0))
    elif not isinstance(v, datetime):
        raise ConfigError(key, v, f"must be a TOML date-time or an ISO-8601 string, "
                          f"not {_type_name(v)}")
    rule = (f"must be within the ephemeris range {EPHEMERIS_START_UTC.date()}.."
            f"{EPHEMERIS_END_UTC.date()} (UTC)")
    try:
        v = v.replace(tzinfo=UTC) if v.tzinfo is None else v.astimezone(UTC)
    except OverflowError:  # year 1 or 9999 moved across midnight by its offset
        raise ConfigError(key, shown, rule) from None
    if not EPHEMERIS_START_UTC <= v <= EPHEMERIS_END_UTC:
        raise ConfigError(key, shown, rule)
    return v


def inertia_tensor(key, v):
    """A rigid body's inertia tensor: symmetric, positive definite, triangle inequalities."""
    j = np.array(_array(key, v, (3, 3)))
    scale = float(np.abs(j).max())
    if scale == 0.0:
        raise ConfigError(key, v, "must be positive definite (all elements are 0)")
    js = j / scale  # dimensionless, so no overflow for any finite input
    if not np.all(np.abs(js - js.T) <= 1e-9):
        raise ConfigError(key, v, "must be symmetric (to a relative 1e-9)")
    a, b, c = np.linalg.eigvalsh(js)  # ascending
    moments = ", ".join(f"{float(m) * scale:.6g}" for m in (a, b, c))
    if a <= 1e-12 * c:
        raise ConfigError(key, v, f"must be positive definite (principal moments {moments})")
    if a + b < c * (1 - 1e-9):
        raise ConfigError(key, v, f"principal moments {moments} break the triangle inequality"
                          " (each must be <= the sum of the other two)")
    # Mirror the upper triangle: exactly symmetric, and unchanged when loaded again.
    return tuple(tuple(float(j[min(r, k), max(r, k)]) for k in range(3)) for r in range(3))


def misalignment_matrix(key, v):
    """Gyro input-axis misalignments: 3x3, zero diagonal, each within 1 degree."""
    m = _array(key, v, (3, 3))
    if any(m[i][i] != 0.0 for i in range(3)):
        raise ConfigError(key, v, "diagonal must be 0: scale-factor error is set by "
                          "gyro.scale_factor_error_ppm")
    if any(abs(x) > 3600.0 for row in m for x in row):
        raise ConfigError(key, v, "every element's magnitude must be <= 3600 arcsec")
    return m


def attitude(key, v):
    """``"random"``, or a quaternion [w, x, y, z] (inertial -> body), returned normalised."""
    if v == "random":
        return "random"
    if not isinstance(v, list):
        raise ConfigError(key, v, 'must be "random" or a quaternion [w, x, y, z] '
                          "(inertial -> body)")
    given = _array(key, v, (4,))
    big = max(abs(x) for x in given)
    if big == 0.0:
        raise ConfigError(key, v, "quaternion [w, x, y, z] must not be all zero")
    if abs(math.fsum(x * x for x in given) - 1.0) <= 4e-16:
        return given  # already unit: kept bit for bit, so a saved scenario loads unchanged
    q = np.array(given) / big  # scaled first so that 1e-320 or 1e308 normalise too
    return tuple(float(x) for x in q / np.linalg.norm(q))


def mode_timeouts(key, v):
    """A table with exactly the keys ``MODE_KEYS``, each a time > 0 s."""
    if not isinstance(v, dict):
        raise ConfigError(key, v, f"must be a table of the modes {', '.join(MODE_KEYS)}")
    missing = [m for m in MODE_KEYS if m not in v]
    extra = [m for m in v if m not in MODE_KEYS]
    if missing or extra:
        raise ConfigError(key, v, f"must have exactly the modes {', '.join(MODE_KEYS)}")
    check = number(POSITIVE)
    return {m: check(f"{key}.{m}", v[m]) for m in MODE_KEYS}


def magnitude_window(key, v):
    """[brightest, faintest] visual magnitudes, brightest < faintest."""
    lo, hi = _array(key, v, (2,))
    if not lo < hi:
        raise ConfigError(key, v, "must be [brightest, faintest] with brightest < faintest")
    return (lo, hi)


@functools.cache
def _catalog() -> dict:
    import ephem.stars

    return {name.lower(): name for name in ephem.stars.stars}


def star_name(key, v):
    """A star of PyEphem's catalog (any case), returned with its catalog spelling."""
    if not isinstance(v, str):
        raise ConfigError(key, v, f"must be a star name (a string), not {_type_name(v)}")
    found = _catalog().get(v.strip().lower())
    if found is None:
        near = difflib.get_close_matches(v.strip().lower(), list(_catalog()), n=3, cutoff=0.5)
        hint = ("; nearest: " + ", ".join(_catalog()[n] for n in near)) if near else ""
        raise ConfigError(key, v, f"not in the PyEphem star catalog{hint}")
    return found


# Words for the configuration reference (see :func:`allowed`).
utc_datetime.allowed = (f"a date-time (TOML or ISO-8601 string), UTC, within "
                        f"{EPHEMERIS_START_UTC.date()}..{EPHEMERIS_END_UTC.date()}")
inertia_tensor.allowed = ("a 3x3 array: symmetric, positive definite, principal moments "
                          "obeying the triangle inequality")
misalignment_matrix.allowed = "a 3x3 array, diagonal 0, each element within +-3600"
attitude.allowed = '"random", or a quaternion [w, x, y, z] (inertial to body; normalised)'
mode_timeouts.allowed = f"a table of the modes {', '.join(MODE_KEYS)}, each > 0"
magnitude_window.allowed = "[brightest, faintest], brightest < faintest"
star_name.allowed = "a star name of the PyEphem catalog (any case)"
boolean.allowed = "true or false"

#: One checker per key, in the order of the default file.
RULES: dict[str, Callable] = {
    "mission.date_utc": utc_datetime,
    "mission.seed": integer(at_least(0), below(2**32)),
    "mission.frame_s": number(POSITIVE),
    "mission.telemetry_every_frames": integer(at_least(1)),
    "ejection.attitude": attitude,
    "ejection.tipoff_rate_max_deg_s": number(NON_NEGATIVE),
    "vehicle.inertia_kg_m2": inertia_tensor,
    "gyro.drift_deg_h": vector(3),
    "gyro.scale_factor_error_ppm": vector(3, magnitude_at_most(1e5)),
    "gyro.misalignment_arcsec": misalignment_matrix,
    "gyro.arw_deg_rt_h": number(NON_NEGATIVE),
    "gyro.rrw_deg_h_rt_h": number(NON_NEGATIVE),
    "gyro.range_deg_s": number(POSITIVE),
    "sun_sensor.linear_range_arcsec": number(POSITIVE),
    "sun_sensor.presence_half_angle_deg": number(in_open_closed(0, 90)),
    "sun_sensor.noise_arcsec": number(NON_NEGATIVE),
    "sun_sensor.coarse_noise_deg": number(NON_NEGATIVE),
    "star_tracker.fov_long_half_deg": number(in_open(0, 90)),
    "star_tracker.fov_narrow_half_deg": number(in_open(0, 90)),
    "star_tracker.magnitude_window": magnitude_window,
    "star_tracker.noise_arcsec": number(NON_NEGATIVE),
    "jets.thrust_n": vector(3, POSITIVE),
    "jets.moment_arm_m": vector(3, POSITIVE),
    "jets.min_on_time_s": number(POSITIVE),
    "jets.isp_s": number(POSITIVE),
    "jets.propellant_kg": number(POSITIVE),
    "pwpf.filter_gain": number(POSITIVE),
    "pwpf.time_constant_s": number(POSITIVE),
    "pwpf.on_threshold_v": number(POSITIVE),
    "pwpf.off_threshold_v": number(NON_NEGATIVE),
    "pwpf.full_on_v": number(POSITIVE),
    "control.position_gain_v_per_arcsec": vector(3, POSITIVE),
    "control.rate_gain_v_per_arcsec_s": vector(3, POSITIVE),
    "control.position_limit_arcsec": vector(3, POSITIVE),
    "control.output_limit_v": number(POSITIVE),
    "control.integral_time_s": number(POSITIVE),
    "control.integral_limit_arcsec": number(POSITIVE),
    "electronics.vfc_pulse_weight_arcsec": number(POSITIVE),
    "electronics.vfc_max_rate_pps": number(POSITIVE),
    "electronics.counter_bits": integer(in_closed(8, 62)),
    "electronics.drift_counter_bits": integer(in_closed(4, 62)),
    "electronics.counter_overflow": one_of("wrap", "saturate"),
    "electronics.drift_dac_bits": integer(in_closed(4, 32)),
    "electronics.register_bits": integer(in_closed(4, 32)),
    "electronics.register_lsb_arcsec": number(POSITIVE),
    "electronics.rate_command_deg_s": number(POSITIVE),
    "electronics.computer_step_frames": integer(at_least(1)),
    "sequencer.settle_threshold_arcsec": number(POSITIVE),
    "sequencer.settle_time_s": number(POSITIVE),
    "sequencer.handover_arcsec": number(POSITIVE),
    "sequencer.drift_count_s": number(POSITIVE),
    "sequencer.tracker_blanking_s": number(POSITIVE),
    "sequencer.sensor_loss_s": number(POSITIVE),
    "sequencer.mode1_slew_rate_deg_s": number(POSITIVE),
    "sequencer.mode1_slew_gain_per_s": number(POSITIVE),
    "sequencer.timeout_s": mode_timeouts,
    "target.star": star_name,
    "target.ra_deg": number(in_closed_open(0, 360)),
    "target.dec_deg": number(in_closed(-90, 90)),
    "calibration.apply": boolean,
    "dither.amplitude_urad": vector(3, NON_NEGATIVE),
    "dither.period_s": vector(3, POSITIVE),
    "dither.sample_s": number(POSITIVE),
    "dither.record_s": number(POSITIVE),
    "dither.lead_in_s": number(NON_NEGATIVE),
    "dither.feedforward": boolean,
    "dither.inertia_estimate_scale": number(NON_NEGATIVE),
    "dither.estimator": one_of("optical", "command"),
    "dither.detector": one_of("fft", "hann", "lsq"),
    "dither.store_cross_coupling": boolean,
}


# ---------------------------------------------------------------------------
# Rules that tie keys together (run after every key passed its own rule).
# ---------------------------------------------------------------------------

def _frame_fits_jet_minimum(v):
    """`mission.frame_s` <= `jets.min_on_time_s` (a valve pulse lasts whole frames)."""
    frame, t_min = v["mission.frame_s"], v["jets.min_on_time_s"]
    if frame > t_min * (1 + 1e-12):
        raise ConfigError("mission.frame_s", frame,
                          f"frame too coarse for the jet minimum on-time: must be <= "
                          f"jets.min_on_time_s ({t_min:g} s)")


def _pwpf_hysteresis(v):
    """`pwpf.off_threshold_v` < `pwpf.on_threshold_v` (the modulator's hysteresis)."""
    on, off = v["pwpf.on_threshold_v"], v["pwpf.off_threshold_v"]
    if not on > off:
        raise ConfigError("pwpf.off_threshold_v", off,
                          f"must be < pwpf.on_threshold_v ({on:g} V)")


def _sun_presence_covers_linear_range(v):
    """`sun_sensor.presence_half_angle_deg` >= the fine linear range."""
    half, lin_deg = v["sun_sensor.presence_half_angle_deg"], v["sun_sensor.linear_range_arcsec"]
    lin_deg /= 3600.0
    if half < lin_deg:
        raise ConfigError("sun_sensor.presence_half_angle_deg", half,
                          f"must be >= the sun sensor linear range ({lin_deg:g} deg)")


def _dither_sampling(v):
    """`dither.sample_s` >= `mission.frame_s`; a dithered axis's period > 2 samples."""
    sample, frame = v["dither.sample_s"], v["mission.frame_s"]
    if sample < frame * (1 - 1e-12):
        raise ConfigError("dither.sample_s", sample,
                          f"must be >= mission.frame_s ({frame:g} s): samples are taken "
                          "once a frame at most")
    pairs = zip(v["dither.amplitude_urad"], v["dither.period_s"], strict=True)
    for axis, (amp, period) in enumerate(pairs):
        if amp > 0 and not period > 2 * sample:
            raise ConfigError("dither.period_s", v["dither.period_s"],
                              f"element {axis} must be > 2 x dither.sample_s ({2 * sample:g} s)"
                              " (Nyquist) on a dithered axis")


def _one_target_form(v):
    """`target.star`, or both `target.ra_deg` and `target.dec_deg`."""
    if v["target.star"] is not None:
        return
    for k in TARGET_RADEC_FORM:
        if v[f"target.{k}"] is None:
            raise ConfigError(f"target.{k}", rule="missing: give target.star, or both "
                              "target.ra_deg and target.dec_deg")


#: Cross-key rules, in the order they are checked.
CROSS_RULES = (_frame_fits_jet_minimum, _pwpf_hysteresis, _sun_presence_covers_linear_range,
               _dither_sampling, _one_target_form)


# ---------------------------------------------------------------------------
# Reading and merging
# ---------------------------------------------------------------------------

def _read_toml(path) -> dict:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(None, str(p), f"scenario file not found: {p}") from None
    except (OSError, ValueError) as e:  # a directory, no permission, not UTF-8, NUL in path
        raise ConfigError(None, str(p), f"cannot read scenario file {p}: {e}") from None
    return _parse_toml(text, str(p))


def _parse_toml(text: str, source: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:  # its message gives the line and column
        raise ConfigError(None, source, f"{source}: TOML syntax error: {e}") from None
    except RecursionError:
        raise ConfigError(None, source, f"{source}: TOML syntax error: nested too deeply"
                          ) from None


@functools.cache
def _default_text() -> str:
    return DEFAULT_SCENARIO_PATH.read_text(encoding="utf-8")


@functools.cache
def _default_parsed() -> dict:
    return _parse_toml(_default_text(), str(DEFAULT_SCENARIO_PATH))


def _default_dict() -> dict:
    """A fresh copy of the parsed default (parsed once: a campaign builds one per run)."""
    return _copy_tables(_default_parsed())


def _copy_tables(v):
    """Copy of TOML data: tables and arrays copied, scalars (immutable) shared."""
    if isinstance(v, Mapping):
        return {k: _copy_tables(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_copy_tables(x) for x in v]
    return v


@functools.cache
def _schema() -> dict:
    """Nested dict of every valid key (the default plus the optional target keys)."""
    schema = _default_dict()
    schema["target"] = {**schema["target"], **dict.fromkeys(TARGET_STAR_FORM + TARGET_RADEC_FORM)}
    return schema


def _all_keys(schema=None, prefix="") -> list:
    schema = _schema() if schema is None else schema
    out = []
    for k, v in schema.items():
        out.append(prefix + k)
        if isinstance(v, dict):
            out += _all_keys(v, f"{prefix}{k}.")
    return out


def _unknown(path: tuple, schema: dict) -> ConfigError:
    """Error for an unknown key, naming the nearest valid keys."""
    key = ".".join(path)
    valid = _all_keys()
    same_depth = [k for k in valid if k.count(".") == key.count(".")]
    near = difflib.get_close_matches(key, same_depth, n=3, cutoff=0.6)
    # Also the right name in the wrong section (gyro.inertia_kg_m2 -> vehicle.inertia_kg_m2).
    by_name = {}
    for full in valid:
        by_name.setdefault(full.rsplit(".", 1)[-1], []).append(full)
    for name in difflib.get_close_matches(path[-1], list(by_name), n=2, cutoff=0.8):
        near += [k for k in by_name[name] if k not in near and k in same_depth]
    if near:
        hint = "nearest valid keys: " + ", ".join(near[:4])
    elif len(path) > 1:
        hint = "valid keys here: " + ", ".join(sorted(schema))
    else:
        hint = "valid sections: " + ", ".join(schema)
    return ConfigError(key, rule=f"unknown key; {hint}")


def _merge(base: dict, incoming: dict, schema: dict, path=()) -> None:
    """Merge ``incoming`` over ``base`` in place: tables key by key, other values replaced."""
    if path == ("target",):
        _replace_target_form(base, incoming)
    for k, v in incoming.items():
        here = (*path, k)
        if not path and k == "dispersions":  # entries by key: see allsky.config.dispersions
            from allsky.config import dispersions

            base[k] = dispersions.merge(base.get(k) or {}, v)
            continue
        if k not in schema:
            raise _unknown(here, schema)
        if isinstance(schema[k], dict):
            if not isinstance(v, dict):
                raise ConfigError(".".join(here), v, f"must be a table, not {_type_name(v)}")
            if not isinstance(base.get(k), dict):
                base[k] = {}
            _merge(base[k], v, schema[k], here)
        else:
            base[k] = v


def _replace_target_form(base: dict, incoming: dict) -> None:
    star = [k for k in TARGET_STAR_FORM if k in incoming]
    radec = [k for k in TARGET_RADEC_FORM if k in incoming]
    if star and radec:
        raise ConfigError("target", incoming, "set either target.star or target.ra_deg + "
                          "target.dec_deg, not both")
    for k in TARGET_RADEC_FORM if star else TARGET_STAR_FORM if radec else ():
        base.pop(k, None)


def parse_override(item: str) -> dict:
    """``"a.b=VALUE"`` -> ``{"a": {"b": value}}``; VALUE in TOML syntax, else a plain string."""
    if not isinstance(item, str) or "=" not in item:
        raise ConfigError(None, item, f"override {item!r} must be KEY=VALUE, "
                          "e.g. gyro.arw_deg_rt_h=0.002")
    key, text = item.split("=", 1)
    parts = [p.strip() for p in key.split(".")]
    if not all(_KEY_PART.fullmatch(p) for p in parts):
        raise ConfigError(None, item, f"override {item!r}: KEY must be a dotted path "
                          "such as gyro.drift_deg_h")
    value = _parse_value(text)
    for p in reversed(parts):
        value = {p: value}
    return value


def _parse_value(text: str):
    try:
        parsed = tomllib.loads(f"v = {text}")
    except (tomllib.TOMLDecodeError, RecursionError):
        return text.strip()
    return parsed["v"] if list(parsed) == ["v"] else text.strip()


# ---------------------------------------------------------------------------
# The frozen result
# ---------------------------------------------------------------------------

def _freeze(v):
    if isinstance(v, Mapping):
        return MappingProxyType({k: _freeze(x) for k, x in v.items()})
    if isinstance(v, list | tuple):
        return tuple(_freeze(x) for x in v)
    return v


def _thaw(v):
    if isinstance(v, Mapping):
        return {k: _thaw(x) for k, x in v.items()}
    if isinstance(v, tuple):
        return [_thaw(x) for x in v]
    return v


def _iso_utc(d: datetime) -> str:
    frac = f".{d.microsecond:06d}" if d.microsecond else ""
    return f"{d.year:04d}-{d:%m-%dT%H:%M:%S}{frac}Z"  # %Y drops the zeros of year 999


class Section:
    """One frozen scenario section: its keys as read-only attributes."""

    __slots__ = ("_name", "_values")
    __hash__ = None

    def __init__(self, name: str, values: Mapping):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_values", {k: _freeze(v) for k, v in values.items()})

    def __getattr__(self, key):
        if key.startswith("_"):
            raise AttributeError(key)
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"scenario section [{self._name}] has no key {key!r}") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __delattr__(self, key):
        raise AttributeError("a Scenario is frozen")

    def __dir__(self):
        return sorted(self._values)

    def __eq__(self, other):
        if not isinstance(other, Section):
            return NotImplemented
        return self._name == other._name and self._values == other._values

    def __reduce__(self):
        return Section, (self._name, _thaw(self._values))

    def __repr__(self):
        return f"Section({self._name!r}, {_thaw(self._values)!r})"


class Scenario:
    """A validated, frozen scenario: ``cfg.section.key`` (build it with :func:`load_scenario`).

    Vectors are tuples of floats, matrices tuples of tuples, ``mission.date_utc``
    a UTC datetime, ``sequencer.timeout_s`` a read-only mapping mode -> seconds.
    """

    __slots__ = ("_sections",)
    __hash__ = None

    def __init__(self, sections: Mapping[str, Mapping]):
        object.__setattr__(self, "_sections",
                           {name: Section(name, values) for name, values in sections.items()})

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._sections[name]
        except KeyError:
            raise AttributeError(f"scenario has no section [{name}]") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __delattr__(self, key):
        raise AttributeError("a Scenario is frozen")

    def __dir__(self):
        return [*self._sections, "as_dict", "to_toml"]

    def __eq__(self, other):
        if not isinstance(other, Scenario):
            return NotImplemented
        return self._sections == other._sections

    def __reduce__(self):
        return Scenario, ({n: _thaw(s._values) for n, s in self._sections.items()},)

    def __repr__(self):
        t = self.target
        what = t.star or f"RA {t.ra_deg:g} deg, Dec {t.dec_deg:g} deg"
        return f"<Scenario {_iso_utc(self.mission.date_utc)} seed {self.mission.seed}: {what}>"

    def _export(self, date_as_text: bool) -> dict:
        out = {}
        for name, sec in self._sections.items():
            table = out[name] = {}
            for k, v in sec._values.items():
                if v is None:  # the target form not in use
                    continue
                if isinstance(v, datetime) and date_as_text:
                    v = _iso_utc(v)
                table[k] = _thaw(v)
        return out

    def as_dict(self) -> dict:
        """Plain nested dict of lists, floats and strings (the date as ``YYYY-MM-DDTHH:MM:SSZ``).

        :func:`scenario_from_dict` turns it back into an equal Scenario.
        """
        return self._export(date_as_text=True)

    def to_toml(self) -> str:
        """The fully resolved scenario as TOML text that loads back to an equal Scenario."""
        header = "# allsky scenario, fully resolved (every key, validated)\n\n"
        return header + toml_dumps(self._export(date_as_text=False))


# ---------------------------------------------------------------------------
# A small TOML writer (enough for scenarios: tables of scalars, arrays, inline tables)
# ---------------------------------------------------------------------------

_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f",
            "\r": "\\r"}


def _toml_key(k: str) -> str:
    return k if _KEY_PART.fullmatch(k) else _toml_string(k)


def _toml_string(s: str) -> str:
    out = []
    for ch in s:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)  # shortest text that reads back to the same float
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, datetime):
        if v.tzinfo is not None and v.utcoffset().total_seconds() == 0:
            return _iso_utc(v)
        return v.isoformat()
    if isinstance(v, date | time):
        return v.isoformat()
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        if not v:
            return "{}"
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def toml_dumps(doc: Mapping) -> str:
    """TOML text for a dict of tables (and top-level scalars); ``tomllib.loads`` reads it back."""
    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in doc.items()
             if not isinstance(v, Mapping)]
    for name, table in doc.items():
        if isinstance(table, Mapping):
            if lines:
                lines.append("")
            lines.append(f"[{_toml_key(name)}]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------

def _validate(data: dict) -> dict:
    """Check every key of the merged dict; return ``{section: {key: value}}``."""
    flat = {}
    for key, rule in RULES.items():
        sec, name = key.split(".")
        if name in data.get(sec, {}):
            flat[key] = rule(key, data[sec][name])
        elif sec == "target":
            flat[key] = None
        else:
            raise ConfigError(key, rule="missing")
    for rule in CROSS_RULES:
        rule(flat)
    sections = {}
    for key, v in flat.items():
        sec, name = key.split(".")
        sections.setdefault(sec, {})[name] = v
    from allsky.config import dispersions

    sections["dispersions"] = dispersions.validate(data.get("dispersions") or {}, flat)
    # A key just added to the default but not yet to RULES is kept as read (frozen), so
    # the simulator can use it; test_config checks that RULES covers the whole schema.
    for sec, table in data.items():
        for name, v in table.items():
            sections.setdefault(sec, {}).setdefault(name, v)
    return sections


def scenario_from_dict(data: Mapping, overrides=()) -> Scenario:
    """Validate a nested dict (as from a TOML file or :meth:`Scenario.as_dict`).

    Parameters
    ----------
    data : dict
        Sections of keys; merged over the packaged default.
    overrides : iterable of str
        ``KEY=VALUE`` strings applied after ``data``, in order.

    Raises
    ------
    ConfigError
        For an unknown key or any value that breaks its rule.
    """
    if isinstance(overrides, str):
        overrides = (overrides,)
    if not isinstance(data, Mapping):
        raise ConfigError(None, data, "a scenario is a table of sections")
    merged = _default_dict()
    schema = _schema()
    _merge(merged, _copy_tables(data), schema)
    for item in overrides:
        _merge(merged, parse_override(item), schema)
    return Scenario(_validate(merged))


def load_scenario(path=None, overrides=(), disperse=None) -> Scenario:
    """Load a scenario file, merge it over the default, apply overrides, validate.

    Parameters
    ----------
    path : str or path-like, optional
        Scenario TOML file; None for the packaged default alone.
    overrides : iterable of str
        ``KEY=VALUE`` strings (dotted KEY, VALUE in TOML syntax), applied in order.
    disperse : str or path-like, optional
        TOML file holding a ``[dispersions]`` table (and nothing else), merged
        over the scenario's dispersions before the overrides.

    Returns
    -------
    Scenario
        The validated, frozen scenario.

    Raises
    ------
    ConfigError
        For an unreadable or missing file, a TOML syntax error (with its line),
        an unknown key or any value that breaks its rule.
    """
    data = {} if path is None else _read_toml(path)
    if disperse is not None:
        extra = _read_toml(disperse)
        others = [k for k in extra if k != "dispersions"]
        if others:
            raise ConfigError(None, str(disperse), f"{disperse}: a dispersion file holds only a "
                              f"[dispersions] table, not {', '.join(map(repr, others))}")
        from allsky.config import dispersions

        table = dispersions.merge({}, data.get("dispersions", {}))
        data = {**data, "dispersions": dispersions.merge(table, extra.get("dispersions", {}))}
    return scenario_from_dict(data, overrides)
