"""Schema: which keys a scenario has (the packaged default) and what each accepts.

The packaged default (``scenarios/default.toml``, :data:`DEFAULT_SCENARIO_PATH`)
names every key, with the unit in the key's name, and nothing else; only the
three forms of ``[target]`` (:data:`TARGET_STAR_FORM`, :data:`TARGET_RADEC_FORM`,
:data:`TARGET_SEQUENCE_FORM`) may hold keys the default leaves unset.
:data:`RULES` gives each key its checker (:mod:`allsky.config.rules`);
:data:`CROSS_RULES` tie keys together and run after every key passed its own
rule.
"""

import difflib
import functools
import math
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from allsky import xmath
from allsky.config.checkers import (
    attitude,
    boolean,
    inertia_tensor,
    magnitude_window,
    misalignment_matrix,
    mode_timeouts,
    star_name,
    symmetric_eigenvalues,
    utc_datetime,
)
from allsky.config.rules import (
    NON_NEGATIVE,
    POSITIVE,
    SEED_MAX,
    ConfigError,
    at_least,
    in_closed,
    in_closed_open,
    in_open,
    in_open_closed,
    integer,
    magnitude_at_most,
    number,
    one_of,
    real_array,
    type_name,
    vector,
)
from allsky.config.toml_io import copy_tables, parse_toml
from allsky.units import DEG2ARCSEC

#: The packaged default scenario; it also defines the schema.
DEFAULT_SCENARIO_PATH = Path(str(resources.files("allsky") / "scenarios" / "default.toml"))
#: The forms of ``[target]``; keys the default need not contain.
TARGET_STAR_FORM = ("star",)
TARGET_RADEC_FORM = ("ra_deg", "dec_deg")
#: A list of targets flown one after the other, in place of the two single forms.
TARGET_SEQUENCE_FORM = ("sequence",)
#: Most targets a sequence may list (each takes minutes; a mission lasts at most a day).
TARGET_SEQUENCE_MAX = 100

#: [s] Shortest frame: 1/100 of the default 10 ms valve pulse; nothing modelled is faster.
FRAME_MIN_S = 1e-4
#: [s] Longest mission: a day. The loop moves the Sun on a line from its place and rate at
#: the start; against PyEphem the line is off by 1.4" after 24 h, 6.8" after 48 h, 170" after
#: a week (worst of five dates in a year): a day keeps it near the sun sensor's 0.5" noise.
MISSION_MAX_S = 86400.0
#: [s] The Sun's rate is taken from the ephemeris over the first hour (allsky.sim.mission).
SUN_RATE_SPAN_S = 3600.0
#: Most frames a mission may need: ~40 s at the 2.5e6 frames/s measured on one core.
MISSION_MAX_FRAMES = 10**8
#: Most telemetry rows a mission may record: 1e6 rows of 40 float64 are 320 MB.
TELEMETRY_MAX_ROWS = 10**6
#: Most samples of the dither mode's lead-in and record: 128 times the default record.
DITHER_MAX_SAMPLES = 2**20
#: [s] Settling allowed after the dither record, as in the mode table (sequencer.modes).
DITHER_SETTLE_ALLOWANCE_S = 300.0
#: [s] allowed to the hold on target beyond `target.hold_s` (its elapsed leg ends on a frame).
HOLD_TIMEOUT_ALLOWANCE_S = 60.0
#: [kg] Most propellant a tank may hold: 250 times the default 4 kg, past any attitude-control
#: tank of an instrument vehicle. The tank is counted down by each frame's use (a few ug at
#: the default thrust); float64 keeps that use to 1e-8 of itself in a 1000 kg tank, while
#: past ~3e10 kg each frame's use rounds away entirely and the mission reports 0 kg used.
PROPELLANT_MAX_KG = 1000.0


# -- The keys (the default's tables) -----------------------------------------

@functools.cache
def _default_parsed() -> dict:
    text = DEFAULT_SCENARIO_PATH.read_text(encoding="utf-8")
    return parse_toml(text, str(DEFAULT_SCENARIO_PATH))


def default_tables() -> dict:
    """A fresh copy of the parsed default (parsed once: a campaign builds one per run)."""
    return copy_tables(_default_parsed())


@functools.cache
def key_tree() -> dict:
    """Nested dict of every valid key: the default's plus the optional target keys.

    Read only (the result is cached and shared).
    """
    tree = default_tables()
    tree["target"] = {**tree["target"], **dict.fromkeys(
        TARGET_STAR_FORM + TARGET_RADEC_FORM + TARGET_SEQUENCE_FORM)}
    return tree


