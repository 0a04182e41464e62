"""The schema: which keys a scenario has (the packaged default) and what each accepts.

The packaged default (``scenarios/default.toml``, :data:`DEFAULT_SCENARIO_PATH`)
names every key, with the unit in the key's name, and nothing else; only the
two forms of ``[target]`` (:data:`TARGET_STAR_FORM`, :data:`TARGET_RADEC_FORM`)
may hold keys the default leaves unset. :data:`RULES` gives each key its
checker (:mod:`allsky.config.rules`); :data:`CROSS_RULES` tie keys together
and run after every key passed its own rule.
"""

import difflib
import functools
import math
from collections.abc import Callable
from datetime import timedelta
from importlib import resources
from pathlib import Path

from allsky.config.rules import (
    EPHEMERIS_END_UTC,
    EPHEMERIS_START_UTC,
    MODE_KEYS,
    NON_NEGATIVE,
    POSITIVE,
    SEED_MAX,
    ConfigError,
    at_least,
    attitude,
    boolean,
    in_closed,
    in_closed_open,
    in_open,
    in_open_closed,
    inertia_tensor,
    integer,
    magnitude_at_most,
    magnitude_window,
    misalignment_matrix,
    mode_timeouts,
    number,
    one_of,
    star_name,
    utc_datetime,
    vector,
)
from allsky.config.toml_io import copy_tables, iso_utc, parse_toml
from allsky.units import DEG2ARCSEC

#: The packaged default scenario; it also defines the schema.
DEFAULT_SCENARIO_PATH = Path(str(resources.files("allsky") / "scenarios" / "default.toml"))
#: The two forms of ``[target]``; keys the default need not contain.
TARGET_STAR_FORM = ("star",)
TARGET_RADEC_FORM = ("ra_deg", "dec_deg")

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


# ---------------------------------------------------------------------------
# The keys (the default's tables)
# ---------------------------------------------------------------------------

@functools.cache
def _default_parsed() -> dict:
    text = DEFAULT_SCENARIO_PATH.read_text(encoding="utf-8")
    return parse_toml(text, str(DEFAULT_SCENARIO_PATH))


def default_tables() -> dict:
    """A fresh copy of the parsed default (parsed once: a campaign builds one per run)."""
    return copy_tables(_default_parsed())


@functools.cache
def key_tree() -> dict:
    """Nested dict of every valid key (the default plus the optional target keys); read only."""
    tree = default_tables()
    tree["target"] = {**tree["target"], **dict.fromkeys(TARGET_STAR_FORM + TARGET_RADEC_FORM)}
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
    """Error for the unknown key ``path`` in the table ``here``, naming the nearest valid keys."""
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


# ---------------------------------------------------------------------------
# What each key accepts
# ---------------------------------------------------------------------------

_MOST_FRAMES = "the most frames a mission may take"
_A_DAY = "a mission lasts at most a day"

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
    "jets.thrust_n": vector(3, POSITIVE),
    "jets.moment_arm_m": vector(3, POSITIVE),
    "jets.min_on_time_s": number(in_open_closed(0, 1, "cold-gas valves: a few to tens of ms")),
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
    "electronics.vfc_pulse_weight_arcsec": number(in_open_closed(
        0, DEG2ARCSEC, "1 deg: a 360 deg calibration turn counts 360 pulses or more")),
    "electronics.vfc_max_rate_pps": number(POSITIVE),
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
    "target.star": star_name,
    "target.ra_deg": number(in_closed_open(0, 360)),
    "target.dec_deg": number(in_closed(-90, 90)),
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
    """What :data:`RULES` accepts for ``key``, in words (for the configuration reference)."""
    return RULES[key].allowed


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
    half = v["sun_sensor.presence_half_angle_deg"]
    lin_deg = v["sun_sensor.linear_range_arcsec"] / DEG2ARCSEC
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


def _dither_record(v):
    """`dither.sample_s` whole frames; `dither.record_s` >= dithered periods, <= 2^20 samples."""
    sample, frame = v["dither.sample_s"], v["mission.frame_s"]
    per_sample = sample / frame
    if abs(per_sample - round(per_sample)) > 1e-9 * per_sample:
        raise ConfigError("dither.sample_s", sample,
                          f"must be a whole number of frames (mission.frame_s = {frame:g} s): "
                          f"the record is sampled every {max(1, round(per_sample))} frames")
    lead, record = v["dither.lead_in_s"], v["dither.record_s"]
    samples = (lead + record) / sample
    if samples > DITHER_MAX_SAMPLES:
        raise ConfigError("dither.record_s", record,
                          f"dither.lead_in_s + dither.record_s would hold {samples:.4g} samples "
                          f"of {sample:g} s; must be <= {DITHER_MAX_SAMPLES * sample - lead:g} s "
                          f"(at most 2^20 = {DITHER_MAX_SAMPLES} samples)")
    pairs = zip(v["dither.amplitude_urad"], v["dither.period_s"], strict=True)
    for axis, (amp, period) in enumerate(pairs):
        if amp > 0 and period > record:
            raise ConfigError("dither.period_s", v["dither.period_s"],
                              f"element {axis} must be <= dither.record_s ({record:g} s): the "
                              "record holds a whole period of each dithered axis")


