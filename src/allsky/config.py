"""Scenarios: TOML files, ``--set`` overrides, validation, a frozen result.

A scenario file is merged over the packaged default
(``scenarios/default.toml``), key by key, so a file states only what it
changes; a file's ``[target]`` table replaces the default target as a whole.
The default defines the schema: a section or key it does not have is an
error naming the nearest valid keys. Every value is checked once, here, for
type, finiteness and its physical rule; anything wrong raises
:class:`ConfigError` naming the key, the value and the rule.

Overrides are ``KEY=VALUE`` strings, KEY a dotted path
(``gyro.drift_deg_h``, ``sequencer.timeout_s.6-1``), VALUE in TOML value
syntax (``[800,-300,1500]``, ``2027-03-01T00:00:00Z``, ``"Vega"``); a bare word
that is not TOML is taken as a string (``target.star=Vega``). The target is
either ``target.star`` or ``target.ra_deg`` + ``target.dec_deg``: setting one
form replaces the other.
"""

import copy
import difflib
import math
import tomllib
from datetime import UTC, date, datetime, time
from importlib import resources
from pathlib import Path
from types import MappingProxyType

import numpy as np

DEFAULT_SCENARIO_PATH = Path(str(resources.files("allsky") / "scenarios" / "default.toml"))
MODE_KEYS = ("1", "2", "3", "4", "5", "6-1", "6-2")
EPHEMERIS_YEARS = (1900, 2100)
# Keys that may appear although the default does not set them.
OPTIONAL_KEYS = {"target": ("star", "ra_deg", "dec_deg")}


class ConfigError(Exception):
    """A scenario value that breaks a rule; ``str()`` is one line: key = value: rule."""

    def __init__(self, key, value, rule):
        self.key, self.value, self.rule = key, value, rule
        shown = repr(value) if not isinstance(value, float) else f"{value!r}"
        super().__init__(f"{key} = {shown}: {rule}" if key else rule)


# ---------------------------------------------------------------------------
# Reading and merging
# ---------------------------------------------------------------------------

