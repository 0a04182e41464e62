"""A scenario's ``[[faults]]``: hardware failures injected into a mission.

Each ``[[faults]]`` table names one failure (``kind``), where it acts and
when it starts::

    [[faults]]
    kind = "tracker_dropout"     # star tracker 105 sees nothing
    start_mode = "4"             # at the start of Mode 4 (or start_s = 512.0)
    duration_s = 60.0            # absent: permanent

The kinds (:data:`KINDS`) and the fields each needs:

* ``jet_stuck_open``, ``jet_failed_off``: ``axis`` and ``sign`` (+1 or -1,
  the couple of that axis that fires the positive or negative way); a stuck
  couple may give ``jets``: 2 (the default: both jets of the couple, a
  shared valve driver stuck on, the couple's whole torque) or 1 (one jet,
  half the torque, and the opposite couple can still brake against it);
* ``gyro_stuck`` (output frozen at its value at the onset), ``gyro_dead``
  (output zero): ``axis``; ``gyro_bias_step``: ``axis``, ``size_deg_h``;
  ``gyro_scale_factor_step``: ``axis``, ``size_ppm``;
* ``sun_sensor_blind`` (sun sensor 104 sees no Sun), ``tracker_dropout``
  (star tracker 105 sees no star): no field;
* ``tracker_stray_light``: ``offset_deg``, where a false target sits in the
  tracker's field (its yaw output, body-fixed: a glint off dust or the
  vehicle), within the narrow half-field; optional ``magnitude``, its
  brightness [mag]: without it the tracker follows the glint whatever it
  holds; with it the glint is one more light in the slit (locked only when
  the tracker holds nothing and the glint is inside the magnitude window,
  and added to the light the bright gate judges);
* ``wrong_star``: ``star``, a catalog star the magnitude window also passes;
* ``counter_upset``: ``register`` (the numeral as a string: "13"-"18" up/down
  and drift counters, "25"-"27" storage registers) and ``bit`` (0 = least
  significant, below the word length): the bit flips once, at the onset;
* ``propellant_leak``: ``rate_kg_s`` [kg/s], the flow at the initial tank
  pressure (on a blow-down feed it follows the tank pressure, as the jets'
  flow does); and either ``torque_n_m``, the body torque [roll, pitch, yaw]
  the escaping gas gives at that pressure, or the vent it escapes from:
  ``vent_position_m`` [m] (body axes, from the centre of mass) and
  ``vent_direction`` (body axes, the way the gas leaves; normalised), the
  gas then thrusting at the jets' exhaust speed ``jets.isp_s g0``. A leak
  with neither is refused (naming ``torque_n_m``).

``start_s`` [s] (mission time) or ``start_mode`` (a mode name: the fault
starts when that mode starts) gives the onset; neither means ``start_s =
0``. ``duration_s`` [s] ends it; absent, the fault is permanent. ``axis``
is "roll", "pitch" or "yaw". A scenario holds at most :data:`MAX_FAULTS`.
Anything else is a :class:`~allsky.config.rules.ConfigError` naming the key
(``faults[2].axis``).

In ``[dispersions]``, ``faults.N = { dist = "fault", probability = P, low =
T0, high = T1 }`` (N counts the ``[[faults]]`` tables from 1) keeps fault N
in a run with probability P and, with ``low`` and ``high`` [s], draws its
onset uniformly in that span (:func:`validate_dispersion`,
:func:`allsky.config.dispersions.draw`).
"""

from collections.abc import Mapping
from pathlib import Path

from allsky import xmath
from allsky.config.checkers import star_name
from allsky.config.rules import (
    MODE_KEYS,
    NON_NEGATIVE,
    POSITIVE,
    ConfigError,
    as_float,
    check_conds,
    in_closed,
    number,
    type_name,
    vector,
)
from allsky.config.schema import DEFAULT_SCENARIO_PATH
from allsky.vocabulary import AXES, FAULT_KINDS