def _all_keys(tree=None, prefix="") -> list:
    tree = key_tree() if tree is None else tree
    out = []
    for k, v in tree.items():
        out.append(prefix + k)
        if isinstance(v, dict):
            out += _all_keys(v, f"{prefix}{k}.")
    return out


def unknown_key(path: tuple, here: dict) -> ConfigError:
    """Error for unknown key ``path`` in table ``here``, naming the nearest valid keys."""
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
        hint = "valid keys here: " + ", ".join(sorted(here))
    else:
        hint = "valid sections: " + ", ".join(here)
    return ConfigError(key, rule=f"unknown key; {hint}")


# -- What each key accepts ---------------------------------------------------

#: [deg/h] Largest integrator drift accepted (1 deg/h = 1 arcsec/s at the converter input).
INTEGRATOR_DRIFT_MAX_DEG_H = 100.0
#: Most reaction wheels an array may have (the envelope has a facet per pair of them).
WHEELS_MAX = 12
#: A spin axis is normalised when its length is within this of 1, refused otherwise.
WHEEL_AXIS_LENGTH_TOL = 0.01
#: Smallest singular value of the spin axes, relative to the largest, to span 3-D.
WHEEL_SPAN_TOL = 1e-6


def wheel_axes(key, v):
    """Spin axes of 3 to WHEELS_MAX wheels: unit vectors (normalised) that span 3-D.

    ``v`` is the value of ``key`` as read from TOML: one row ``[x, y, z]``
    (body axes) per wheel.
    """
    rows = v if isinstance(v, list) else None
    if rows is None or not 3 <= len(rows) <= WHEELS_MAX:
        got = f"{len(v)} rows" if isinstance(v, list) else type_name(v)
        raise ConfigError(key, v, f"must be an array of 3 to {WHEELS_MAX} spin axes "
                          f"[x, y, z] (one per wheel), not {got}")
    g = real_array(key, v, (len(rows), 3))
    for i, r in enumerate(g):
        n = math.sqrt(math.fsum(x * x for x in r))
        if abs(n - 1.0) > WHEEL_AXIS_LENGTH_TOL:
            raise ConfigError(key, v, f"row {i} has length {n:.6g}: spin axes are unit "
                              f"vectors (lengths within {WHEEL_AXIS_LENGTH_TOL:g} of 1 are "
                              "normalised)")
    # The singular values of g are the square roots of the eigenvalues of g'g.
    gram = [[math.fsum(r[a] * r[b] for r in g) for b in range(3)] for a in range(3)]
    smallest, _, largest = symmetric_eigenvalues(gram)
    if smallest <= WHEEL_SPAN_TOL ** 2 * largest:
        raise ConfigError(key, v, "the spin axes lie in one plane (or on one line): they "
                          "must span 3-D to give torque about every axis")
    # Rows already of unit length are kept bit for bit (a saved scenario loads unchanged).
    # A row whose squared length rounds to exactly 1 is within 1.1e-16 of unit length,
    # and any three-term dot product of it (errors below 2.8e-16 for positive terms)
    # passes the 4e-16 test below: such rows need no NumPy to tell.
    if all(math.fsum(x * x for x in r) == 1.0 for r in g):
        return g
    import numpy as np  # only to normalise: validating a scenario otherwise needs no NumPy

    a = np.array(g)
    return tuple(tuple(float(x) for x in (r if abs(xmath.dot(r, r) - 1.0) <= 4e-16
                                          else r / math.sqrt(xmath.dot(r, r))))
                 for r in a)


wheel_axes.allowed = (f"an array of 3 to {WHEELS_MAX} spin axes [x, y, z] spanning 3-D, "
                      f"each of length 1 (to {WHEEL_AXIS_LENGTH_TOL:g}; normalised)")


def per_wheel(*conds):
    """Checker of one number for all wheels or one per wheel, each obeying ``*conds``."""
    one = number(*conds)

    def check(key, v):
        if isinstance(v, list):
            return vector(len(v), *conds)(key, v) if v else one(key, v)
        return one(key, v)
    check.allowed = one.allowed + "; or an array of one such number per wheel"
    return check


_MOST_FRAMES = "the most frames a mission may take"
_RA_DEG = number(in_closed_open(0, 360))
_DEC_DEG = number(in_closed(-90, 90))