def _fft_whole_periods(v):
    """With `dither.detector = "fft"`, `dither.record_s` holds whole periods of dithered axes."""
    if v["dither.detector"] != "fft":
        return
    sample, record = v["dither.sample_s"], v["dither.record_s"]
    n = round(record / sample)  # the samples the analysis takes (allsky.sequencer.dither_mode)
    pairs = zip(v["dither.amplitude_urad"], v["dither.period_s"], strict=True)
    for axis, (amp, period) in enumerate(pairs):
        turns = n * sample / period
        if amp > 0 and abs(turns - round(turns)) > 1e-6:  # the tolerance of dither.fft_amplitude
            raise ConfigError("dither.period_s", v["dither.period_s"],
                              f"element {axis} goes {turns:.6g} times into dither.record_s "
                              f'({record:g} s): the "fft" detector needs whole periods in the '
                              'record (or use "hann" or "lsq")')


def _converters_follow_the_turns(v):
    """Converters 8, 10, 12 follow the calibration turns: max rate x pulse weight > rate command."""
    pps, weight = v["electronics.vfc_max_rate_pps"], v["electronics.vfc_pulse_weight_arcsec"]
    turn_arcsec_s = v["electronics.rate_command_deg_s"] * DEG2ARCSEC
    if not pps * weight > turn_arcsec_s:
        raise ConfigError("electronics.vfc_max_rate_pps", pps,
                          f"must be > {turn_arcsec_s / weight:g}: converters 8, 10, 12 saturate "
                          f"at {pps * weight:g} arcsec/s, no faster than the calibration turns "
                          f"({turn_arcsec_s:g} arcsec/s, electronics.rate_command_deg_s)")


# ---------------------------------------------------------------------------
# How long a mission may take, and what that costs
# ---------------------------------------------------------------------------

def plan_durations_s(v) -> dict:
    """Longest time [s] of the ``legacy`` and ``dither`` plans: their modes' timeouts.

    The dither mode, in place of Modes 4 and 5, is allowed its lead-in and record and
    :data:`DITHER_SETTLE_ALLOWANCE_S`."""
    t = v["sequencer.timeout_s"]
    legacy = math.fsum(t[m] for m in MODE_KEYS)
    dither = math.fsum([*(t[m] for m in MODE_KEYS if m not in ("4", "5")),
                        v["dither.lead_in_s"], v["dither.record_s"], DITHER_SETTLE_ALLOWANCE_S])
    return {"legacy": legacy, "dither": dither}


def longest_mission_s(v) -> float:
    """The longest a mission of either plan can take [s] (:func:`plan_durations_s`)."""
    return max(plan_durations_s(v).values())


def last_start_utc(v):
    """The latest ``mission.date_utc`` whose mission ends inside the ephemeris range."""
    span_s = max(longest_mission_s(v), SUN_RATE_SPAN_S)
    return EPHEMERIS_END_UTC - timedelta(seconds=span_s)


def _mission_within_a_day(v):
    """The longest mission (its plan's mode timeouts) <= 86400 s: the Sun moves on a line."""
    plans = plan_durations_s(v)
    why = f"must fit in {MISSION_MAX_S:g} s, a day: the Sun moves on a line good to 1.4 arcsec"
    if plans["legacy"] > MISSION_MAX_S:
        raise ConfigError("sequencer.timeout_s", v["sequencer.timeout_s"],
                          f"the modes' timeouts add up to {plans['legacy']:g} s; a mission {why}")
    if plans["dither"] > MISSION_MAX_S:
        raise ConfigError("dither.record_s", v["dither.record_s"],
                          f"the dither plan would take {plans['dither']:g} s (timeouts of Modes "
                          f"1, 2, 3, 6-1, 6-2 + dither.lead_in_s + dither.record_s + "
                          f"{DITHER_SETTLE_ALLOWANCE_S:g} s); a mission {why}")


def _frames_of_the_longest_mission(v):
    """The longest mission / `mission.frame_s` <= 1e8 frames (about 40 s of computing)."""
    longest, frame = longest_mission_s(v), v["mission.frame_s"]
    frames = longest / frame
    if frames > MISSION_MAX_FRAMES:
        raise ConfigError("mission.frame_s", frame,
                          f"the longest mission ({longest:g} s) would take {frames:.4g} frames; "
                          f"must be >= {longest / MISSION_MAX_FRAMES:g} s (at most "
                          f"{MISSION_MAX_FRAMES:.0e} frames, about 40 s of computing)")


def _telemetry_rows(v):
    """The longest mission's frames / `mission.telemetry_every_frames` <= 1e6 rows (320 MB)."""
    frames = longest_mission_s(v) / v["mission.frame_s"]
    every = v["mission.telemetry_every_frames"]
    if frames / every > TELEMETRY_MAX_ROWS:
        raise ConfigError("mission.telemetry_every_frames", every,
                          f"the longest mission ({frames:.4g} frames) would record "
                          f"{frames / every:.4g} telemetry rows; must be >= "
                          f"{math.ceil(frames / TELEMETRY_MAX_ROWS)} (at most "
                          f"{TELEMETRY_MAX_ROWS:.0e} rows, 320 MB)")


def _mission_ends_inside_the_ephemeris(v):
    """`mission.date_utc` + the longest mission (at least 1 h) ends by 2100-12-31T23:59:59Z."""
    date, last = v["mission.date_utc"], last_start_utc(v)
    if date > last:
        span = f"{EPHEMERIS_START_UTC.date()}..{EPHEMERIS_END_UTC.date()}"
        raise ConfigError("mission.date_utc", date, f"must be <= {iso_utc(last)}: the mission "
                          f"would end after the ephemeris range {span} (the longest mission "
                          f"takes {longest_mission_s(v):g} s, the Sun's rate the first "
                          f"{SUN_RATE_SPAN_S:g} s)")


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
               _dither_sampling, _dither_record, _fft_whole_periods, _converters_follow_the_turns,
               _mission_within_a_day, _frames_of_the_longest_mission, _telemetry_rows,
               _mission_ends_inside_the_ephemeris, _one_target_form)