#: Most faults one scenario may hold (the frame loop's fixed-size fault arrays).
MAX_FAULTS = 8
#: Fault kind -> the fields it needs beyond the timing (in this order): the vocabulary's.
KINDS = {k.name: k.fields for k in FAULT_KINDS}
#: Fault kind -> the fields it may have beyond those (absent: the behaviour without them).
OPTIONAL = {k.name: k.optional for k in FAULT_KINDS}
TIMING = ("start_s", "start_mode", "duration_s")
#: Modes a fault may start with: the patent's, the hold on target, the moves to a next
#: target, the dither mode (:func:`check_plan`: only those the mission flies).
START_MODES = (*MODE_KEYS, "hold", "reacquire", "recycle", "direct", "dither")
#: Counter or register numeral -> the scenario key giving its word length [bit].
REGISTER_BITS_KEY = {
    **dict.fromkeys(("13", "15", "17"), "electronics.drift_counter_bits"),
    **dict.fromkeys(("14", "16", "18"), "electronics.counter_bits"),
    **dict.fromkeys(("25", "26", "27"), "electronics.register_bits"),
}
#: [deg/h] largest bias step, [ppm] largest scale-factor step, [kg/s] largest leak.
BIAS_STEP_MAX_DEG_H = 3600.0
SCALE_STEP_MAX_PPM = 1e6
LEAK_MAX_KG_S = 1.0
#: [N m] largest leak torque per axis (a leak of 1 kg/s at Isp 65 s thrusts 640 N).
LEAK_TORQUE_MAX_N_M = 100.0
#: [m] Largest distance of a leak's vent from the centre of mass, per body axis.
VENT_MAX_M = 10.0
#: The fields that give a leak's vent instead of its torque.
VENT_KEYS = ("vent_position_m", "vent_direction")
#: [mag] brightest and faintest glint a stray-light fault may give (the Sun is -26.7).
GLINT_MAG_RANGE = (-30.0, 30.0)
DISPERSION_DIST = "fault"


def _quoted(names) -> str:
    return ", ".join(f'"{n}"' for n in names)


def _string(key, v, choices):
    if not isinstance(v, str) or v not in choices:
        raise ConfigError(key, v, f"must be one of {_quoted(choices)}")
    return v


def _sign(key, v):
    if isinstance(v, bool) or v not in (1, -1, 1.0, -1.0):
        raise ConfigError(key, v, "must be +1 or -1 (the jet of the couple)")
    return int(v)


def _bit(key, v, bits, word):
    if isinstance(v, bool) or not isinstance(v, int):
        raise ConfigError(key, v, f"must be an integer, not {type_name(v)}")
    check_conds((in_closed(0, bits - 1, f"{word} has {bits} bits"),), key, v, v)
    return v