def target_sequence(key, v):
    """Targets in flight order: each a catalog star name or ``{ ra_deg, dec_deg }``.

    ``v`` is the value of ``key`` as read from TOML, an array.

    Returned as a tuple of star names (catalog spelling) and
    ``{"ra_deg": ..., "dec_deg": ...}`` tables; an entry that is neither is
    refused naming it (``target.sequence[2]``, counted from 0).
    """
    if not isinstance(v, list) or not v:
        raise ConfigError(key, v, "must be a non-empty array of targets (star names or "
                          "{ ra_deg = ..., dec_deg = ... } tables)")
    if len(v) > TARGET_SEQUENCE_MAX:
        raise ConfigError(key, f"{len(v)} targets", f"at most {TARGET_SEQUENCE_MAX} targets")
    out = []
    for i, entry in enumerate(v):
        where = f"{key}[{i}]"
        if isinstance(entry, str):
            out.append(star_name(where, entry))
        elif isinstance(entry, dict):
            if set(entry) != set(TARGET_RADEC_FORM):
                raise ConfigError(where, entry, "must be a table of exactly ra_deg and dec_deg")
            out.append({"ra_deg": _RA_DEG(f"{where}.ra_deg", entry["ra_deg"]),
                        "dec_deg": _DEC_DEG(f"{where}.dec_deg", entry["dec_deg"])})
        else:
            raise ConfigError(where, entry, "must be a star name or a table "
                              "{ ra_deg = ..., dec_deg = ... }")
    return tuple(out)


target_sequence.allowed = (f"an array of 1 to {TARGET_SEQUENCE_MAX} targets, each a star name "
                           "of the PyEphem catalog or { ra_deg = [0, 360), dec_deg = [-90, 90] }")
_A_DAY = "a mission lasts at most a day"


def tle_line(key, v):
    """A line of a two-line element set, or ``""`` while ``orbit.kind`` is not "tle".

    ``v`` is the value of ``key`` as read from TOML.

    The lines are checked as an element set together (their form, checksums
    and SGP4's start) by the cross rule of ``orbit.kind``.
    """
    if not isinstance(v, str):
        raise ConfigError(key, v, f"must be a string, not {type_name(v)}")
    if len(v.rstrip()) not in (0, 69):
        raise ConfigError(key, v, f"must have 69 characters (a line of a two-line element "
                          f"set), not {len(v.rstrip())}")
    return v.rstrip()


tle_line.allowed = 'a line of a two-line element set (69 characters), or "" with no "tle"'

