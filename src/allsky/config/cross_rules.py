"""Rules that tie scenario keys together, run after each key passed its own.

Each rule is a function of the flat scenario (``"table.key" -> value``) that
raises :class:`~allsky.config.rules.ConfigError` naming a key; its docstring
is the rule in words, as the configuration reference prints it.
"""

import math
from datetime import datetime, timedelta

from allsky.config.rules import (
    EPHEMERIS_END_UTC,
    EPHEMERIS_START_UTC,
    MODE_KEYS,
    ConfigError,
)
from allsky.config.schema import (
    DITHER_MAX_SAMPLES,
    DITHER_SETTLE_ALLOWANCE_S,
    HOLD_TIMEOUT_ALLOWANCE_S,
    MISSION_MAX_FRAMES,
    MISSION_MAX_S,
    SUN_RATE_SPAN_S,
    TARGET_RADEC_FORM,
    TELEMETRY_MAX_ROWS,
)
from allsky.config.toml_io import iso_utc
from allsky.units import DEG2ARCSEC
from allsky.vehicle import sky
from allsky.vehicle.sky import check_to_pass_deg, cone_angle_deg


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


def _one_limit_per_wheel(v):
    """`wheels.max_torque_n_m`, `max_momentum_n_m_s`, `inertia_kg_m2`: one number or one per wheel."""
    n = len(v["wheels.axes"])
    for key in ("wheels.max_torque_n_m", "wheels.max_momentum_n_m_s", "wheels.inertia_kg_m2"):
        if isinstance(v[key], tuple) and len(v[key]) != n:
            raise ConfigError(key, v[key], f"must be one number or {n} numbers, one per wheel "
                              f"of wheels.axes ({len(v[key])} given)")