def validate_fault(where: str, entry, values: Mapping) -> dict:
    """One ``[[faults]]`` table, checked; returns its fields normalised.

    ``entry`` is the table as read from TOML; ``where`` is its name in errors
    (``faults[1]``); ``values`` the scenario's validated values by dotted key
    (for word lengths, the tracker's field and the star catalog).
    """
    if not isinstance(entry, Mapping):
        raise ConfigError(where, entry, f"must be a table, not {type_name(entry)}")
    kind = entry.get("kind")
    if kind is None:
        raise ConfigError(f"{where}.kind", rule=f"missing: one of {_quoted(KINDS)}")
    _string(f"{where}.kind", kind, tuple(KINDS))
    need = KINDS[kind]
    may = OPTIONAL[kind]
    for k in entry:
        if k not in ("kind", *need, *may, *TIMING):
            raise ConfigError(f"{where}.{k}", entry[k], f'unknown field for kind = "{kind}"; '
                              f"valid: {', '.join((*need, *may, *TIMING))}")
    for k in need:
        if k not in entry:
            raise ConfigError(f"{where}.{k}", rule=f'missing: kind = "{kind}" needs '
                              f"{', '.join(need)}")
    out = {"kind": kind}
    for k in (*need, *(m for m in may if m in entry)):
        key, v = f"{where}.{k}", entry[k]
        if k == "axis":
            out[k] = _string(key, v, AXES)
        elif k == "sign":
            out[k] = _sign(key, v)
        elif k == "size_deg_h":
            out[k] = number(in_closed(-BIAS_STEP_MAX_DEG_H, BIAS_STEP_MAX_DEG_H))(key, v)
        elif k == "size_ppm":
            out[k] = number(in_closed(-SCALE_STEP_MAX_PPM, SCALE_STEP_MAX_PPM))(key, v)
        elif k == "offset_deg":
            half = values["star_tracker.fov_narrow_half_deg"]
            out[k] = number(in_closed(-half, half, "inside the tracker's narrow half-field, "
                                      "star_tracker.fov_narrow_half_deg"))(key, v)
        elif k == "star":
            out[k] = star_name(key, v)
            _slit_meets(key, out[k], values)
        elif k == "register":
            out[k] = _string(key, v, tuple(REGISTER_BITS_KEY))
        elif k == "bit":
            reg = out["register"]
            out[k] = _bit(key, v, values[REGISTER_BITS_KEY[reg]],
                          f"{'register' if reg >= '25' else 'counter'} {reg}")
        elif k == "jets":
            if isinstance(v, bool) or v not in (1, 2, 1.0, 2.0):
                raise ConfigError(key, v, "must be 1 (one jet of the couple) or 2 (both)")
            out[k] = int(v)
        elif k == "torque_n_m":
            out[k] = vector(3, in_closed(-LEAK_TORQUE_MAX_N_M, LEAK_TORQUE_MAX_N_M))(key, v)
        elif k == "magnitude":
            out[k] = number(in_closed(*GLINT_MAG_RANGE))(key, v)
        elif k == "rate_kg_s":
            out[k] = number(POSITIVE, in_closed(0, LEAK_MAX_KG_S))(key, v)
        elif k == "vent_position_m":
            out[k] = vector(3, in_closed(-VENT_MAX_M, VENT_MAX_M))(key, v)
        elif k == "vent_direction":
            d = vector(3)(key, v)
            norm = xmath.hypot(xmath.hypot(d[0], d[1]), d[2])
            if not norm > 0.0:
                raise ConfigError(key, v, "must not be zero: the way the gas leaves the vent")
            out[k] = tuple(float(x) / norm for x in d)
        else:  # every field of the vocabulary has a rule above (tests/config/test_config.py)
            raise AssertionError(f"fault field {k!r}: the vocabulary names it, no rule checks it")
    if kind == "propellant_leak":
        _leak_thrusts(where, out)
    if "start_s" in entry and "start_mode" in entry:
        raise ConfigError(where, rule="give start_s or start_mode, not both")
    if "start_mode" in entry:
        out["start_mode"] = _string(f"{where}.start_mode", entry["start_mode"], START_MODES)
        _scenario_flies(f"{where}.start_mode", out["start_mode"], values)
    else:
        out["start_s"] = number(NON_NEGATIVE)(f"{where}.start_s", entry.get("start_s", 0.0))
        _starts_in_time(f"{where}.start_s", out["start_s"], values)
    if "duration_s" in entry:
        out["duration_s"] = number(POSITIVE)(f"{where}.duration_s", entry["duration_s"])
    return out


def _leak_thrusts(where, out):
    """A leak's gas turns the vehicle: its torque is given, or its vent is (not both)."""
    vent = [k for k in VENT_KEYS if k in out]
    if "torque_n_m" in out and vent:
        raise ConfigError(f"{where}.{vent[0]}", rule="give the leak's torque_n_m or its vent "
                          f"({' and '.join(VENT_KEYS)}), not both")
    if "torque_n_m" not in out and len(vent) < 2:
        if vent:
            missing = next(k for k in VENT_KEYS if k not in out)
            raise ConfigError(f"{where}.{missing}", rule=f"missing: a leak's vent needs both "
                              f"{' and '.join(VENT_KEYS)}")
        raise ConfigError(f"{where}.torque_n_m", rule="missing: the escaping gas thrusts (at "
                          "the jets' exhaust speed, 5 g/s about 3.2 N): give the leak's body "
                          "torque, or its vent (" + " and ".join(VENT_KEYS) + ")")


def _starts_in_time(key, start_s, values):
    """Refuse an onset after the longest mission ends: the fault would never start."""
    from allsky.config.cross_rules import longest_mission_s  # it imports the sky

    longest = longest_mission_s(values)
    if start_s >= longest:
        raise ConfigError(key, start_s, f"must be < {longest:g} s: the longest mission (the "
                          "timeouts of the modes it flies, sequencer.timeout_s) ends by then, "
                          "so the fault would never start")