#: One checker per key, in the order of the default file.
RULES: dict[str, Callable] = {
    "mission.date_utc": utc_datetime,
    "mission.seed": integer(in_closed(0, SEED_MAX, "2**32 - 1: 32-bit seeds")),
    "mission.frame_s": number(at_least(FRAME_MIN_S, "a hundredth of the default 10 ms "
                                                    "valve pulse; nothing modelled is faster")),
    "mission.telemetry_every_frames": integer(in_closed(1, MISSION_MAX_FRAMES, _MOST_FRAMES)),
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
    "star_tracker.reference_star": star_name,
    "star_tracker.cone_angle_check_deg": number(in_closed(0, 90, "0 = no check")),
    "star_tracker.bright_gate": boolean,
    "star_tracker.moving_bodies": one_of("auto", "on", "off"),
    "jets.thrust_n": vector(3, POSITIVE),
    "jets.moment_arm_m": vector(3, POSITIVE),
    "jets.min_on_time_s": number(in_open_closed(0, 1, "cold-gas valves: a few to tens of ms")),
    "jets.isp_s": number(POSITIVE),
    "jets.propellant_kg": number(POSITIVE, in_open_closed(
        0, PROPELLANT_MAX_KG, "a tank larger than any attitude-control system's, whose "
        "per-frame use float64 cannot resolve")),
    "jets.supply": one_of("regulated", "blowdown"),
    "jets.tank_pressure_initial_bar": number(POSITIVE),
    "jets.tank_pressure_final_bar": number(POSITIVE),
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
    "actuators.kind": one_of("jets", "wheels"),
    "wheels.axes": wheel_axes,
    "wheels.max_torque_n_m": per_wheel(POSITIVE),
    "wheels.max_momentum_n_m_s": per_wheel(POSITIVE),
    "wheels.inertia_kg_m2": per_wheel(POSITIVE),
    "wheels.unload_fraction": number(in_open(0, 1)),
    "wheels.unload_end_fraction": number(in_open(0, 1)),
    "wheels.allocation": one_of("pseudo_inverse", "direct"),
    "electronics.vfc_pulse_weight_arcsec": number(in_open_closed(
        0, DEG2ARCSEC, "1 deg: a 360 deg calibration turn counts 360 pulses or more")),
    "electronics.vfc_max_rate_pps": number(POSITIVE),
    "electronics.integrator_drift_deg_h": vector(3, in_closed(
        -INTEGRATOR_DRIFT_MAX_DEG_H, INTEGRATOR_DRIFT_MAX_DEG_H,
        "an amplifier offset this large is a failed chain, not a drift")),
    "electronics.counter_bits": integer(in_closed(8, 62)),
    "electronics.drift_counter_bits": integer(in_closed(4, 62)),
    "electronics.counter_overflow": one_of("wrap", "saturate"),
    "electronics.drift_dac_bits": integer(in_closed(4, 32)),
    "electronics.register_bits": integer(in_closed(4, 32)),
    "electronics.register_lsb_arcsec": number(POSITIVE),
    "electronics.rate_command_deg_s": number(POSITIVE),
    "electronics.computer_step_frames": integer(in_closed(1, MISSION_MAX_FRAMES, _MOST_FRAMES)),
    "sequencer.settle_threshold_arcsec": number(POSITIVE),
    "sequencer.settle_time_s": number(POSITIVE),
    "sequencer.handover_arcsec": number(POSITIVE),
    "sequencer.drift_count_s": number(in_open_closed(0, MISSION_MAX_S, _A_DAY)),
    "sequencer.tracker_blanking_s": number(POSITIVE),
    "sequencer.sensor_loss_s": number(POSITIVE),
    "sequencer.mode1_slew_rate_deg_s": number(POSITIVE),
    "sequencer.mode1_slew_gain_per_s": number(POSITIVE),
    "sequencer.timeout_s": mode_timeouts(in_open_closed(0, MISSION_MAX_S, _A_DAY)),
    "sequencer.between_targets": one_of("reacquire", "recycle", "direct"),
    "sequencer.recovery": boolean,
    "sequencer.turn_check_ppm": number(in_closed(0, 500000, "half a turn: the nearest whole "
                                                 "number of turns is then the one meant; "
                                                 "0 = no check")),
    "orbit.kind": one_of("none", "circular", "tle"),
    "orbit.altitude_km": number(in_closed(150, 1000, "below 150 km a vehicle reenters within "
                                          "a day; the atmosphere's table ends at 1000 km")),
    "orbit.inclination_deg": number(in_closed(0, 180)),
    "orbit.raan_deg": number(in_closed_open(0, 360)),
    "orbit.arg_latitude_deg": number(in_closed_open(0, 360)),
    "orbit.j2": boolean,
    "orbit.tle_line1": tle_line,
    "orbit.tle_line2": tle_line,
    "orbit.sample_s": number(in_open_closed(0, 60, "the interpolation's error grows as its "
                                            "square: 4 km at 60 s")),
    "orbit.atmosphere_height_km": number(in_closed(0, 200)),
    "orbit.gravity_gradient": boolean,
    "orbit.aerodynamic": boolean,
    "orbit.drag_area_m2": number(NON_NEGATIVE),
    "orbit.drag_coefficient": number(NON_NEGATIVE),
    "orbit.pressure_offset_m": vector(3, magnitude_at_most(10)),
    "orbit.solar_pressure": boolean,
    "orbit.srp_area_m2": number(NON_NEGATIVE),
    "orbit.srp_reflectivity": number(in_closed(1, 2, "1 = black, 2 = mirror")),
    "orbit.srp_offset_m": vector(3, magnitude_at_most(10)),
    "target.star": star_name,
    "target.ra_deg": _RA_DEG,
    "target.dec_deg": _DEC_DEG,
    "target.sequence": target_sequence,
    "target.hold_s": number(in_closed(0, MISSION_MAX_S, _A_DAY)),
    "calibration.apply": boolean,
    "dither.amplitude_urad": vector(3, NON_NEGATIVE),
    "dither.period_s": vector(3, POSITIVE),
    "dither.sample_s": number(in_open_closed(0, MISSION_MAX_S, _A_DAY)),
    "dither.record_s": number(in_open_closed(0, MISSION_MAX_S, _A_DAY)),
    "dither.lead_in_s": number(in_closed(0, MISSION_MAX_S, _A_DAY)),
    "dither.feedforward": boolean,
    "dither.inertia_estimate_scale": number(NON_NEGATIVE),
    "dither.estimator": one_of("optical", "command"),
    "dither.detector": one_of("fft", "hann", "lsq"),
    "dither.store_cross_coupling": boolean,
}


def allowed(key: str) -> str:
    """What :data:`RULES` accepts for ``key``, in words.

    The configuration reference shows these words.
    """
    return RULES[key].allowed