def _read_toml(path) -> dict:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("", None, f"scenario file not found: {p}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError("", None, f"cannot read scenario file {p}: {e}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError("", None, f"{p}: not valid TOML: {e}") from None


def _default_dict() -> dict:
    return _read_toml(DEFAULT_SCENARIO_PATH)


def _valid_keys(default: dict) -> list:
    keys = []
    for sec, table in default.items():
        for k in table:
            keys.append(f"{sec}.{k}")
        for k in OPTIONAL_KEYS.get(sec, ()):
            keys.append(f"{sec}.{k}")
    return sorted(set(keys))


def _unknown(key: str, default: dict) -> ConfigError:
    near = difflib.get_close_matches(key, _valid_keys(default), n=3, cutoff=0.4)
    hint = f"; nearest valid keys: {', '.join(near)}" if near else ""
    return ConfigError(key, None, f"unknown key{hint}")


def _check_known(data: dict, default: dict) -> None:
    for sec, table in data.items():
        if sec not in default:
            raise _unknown(sec, default)
        if not isinstance(table, dict):
            raise ConfigError(sec, table, "must be a table of keys")
        for k in table:
            if k not in default[sec] and k not in OPTIONAL_KEYS.get(sec, ()):
                raise _unknown(f"{sec}.{k}", default)


def _merge(default: dict, user: dict) -> dict:
    out = copy.deepcopy(default)
    for sec, table in user.items():
        if sec == "target":
            forms = {"star"} & set(table), {"ra_deg", "dec_deg"} & set(table)
            if forms[0] and forms[1]:
                raise ConfigError("target", dict(table),
                                  "set either target.star or target.ra_deg + target.dec_deg,"
                                  " not both")
            out["target"] = {}
        for k, v in table.items():
            if sec == "sequencer" and k == "timeout_s" and isinstance(v, dict):
                v = {**out[sec][k], **v}
            out[sec][k] = v
    return out


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()


def _apply_override(data: dict, item: str, default: dict) -> None:
    if "=" not in item:
        raise ConfigError(item, None, "an override must be KEY=VALUE")
    key, text = item.split("=", 1)
    key = key.strip()
    parts = key.split(".")
    value = _parse_value(text)
    if len(parts) == 3 and parts[:2] == ["sequencer", "timeout_s"]:
        if parts[2] not in MODE_KEYS:
            raise ConfigError(key, value, f"mode must be one of {', '.join(MODE_KEYS)}")
        data["sequencer"]["timeout_s"] = dict(data["sequencer"]["timeout_s"])
        data["sequencer"]["timeout_s"][parts[2]] = value
        return
    if len(parts) != 2:
        raise ConfigError(key, value, "a key is SECTION.NAME")
    sec, name = parts
    if sec not in default or (name not in default[sec]
                              and name not in OPTIONAL_KEYS.get(sec, ())):
        raise _unknown(key, default)
    if sec == "target":
        if name == "star":
            data["target"].pop("ra_deg", None)
            data["target"].pop("dec_deg", None)
        else:
            data["target"].pop("star", None)
    data[sec][name] = value


# ---------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------

def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(key, v, *, integer=False):
    if integer:
        if not isinstance(v, int) or isinstance(v, bool):
            raise ConfigError(key, v, "must be an integer")
        return v
    if not _is_number(v):
        raise ConfigError(key, v, "must be a number")
    v = float(v)
    if not math.isfinite(v):
        raise ConfigError(key, v, "must be finite")
    return v


def _vector(key, v, n):
    if not isinstance(v, list) or len(v) != n:
        raise ConfigError(key, v, f"must be a list of {n} numbers")
    return tuple(_number(key, x) for x in v)


def _matrix(key, v):
    if not isinstance(v, list) or len(v) != 3 or not all(isinstance(r, list) for r in v):
        raise ConfigError(key, v, "must be a 3x3 list of lists of numbers")
    return tuple(_vector(key, r, 3) for r in v)


def _positive(key, v):
    if v <= 0:
        raise ConfigError(key, v, "must be > 0")
    return v


def _nonneg(key, v):
    if v < 0:
        raise ConfigError(key, v, "must be >= 0")
    return v


def _in_range(lo, hi):
    def check(key, v):
        if not lo <= v <= hi:
            raise ConfigError(key, v, f"must be between {lo} and {hi}")
        return v
    return check


def _all(rule):
    def check(key, vs):
        for x in vs:
            rule(key, x)
        return vs
    return check


def _date(key, v):
    if isinstance(v, str):
        try:
            v = datetime.fromisoformat(v.strip())
        except ValueError:
            raise ConfigError(key, v, "must be an ISO-8601 date-time, e.g. "
                              "2026-11-22T12:00:00Z") from None
    elif isinstance(v, date) and not isinstance(v, datetime):
        v = datetime.combine(v, time(0, 0))
    elif not isinstance(v, datetime):
        raise ConfigError(key, v, "must be a TOML date-time or an ISO-8601 string")
    v = v.replace(tzinfo=UTC) if v.tzinfo is None else v.astimezone(UTC)
    lo, hi = EPHEMERIS_YEARS
    if not lo <= v.year <= hi:
        raise ConfigError(key, v.isoformat(), f"outside the ephemeris range {lo}-{hi}")
    return v


def _inertia(key, v):
    j = np.array(_matrix(key, v))
    if not np.allclose(j, j.T, rtol=1e-9, atol=1e-12 * np.abs(j).max()):
        raise ConfigError(key, v, "must be symmetric")
    ev = np.linalg.eigvalsh(j)
    if ev.min() <= 0:
        raise ConfigError(key, v, "must be positive definite (principal moments > 0)")
    a, b, c = ev
    if a + b < c * (1 - 1e-12):
        raise ConfigError(key, v, "principal moments break the triangle inequality"
                          " (no rigid body has them)")
    return tuple(tuple(r) for r in j.tolist())


def _misalignment(key, v):
    m = _matrix(key, v)
    if any(m[i][i] != 0 for i in range(3)):
        raise ConfigError(key, v, "diagonal must be 0: scale-factor error is set by "
                          "gyro.scale_factor_error_ppm")
    if any(abs(x) > 3600 for r in m for x in r):
        raise ConfigError(key, v, "misalignments must be within +-3600 arcsec")
    return m


def _attitude(key, v):
    if v == "random":
        return "random"
    if isinstance(v, list) and len(v) == 4:
        q = np.array([_number(key, x) for x in v])
        n = np.linalg.norm(q)
        if n == 0:
            raise ConfigError(key, v, "quaternion [w, x, y, z] must not be zero")
        return tuple((q / n).tolist())
    raise ConfigError(key, v, 'must be "random" or a quaternion [w, x, y, z] (inertial->body)')


def _one_of(*choices):
    def check(key, v):
        if v not in choices:
            raise ConfigError(key, v, f"must be one of {', '.join(map(repr, choices))}")
        return v
    return check


def _boolean(key, v):
    if not isinstance(v, bool):
        raise ConfigError(key, v, "must be true or false")
    return v


def _string(key, v):
    if not isinstance(v, str):
        raise ConfigError(key, v, "must be a string")
    return v


def _timeouts(key, v):
    if not isinstance(v, dict) or set(v) != set(MODE_KEYS):
        raise ConfigError(key, v, f"must be a table with exactly the modes {', '.join(MODE_KEYS)}")
    return MappingProxyType({m: _positive(f"{key}.{m}", _number(f"{key}.{m}", v[m]))
                             for m in MODE_KEYS})


def _window(key, v):
    lo, hi = _vector(key, v, 2)
    if not lo < hi:
        raise ConfigError(key, v, "must be [brightest, faintest] with brightest < faintest")
    return (lo, hi)


def num(*rules, integer=False):
    def check(key, v):
        v = _number(key, v, integer=integer)
        for r in rules:
            r(key, v)
        return v
    return check


def vec(n, *rules):
    def check(key, v):
        v = _vector(key, v, n)
        for r in rules:
            r(key, v)
        return v
    return check


POS, NONNEG = num(_positive), num(_nonneg)


def BITS(lo, hi):
    return num(_in_range(lo, hi), integer=True)


#: One rule per key: the whole schema's checks in one table.
RULES = {
    "mission.date_utc": _date,
    "mission.seed": num(_in_range(0, 2**32 - 1), integer=True),
    "mission.frame_s": POS,
    "mission.telemetry_every_frames": num(_in_range(1, 10**9), integer=True),
    "ejection.attitude": _attitude,
    "ejection.tipoff_rate_max_deg_s": num(_in_range(0, 30)),
    "vehicle.inertia_kg_m2": _inertia,
    "gyro.drift_deg_h": vec(3, _all(_in_range(-3600, 3600))),
    "gyro.scale_factor_error_ppm": vec(3, _all(_in_range(-1e5, 1e5))),
    "gyro.misalignment_arcsec": _misalignment,
    "gyro.arw_deg_rt_h": NONNEG,
    "gyro.rrw_deg_h_rt_h": NONNEG,
    "gyro.range_deg_s": POS,
    "sun_sensor.linear_range_arcsec": POS,
    "sun_sensor.presence_half_angle_deg": num(_positive, _in_range(0, 90)),
    "sun_sensor.noise_arcsec": NONNEG,
    "sun_sensor.coarse_noise_deg": num(_in_range(0, 30)),
    "star_tracker.fov_long_half_deg": num(_positive, _in_range(0, 89.9)),
    "star_tracker.fov_narrow_half_deg": num(_positive, _in_range(0, 89.9)),
    "star_tracker.magnitude_window": _window,
    "star_tracker.noise_arcsec": NONNEG,
    "jets.thrust_n": vec(3, _all(_positive)),
    "jets.moment_arm_m": vec(3, _all(_positive)),
    "jets.min_on_time_s": POS,
    "jets.isp_s": POS,
    "jets.propellant_kg": POS,
    "pwpf.filter_gain": POS,
    "pwpf.time_constant_s": POS,
    "pwpf.on_threshold_v": POS,
    "pwpf.off_threshold_v": NONNEG,
    "pwpf.full_on_v": POS,
    "control.position_gain_v_per_arcsec": vec(3, _all(_positive)),
    "control.rate_gain_v_per_arcsec_s": vec(3, _all(_positive)),
    "control.position_limit_arcsec": vec(3, _all(_positive)),
    "control.output_limit_v": POS,
    "control.integral_time_s": POS,
    "control.integral_limit_arcsec": POS,
    "electronics.vfc_pulse_weight_arcsec": POS,
    "electronics.vfc_max_rate_pps": POS,
    "electronics.counter_bits": BITS(8, 62),
    "electronics.drift_counter_bits": BITS(4, 62),
    "electronics.counter_overflow": _one_of("wrap", "saturate"),
    "electronics.drift_dac_bits": BITS(4, 32),
    "electronics.register_bits": BITS(4, 32),
    "electronics.register_lsb_arcsec": POS,
    "electronics.rate_command_deg_s": num(_positive, _in_range(0, 10)),
    "electronics.computer_step_frames": num(_in_range(1, 10**6), integer=True),
    "sequencer.settle_threshold_arcsec": POS,
    "sequencer.settle_time_s": POS,
    "sequencer.handover_arcsec": POS,
    "sequencer.drift_count_s": POS,
    "sequencer.tracker_blanking_s": NONNEG,
    "sequencer.sensor_loss_s": POS,
    "sequencer.mode1_slew_rate_deg_s": num(_positive, _in_range(0, 10)),
    "sequencer.mode1_slew_gain_per_s": POS,
    "sequencer.timeout_s": _timeouts,
    "target.star": _string,
    "target.ra_deg": num(_in_range(0, 360)),
    "target.dec_deg": num(_in_range(-90, 90)),
    "calibration.apply": _boolean,
}


def _cross_rules(v: dict) -> None:
    """Rules that tie keys together."""
    frame, t_min = v["mission.frame_s"], v["jets.min_on_time_s"]
    if frame > t_min * (1 + 1e-12):
        raise ConfigError("mission.frame_s", frame,
                          f"frame too coarse for the jet minimum on-time "
                          f"(jets.min_on_time_s = {t_min}): must be <= it")
    if v["target.ra_deg"] == 360.0:
        raise ConfigError("target.ra_deg", 360.0, "must be in [0, 360)")
    if not v["pwpf.on_threshold_v"] > v["pwpf.off_threshold_v"]:
        raise ConfigError("pwpf.off_threshold_v", v["pwpf.off_threshold_v"],
                          f"must be below pwpf.on_threshold_v ({v['pwpf.on_threshold_v']})")
    lin = v["sun_sensor.linear_range_arcsec"] / 3600.0
    if v["sun_sensor.presence_half_angle_deg"] < lin:
        raise ConfigError("sun_sensor.presence_half_angle_deg",
                          v["sun_sensor.presence_half_angle_deg"],
                          f"must be at least the linear range ({lin:g} deg)")
    if v["target.star"] is not None:
        from allsky.sky import _canonical

        try:
            v["target.star"] = _canonical(v["target.star"])
        except KeyError as e:
            raise ConfigError("target.star", v["target.star"], e.args[0]) from None
    elif v["target.ra_deg"] is None or v["target.dec_deg"] is None:
        raise ConfigError("target", None, "give target.star, or both target.ra_deg and "
                          "target.dec_deg")


def _validate(data: dict) -> dict:
    flat = {}
    for key, rule in RULES.items():
        sec, name = key.split(".")
        if name in data.get(sec, {}):
            flat[key] = rule(key, data[sec][name])
        elif sec == "target":
            flat[key] = None
        else:
            raise ConfigError(key, None, "missing")
    _cross_rules(flat)
    return flat


# ---------------------------------------------------------------------------
# The frozen result
# ---------------------------------------------------------------------------

class _Section:
    """Read-only attribute view of one scenario section."""

    __slots__ = ("_name", "_values")

    def __init__(self, name, values):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_values", dict(values))

    def __getattr__(self, key):
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"scenario section [{self._name}] has no key {key!r}") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __eq__(self, other):
        return isinstance(other, _Section) and self._values == other._values

    def __repr__(self):
        return f"<[{self._name}] {self._values}>"