def _unload_hysteresis(v):
    """`wheels.unload_end_fraction` < `wheels.unload_fraction` (unloading stops below it)."""
    start, end = v["wheels.unload_fraction"], v["wheels.unload_end_fraction"]
    if not end < start:
        raise ConfigError("wheels.unload_end_fraction", end,
                          f"must be < wheels.unload_fraction ({start:g}): unloading runs from "
                          "that fraction of the momentum limit down to this one")


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

    ``v`` is the flat scenario (``"table.key" -> value``), every key checked.
    The dither mode, in place of Modes 4 and 5, is allowed its lead-in and
    record and :data:`DITHER_SETTLE_ALLOWANCE_S`; a hold on target
    (`target.hold_s` > 0), flown after either plan, its hold and
    :data:`HOLD_TIMEOUT_ALLOWANCE_S`. Each further target of `target.sequence`
    adds Modes 1, 2, 6-1, 6-2 and the hold (`sequencer.between_targets =
    "reacquire"`), the whole plan again ("recycle"), or the direct roll
    (allowed Mode 6-1's timeout), Mode 6-2 and the hold ("direct")."""
    t = v["sequencer.timeout_s"]
    hold = v["target.hold_s"] + HOLD_TIMEOUT_ALLOWANCE_S if v["target.hold_s"] > 0 else 0.0
    legacy = math.fsum([*(t[m] for m in MODE_KEYS), hold])
    dither = math.fsum([*(t[m] for m in MODE_KEYS if m not in ("4", "5")),
                        v["dither.lead_in_s"], v["dither.record_s"], DITHER_SETTLE_ALLOWANCE_S,
                        hold])
    further = len(v.get("target.sequence") or ((),)) - 1
    if further:
        if v["sequencer.between_targets"] == "recycle":
            legacy, dither = legacy * (1 + further), dither * (1 + further)
        elif v["sequencer.between_targets"] == "direct":
            again = further * math.fsum([*(t[m] for m in ("6-1", "6-2")), hold])
            legacy, dither = legacy + again, dither + again
        else:
            again = further * math.fsum([*(t[m] for m in ("1", "2", "6-1", "6-2")), hold])
            legacy, dither = legacy + again, dither + again
    return {"legacy": legacy, "dither": dither}


def longest_mission_s(v) -> float:
    """The longest a mission of either plan can take [s] (:func:`plan_durations_s`).

    ``v`` is the flat scenario (``"table.key" -> value``), every key checked.
    """
    return max(plan_durations_s(v).values())


def last_start_utc(v):
    """The latest ``mission.date_utc`` whose mission ends inside the ephemeris range.

    ``v`` is the flat scenario (``"table.key" -> value``), every key checked;
    the mission is allowed at least :data:`SUN_RATE_SPAN_S` after its start.
    """
    span_s = max(longest_mission_s(v), SUN_RATE_SPAN_S)
    return EPHEMERIS_END_UTC - timedelta(seconds=span_s)


def _mission_within_a_day(v):
    """The longest mission (its plan's mode timeouts) <= 86400 s: the Sun moves on a line."""
    plans = plan_durations_s(v)
    why = f"must fit in {MISSION_MAX_S:g} s, a day: the Sun moves on a line good to 1.4 arcsec"
    if plans["legacy"] > MISSION_MAX_S:
        if len(v.get("target.sequence") or ()) > 1:
            raise ConfigError("target.sequence", f"{len(v['target.sequence'])} targets",
                              f"the modes' timeouts for every target (and the holds) add up "
                              f"to {plans['legacy']:g} s; a mission {why}")
        if v["target.hold_s"] > 0:
            raise ConfigError("target.hold_s", v["target.hold_s"],
                              f"the modes' timeouts and the hold (+ {HOLD_TIMEOUT_ALLOWANCE_S:g}"
                              f" s) add up to {plans['legacy']:g} s; a mission {why}")
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
    """`target.star`, both `target.ra_deg` and `target.dec_deg`, or `target.sequence`."""
    if v["target.star"] is not None or v.get("target.sequence") is not None:
        return
    for k in TARGET_RADEC_FORM:
        if v[f"target.{k}"] is None:
            raise ConfigError(f"target.{k}", rule="missing: give target.star, both "
                              "target.ra_deg and target.dec_deg, or target.sequence")


def _reference_star_in_window(v):
    """`star_tracker.reference_star` lies inside `star_tracker.magnitude_window`."""
    name, (lo, hi) = v["star_tracker.reference_star"], v["star_tracker.magnitude_window"]
    mag = sky.star(name).magnitude
    if not lo <= mag <= hi:
        raise ConfigError("star_tracker.reference_star", name,
                          f"magnitude {mag:+.2f} is outside star_tracker.magnitude_window "
                          f"[{lo:g}, {hi:g}]: the tracker could never lock it")


def _cone_check_passes_the_reference_star(v):
    """`star_tracker.cone_angle_check_deg`, if set, passes the reference star at the slit's edge.

    A roll search finds a star at the edge of the slit's narrow width
    (`star_tracker.fov_narrow_half_deg`), where its pitch output is further
    from zero than its cone angle (``atan(tan c / cos psi)``); a check
    smaller than that offset refuses the reference star itself.
    """
    check = v["star_tracker.cone_angle_check_deg"]
    if check <= 0.0:
        return

    name, date = v["star_tracker.reference_star"], v["mission.date_utc"]
    sun = sky.sun_direction_inertial(date)
    cosine = max(-1.0, min(1.0, float(sun @ sky.star_direction_inertial(name, date))))
    cone = cone_angle_deg(math.degrees(math.acos(cosine)))
    narrow = v["star_tracker.fov_narrow_half_deg"]
    need = check_to_pass_deg(cone, cone, narrow)
    if check <= need:
        raise ConfigError("star_tracker.cone_angle_check_deg", check,
                          f"too small to pass {name} itself: met at the slit's edge "
                          f"(star_tracker.fov_narrow_half_deg = {narrow:g}) its pitch output "
                          f"is {need:.3f} deg from its cone angle {cone:+.2f} deg; the check "
                          f"must be > {need:.3f} deg")


def _blowdown_pressures(v):
    """`jets.tank_pressure_final_bar` < `jets.tank_pressure_initial_bar` (the tank empties)."""
    p0, pf = v["jets.tank_pressure_initial_bar"], v["jets.tank_pressure_final_bar"]
    if not pf < p0:
        raise ConfigError("jets.tank_pressure_final_bar", pf,
                          f"must be < jets.tank_pressure_initial_bar ({p0:g} bar): the "
                          "pressure falls as the gas is used")


#: [days] the farthest a mission may fly from its element set's epoch
TLE_AGE_MAX_DAYS = 30.0


def _orbit_elements(v):
    """`orbit.kind` = "tle": `orbit.tle_line1` and `orbit.tle_line2` are an element set SGP4 flies."""
    if v["orbit.kind"] != "tle":
        return
    from allsky.vehicle.orbit import parse_tle

    l1, l2 = v["orbit.tle_line1"], v["orbit.tle_line2"]
    if not l1 or not l2:
        raise ConfigError("orbit.tle_line1" if not l1 else "orbit.tle_line2", "",
                          'orbit.kind = "tle" needs both lines of the element set')
    try:
        sat = parse_tle(l1, l2)
    except ValueError as exc:
        raise ConfigError("orbit.tle_line1", l1, f"not an element set SGP4 can fly: {exc}") \
            from None
    date = v["mission.date_utc"]
    epoch = datetime(2000, 1, 1, 12, tzinfo=date.tzinfo) + timedelta(
        days=sat.jdsatepoch + sat.jdsatepochF - 2451545.0)
    age_days = abs((date - epoch) / timedelta(days=1))
    if age_days > TLE_AGE_MAX_DAYS:
        raise ConfigError("mission.date_utc", date, f"is {age_days:.1f} days from the element "
                          f"set's epoch {iso_utc(epoch)}; must be within {TLE_AGE_MAX_DAYS:g} "
                          "days (SGP4's error grows by a few km a day)")


#: Cross-key rules, in the order they are checked.
CROSS_RULES = (_frame_fits_jet_minimum, _pwpf_hysteresis, _sun_presence_covers_linear_range,
               _dither_sampling, _dither_record, _fft_whole_periods, _one_limit_per_wheel,
               _unload_hysteresis, _converters_follow_the_turns,
               _mission_within_a_day, _frames_of_the_longest_mission, _telemetry_rows,
               _mission_ends_inside_the_ephemeris, _one_target_form, _reference_star_in_window,
               _cone_check_passes_the_reference_star, _blowdown_pressures,
               _orbit_elements)