def _slit_meets(key, name, values):
    """Refuse a wrong star the tracker's slit never crosses on the mission date.

    The roll axis holds the Sun and star tracker 105 looks along +z, at 90
    deg from it; rolling, its slit sweeps the stars whose angle from the
    Sun is within 90 deg +- ``star_tracker.fov_long_half_deg``. Any other
    star is never in the field, and the fault would do nothing.
    """
    import math

    from allsky.vehicle import sky

    date = values["mission.date_utc"]
    cos = xmath.dot3(sky.sun_direction_inertial(date), sky.star_direction_inertial(name, date))
    angle = math.degrees(xmath.acos(max(-1.0, min(1.0, cos))))
    half = values["star_tracker.fov_long_half_deg"]
    if abs(angle - 90.0) > half:
        raise ConfigError(key, name, f"{angle:.1f} deg from the Sun on mission.date_utc: the "
                          f"tracker's slit only crosses stars {90 - half:g}-{90 + half:g} deg "
                          "from the Sun (90 deg +- star_tracker.fov_long_half_deg), so the "
                          "wrong star would never be seen")


def _scenario_flies(key, mode, values):
    """Refuse a start mode the scenario never flies: it would never start the fault."""
    if mode == "hold" and not values["target.hold_s"] > 0:
        raise ConfigError(key, mode, "the mission flies no hold on target: set target.hold_s "
                          "> 0, or start the fault in another mode")
    if mode in ("reacquire", "recycle", "direct"):
        seq = values.get("target.sequence") or ()
        how = values["sequencer.between_targets"]
        if len(seq) < 2 or how != mode:
            raise ConfigError(key, mode, f'flown only between the targets of a target.sequence '
                              f'of 2 or more with sequencer.between_targets = "{mode}" (this '
                              f'scenario: {len(seq) or 1} target(s), "{how}")')


def check_plan(faults, plan, plan_name=None) -> None:
    """Refuse a fault whose ``start_mode`` the mission's ``plan`` never flies.

    ``plan`` is the sequence of mode names the mission flies (the dither
    plan has no Modes 4 and 5, the patent's no dither); ``plan_name`` names
    it in the message. ``faults`` are the validated ``[[faults]]`` tables
    (:func:`validate`). Raises :class:`ConfigError` naming
    ``faults[i].start_mode``.
    """
    for i, f in enumerate(faults):
        mode = f.get("start_mode")
        if mode is not None and mode not in plan:
            flown = f"the {plan_name} plan" if plan_name else "the mission"
            raise ConfigError(f"faults[{i}].start_mode", mode,
                              f"{flown} never flies this mode (it flies "
                              f"{', '.join(plan)}): the fault would never start")


def validate(faults, values: Mapping) -> list:
    """The whole ``faults`` array, checked (:func:`validate_fault` for each table).

    ``faults`` is the array as read from TOML; ``values`` the scenario's
    validated values by dotted key.
    """
    if not isinstance(faults, list):
        raise ConfigError("faults", faults, "must be an array of tables ([[faults]])")
    if len(faults) > MAX_FAULTS:
        raise ConfigError("faults", f"{len(faults)} tables", f"at most {MAX_FAULTS} faults")
    return [validate_fault(f"faults[{i}]", f, values) for i, f in enumerate(faults)]


def is_fault_key(key: str) -> bool:
    """Whether ``key``, a ``[dispersions]`` key, names a fault (``faults.N``)."""
    return key.split(".", 1)[0] == "faults"