class Scenario:
    """A validated, frozen scenario: ``cfg.section.key``."""

    __slots__ = ("_flat", "_sections")

    def __init__(self, flat: dict):
        secs = {}
        for key, v in flat.items():
            sec, name = key.split(".")
            secs.setdefault(sec, {})[name] = v
        object.__setattr__(self, "_flat", dict(flat))
        object.__setattr__(self, "_sections", {k: _Section(k, v) for k, v in secs.items()})

    def __getattr__(self, sec):
        try:
            return self._sections[sec]
        except KeyError:
            raise AttributeError(f"scenario has no section [{sec}]") from None

    def __setattr__(self, key, value):
        raise AttributeError("a Scenario is frozen")

    def __eq__(self, other):
        return isinstance(other, Scenario) and self.as_dict() == other.as_dict()

    def as_dict(self) -> dict:
        """Plain nested dict (date as ISO string), loadable by :func:`scenario_from_dict`."""
        out = {}
        for key, v in self._flat.items():
            sec, name = key.split(".")
            if v is None and sec == "target":
                continue
            if isinstance(v, datetime):
                v = v.strftime("%Y-%m-%dT%H:%M:%S") + (
                    f".{v.microsecond:06d}" if v.microsecond else "") + "Z"
            elif isinstance(v, MappingProxyType):
                v = dict(v)
            elif isinstance(v, tuple):
                v = [list(r) if isinstance(r, tuple) else r for r in v]
            out.setdefault(sec, {})[name] = v
        return out

    def to_toml(self) -> str:
        """The resolved scenario as TOML text."""
        lines = []
        for sec, table in self.as_dict().items():
            lines.append(f"[{sec}]")
            for k, v in table.items():
                lines.append(f"{k} = {_toml_value(v, k == 'date_utc')}")
            lines.append("")
        return "\n".join(lines)


def _toml_value(v, is_date=False) -> str:
    if is_date:
        return v
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f'"{k}" = {_toml_value(x)}' for k, x in v.items()) + " }"
    raise TypeError(type(v))


# ---------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------

def scenario_from_dict(data: dict, overrides=()) -> Scenario:
    """Validate a nested dict (merged over the default) into a :class:`Scenario`."""
    default = _default_dict()
    if not isinstance(data, dict):
        raise ConfigError("", data, "a scenario is a table of sections")
    _check_known(data, default)
    merged = _merge(default, data)
    for item in overrides:
        _apply_override(merged, item, default)
    return Scenario(_validate(merged))


def load_scenario(path=None, overrides=()) -> Scenario:
    """Load, merge over the default, apply ``KEY=VALUE`` overrides, validate."""
    data = {} if path is None else _read_toml(path)
    return scenario_from_dict(data, overrides)