def validate_dispersion(key: str, entry, faults: list) -> dict:
    """A ``faults.N`` entry of ``[dispersions]``, checked against the faults.

    ``key`` is ``faults.N``, ``entry`` its table as read from TOML and
    ``faults`` the scenario's validated ``[[faults]]`` tables; N counts them
    from 1. Returns the entry normalised (``probability``, and the onset span
    ``low``, ``high`` [s] when given).
    """
    where = f"dispersions.{key}"
    n = key.split(".", 1)[1] if "." in key else ""
    if not n.isdigit() or not 1 <= int(n) <= len(faults):
        raise ConfigError(where, rule=f"faults.N names the N-th [[faults]] table, N in "
                          f"1..{len(faults)}" if faults else "the scenario has no [[faults]]")
    if not isinstance(entry, Mapping):
        raise ConfigError(where, entry, 'must be a table such as { dist = "fault", '
                          "probability = 0.1 }")
    if entry.get("dist") != DISPERSION_DIST:
        raise ConfigError(f"{where}.dist", entry.get("dist"), f'must be "{DISPERSION_DIST}"')
    for p in entry:
        if p not in ("dist", "probability", "low", "high"):
            raise ConfigError(f"{where}.{p}", rule='unknown parameter for dist = "fault"; '
                              "valid: probability, low, high")
    if "probability" not in entry:
        raise ConfigError(f"{where}.probability", rule="missing")
    out = {"dist": DISPERSION_DIST,
           "probability": number(in_closed(0, 1))(f"{where}.probability",
                                                  entry["probability"])}
    if ("low" in entry) != ("high" in entry):
        raise ConfigError(where, rule="give low and high (the onset span [s]) together")
    if "low" in entry:
        lo = number(NON_NEGATIVE)(f"{where}.low", entry["low"])
        hi, why = as_float(entry["high"])
        if why or hi < lo:
            raise ConfigError(f"{where}.high", entry["high"], why or f"must be >= low ({lo:g})")
        out.update(low=lo, high=hi)
    return out


def describe(fault: Mapping) -> str:
    """``fault`` in words, as abort reasons and tables name it ("roll gyro stuck").

    ``fault`` is one validated ``[[faults]]`` table (:func:`validate_fault`).
    """
    kind = fault["kind"]
    axis = fault.get("axis", "")
    sign = "+" if fault.get("sign", 1) > 0 else "-"
    return {
        "jet_stuck_open": (f"one {sign}{axis} jet stuck open" if fault.get("jets") == 1
                           else f"{sign}{axis} jet couple stuck open"),
        "jet_failed_off": f"{sign}{axis} jet failed off",
        "gyro_stuck": f"{axis} gyro stuck",
        "gyro_dead": f"{axis} gyro dead",
        "gyro_bias_step": f"{axis} gyro bias step {fault.get('size_deg_h', 0):+g} deg/h",
        "gyro_scale_factor_step": f"{axis} gyro scale step {fault.get('size_ppm', 0):+g} ppm",
        "sun_sensor_blind": "sun sensor blind",
        "tracker_dropout": "tracker dropout",
        "tracker_stray_light": (f"stray light {fault.get('offset_deg', 0):g} deg off boresight"
                                + (f", magnitude {fault['magnitude']:+g}"
                                   if "magnitude" in fault else "")),
        "wrong_star": f"wrong star {fault.get('star', '')}",
        "counter_upset": f"bit {fault.get('bit', 0)} of {fault.get('register', '')} upset",
        "propellant_leak": (f"propellant leak {fault.get('rate_kg_s', 0):g} kg/s"
                            + (" with torque [" + ", ".join(f"{t:g}" for t in fault["torque_n_m"])
                               + "] N m" if "torque_n_m" in fault else "")
                            + (" venting at [" + ", ".join(f"{t:g}" for t in
                                                            fault["vent_position_m"])
                               + "] m along [" + ", ".join(f"{t:.3g}" for t in
                                                            fault["vent_direction"]) + "]"
                               if "vent_position_m" in fault else "")),
    }[kind]


def packaged_scenarios() -> list:
    """The scenarios packaged with allsky: ``{"name", "path"}``, by name.

    ``name`` runs it (``allsky run mariner4-star-hopping``). The historical
    fault scenarios are among them (docs/faults.md).
    """
    return [{"name": f.stem, "path": str(f)}
            for f in sorted(DEFAULT_SCENARIO_PATH.parent.glob("*.toml"))]


def packaged_or_path(path):
    """A packaged scenario's file for its name; any other ``path`` as it is."""
    if path is None or Path(path).exists():
        return path
    found = [e["path"] for e in packaged_scenarios() if e["name"] == str(path)]
    return found[0] if found else path
