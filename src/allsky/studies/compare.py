"""The patent's calibration (Modes 4-5) against the dither method, same vehicle.

Both methods fly the same vehicle: same scenario, same gyro errors, same
seed, hence the same ejection and the same noise through Mode 3. Then the
legacy mission turns 360 deg in roll and in yaw (Modes 4 and 5) while the
comparison mission dithers in the Sun-and-star hold; each flies Mode 6 to
the target with its own calibration. Per method: scale-factor and
cross-coupling errors, calibration time, the largest excursion from the
attitude the mission wanted (the disruption), the propellant the
calibration used, and the final pointing error. With several runs
(seeds), mean, standard deviation and 95th percentile, beside the analytic
expectation of each method's scale-factor spread (docs/comparison.md).

:func:`compare` returns the figures as data; the table, the figure and
``allsky compare`` are in :mod:`allsky.apps.compare`.
"""

import math

import numpy as np

from allsky import units, xmath
from allsky.computer import word_registers as wr
from allsky.sequencer.dither_mode import analyse, cross_coupling_words
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission
from allsky.sim.results import (
    CROSS_COUPLING_KEYS,
    SCALE_FACTOR_AXES,
    calibration_errors,
    fly_calibrating,
)
from allsky.studies import crlb
from allsky.units import FRACTION2PPM
from allsky.vocabulary import AXES as BODY_AXES

AXES = SCALE_FACTOR_AXES
CC_KEYS = CROSS_COUPLING_KEYS
#: [arcsec] 1-sigma attitude jitter of the optical hold at an instant (the
#: +-1" PWPF dead band; docs/error_budget.md): :func:`predicted`'s value when no
#: measured drift spread gives it
HOLD_JITTER_ARCSEC = 0.3
#: Record lengths [dither periods of the slowest axis] for the error-versus-time curve.
PREFIX_PERIODS = (2, 4, 8, 16)


def _fly(cfg, plan, cross_coupling=None, snapshots=None):
    """Fly one mission; returns (mission, calibration time [s], excursion [arcsec],
    calibration propellant [kg], duration of each calibration mode [s]).

    ``cross_coupling`` (register 23's words by name) is loaded into register
    23 as the calibration starts: misalignment known from elsewhere.
    ``snapshots``, a list, gets the mission's snapshot at the end of the
    calibration (for :func:`allsky.studies.pointing.decompose`)."""
    m = Mission(cfg, telemetry=False, plan=plan)
    cal_modes = ("4", "5") if plan is LEGACY_PLAN else ("dither",)
    known = None if cross_coupling is None else (
        lambda mm: load_cross_coupling(mm.state.word23, cross_coupling))
    keep = None if snapshots is None else (
        lambda mm: None if mm.finished else snapshots.append(mm.snapshot()))
    t_cal, prop, durations = fly_calibrating(m, cal_modes, on_start=known, on_end=keep)
    return m, t_cal, float(m.state.max_excursion_rad[0] * units.RAD2ARCSEC), prop, durations


def _decomposition(out, snapshots) -> None:
    """``pointing_decomposition`` of a method's metrics from its end-of-calibration snapshot.

    Only for a complete mission with a calibration (None otherwise).
    """
    from allsky.studies.pointing import decompose

    done = out["status"] == "complete" and "scale_factor_error_ppm" in out and snapshots
    out["pointing_decomposition"] = decompose(*snapshots[0]) if done else None


def _metrics(m, t_cal, excursion, prop, durations):
    s = m.summary()
    out = {"status": s["status"], "abort_reason": s["abort_reason"], "time_s": t_cal,
           "mode_time_s": durations,
           "max_excursion_arcsec": excursion, "propellant_kg": prop,
           "mission_propellant_kg": s["propellant_kg"],
           "pointing_error_arcsec": s["target"]["pointing_error_arcsec"]}
    if s["calibration"] is not None:
        err = calibration_errors(s["calibration"], s["truth"])
        out["scale_factor_error_ppm"] = err["scale_factor_ppm"]
        out["cross_coupling_error_arcsec"] = err["cross_coupling_arcsec"]
        out["drift_error_deg_h"] = err["drift_deg_h"]
        out["pointing_error_tracker_architecture_arcsec"] = slew_tracking_error_arcsec(
            err["scale_factor_ppm"], s["target"])
    return out, s


def slew_tracking_error_arcsec(scale_factor_error_ppm, target) -> float | None:
    """[arcsec] Slew error of a scale-factor error, the star tracker holding attitude.

    On the dither document's architecture the star tracker, not the gyro
    count, holds the attitude; the gyros carry it only through the slews,
    where a scale-factor error dSF makes a tracking error dSF x the angle
    turned. It is largest on arrival, before the tracker pulls it in:
    ``dSF_roll |roll| (+) dSF_yaw |yaw|`` (root sum of squares; the two
    turns are about orthogonal axes) for the target's roll and yaw turns
    (``target`` of the mission summary). ``scale_factor_error_ppm`` holds the
    method's errors by axis (``"roll"``, ``"yaw"``) [ppm]. Once held on the
    tracker both methods point to the optical hold's jitter. None without a
    target.
    """
    roll, yaw = target.get("programmed_roll_deg"), target.get("programmed_yaw_deg")
    if roll is None or yaw is None:
        return None
    deg = 3600.0 / FRACTION2PPM
    return float(xmath.hypot(scale_factor_error_ppm["roll"] * roll * deg,
                            scale_factor_error_ppm["yaw"] * yaw * deg))


def load_cross_coupling(word23, cross_coupling) -> None:
    """Put the cross-coupling words ``{"roll_into_pitch": ...}`` into register 23.

    ``cross_coupling`` holds the four words by name [-]; ``word23`` is
    register 23, written in place.
    """
    slots = {"roll_into_pitch": wr.ROLL_INTO_PITCH, "roll_into_yaw": wr.ROLL_INTO_YAW,
             "yaw_into_pitch": wr.YAW_INTO_PITCH, "yaw_into_roll": wr.YAW_INTO_ROLL}
    for name, slot in slots.items():
        word23[slot] = float(cross_coupling[name])


def fly_pair(args, on_flight=None):
    """Legacy and dither missions for one seed: ``(scenario_dict, seed)`` -> metrics.

    ``args`` is that pair (a campaign's job). ``on_flight``, if given, is
    called as ``on_flight(name)`` after each mission flown.
    """
    return _fly_pair(args, on_flight)[0]


def _flown(on_flight, name):
    if on_flight is not None:
        on_flight(name)


def _fly_pair(args, on_flight=None):
    """:func:`fly_pair`, and the legacy turns' cross-coupling words (None if aborted)."""
    from allsky.config import scenario_from_dict

    data, seed = args[0], args[1]
    cfg = scenario_from_dict(data, [f"mission.seed={seed}"])
    snaps = []
    m, *rest = _fly(cfg, LEGACY_PLAN, snapshots=snaps)
    legacy, s_legacy = _metrics(m, *rest)
    _decomposition(legacy, snaps)
    _flown(on_flight, "legacy")
    # Same misalignment knowledge for both: the legacy turns' cross-coupling words, given
    # to the dither as the separate misalignment correction its method assumes.
    words = (s_legacy["calibration"] or {}).get("cross_coupling")
    if legacy["status"] != "complete":
        words = None
    legacy["pointing_error_same_misalignment_arcsec"] = legacy["pointing_error_arcsec"]
    snaps = []
    m, *rest = _fly(cfg, DITHER_PLAN, snapshots=snaps)
    dith, s = _metrics(m, *rest)
    _decomposition(dith, snaps)
    _flown(on_flight, "dither")
    if words is not None:
        known, *rest_known = _fly(cfg, DITHER_PLAN, cross_coupling=words)
        _flown(on_flight, "dither, legacy misalignment")
        with_words, _ = _metrics(known, *rest_known)
        dith["pointing_error_same_misalignment_arcsec"] = with_words["pointing_error_arcsec"]
        if "scale_factor_error_ppm" in with_words:
            dith["scale_factor_error_same_misalignment_ppm"] = with_words[
                "scale_factor_error_ppm"]
    else:
        dith["pointing_error_same_misalignment_arcsec"] = None
    if m.dither_estimates is not None:
        truth = s["truth"]["scale_factor"]
        est = m.dither_estimates
        tcc = s["truth"]["cross_coupling"]
        pairs = {"roll_into_pitch": ("roll", "pitch"), "roll_into_yaw": ("roll", "yaw"),
                 "yaw_into_pitch": ("yaw", "pitch"), "yaw_into_roll": ("yaw", "roll")}
        dith["cross_coupling_error_arcsec"] = {
            k: units.RAD2ARCSEC * (est[a]["cross"][b] - tcc[k])
            for k, (a, b) in pairs.items() if a in est}
        dith["scale_factor_error_command_ppm"] = {
            a: FRACTION2PPM * (est[a]["scale_factor_command"] - truth[a]) for a in AXES if a in est}
        dith["tracking_ratio"] = {a: est[a]["tracking_ratio"] for a in est}
        dith["prefix_error_ppm"] = _prefix_errors(m, truth)
    # The information limit of both plans' manoeuvres, flown again recording every frame.
    bounds = crlb.flown_bounds(cfg)
    _flown(on_flight, "information limit")
    return {"seed": seed, "legacy": legacy, "dither": dith, "crlb": bounds}, words


def _prefix_errors(m, truth):
    """Scale-factor error [ppm] of the dither estimate from shorter records."""
    d = m.cfg.dither
    p = m.params.dither
    slow = max(d.period_s[i] for i in range(3) if d.amplitude_urad[i] != 0.0)
    out = {}
    for k in PREFIX_PERIODS:
        rec_s = k * slow
        if rec_s > d.record_s + 1e-9:
            continue
        est = analyse(m.dither_record, d.sample_s, d.lead_in_s, rec_s, p.amplitude_arcsec,
                      p.omega_rad_s, "lsq" if d.detector == "lsq" else "hann"
                      if d.detector == "hann" else "fft",
                      optics_frames=m.params.dither_sample_frames,
                      cross_coupling=cross_coupling_words(m.state.word23))
        key = "scale_factor_optical" if d.estimator == "optical" else "scale_factor_command"
        out[f"{rec_s:g}"] = {a: FRACTION2PPM * (est[a][key] - truth[a]) for a in AXES if a in est}
    return out


#: What each statistic of a comparison over several runs means (:func:`_stats`; all over
#: the complete runs). Unlike ``allsky montecarlo``, whose percentiles are of the signed
#: values, ``p95`` here is of the absolute values; :func:`label_percentiles` adds the
#: explicit ``p95_abs`` beside it.
STATISTICS = {
    "mean": "mean of the signed values",
    "std": "sample standard deviation of the signed values (ddof 1; 0 for one run)",
    "p95": "95th percentile of the absolute values |x| (the same number as p95_abs)",
    "p95_abs": "95th percentile of the absolute values |x|",
}


def _stats(values):
    """Mean and sample standard deviation of ``values``, and the 95th percentile of |values|."""
    v = np.asarray(values, dtype=float)
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "p95": float(np.percentile(np.abs(v), 95))}


def label_percentiles(result: dict) -> dict:
    """A copy of a :func:`compare` result whose statistics name their percentile.

    ``result`` is left as it is. Every statistic (``{"mean", "std", "p95"}``)
    also carries ``p95_abs``, the same number under a name that says it is a
    percentile of the absolute values, and ``statistics`` (:data:`STATISTICS`)
    explains the keys. ``p95`` stays, for scripts that read it.
    ``allsky compare --json`` writes this.
    """
    def walk(value):
        if isinstance(value, dict):
            out = {k: walk(v) for k, v in value.items()}
            if set(value) == {"mean", "std", "p95"}:
                out["p95_abs"] = value["p95"]
            return out
        if isinstance(value, list):
            return [walk(v) for v in value]
        return value

    return {**walk(result), "statistics": dict(STATISTICS)}


def _aggregate(rows, method):
    ok = [r[method] for r in rows if r[method]["status"] == "complete"]
    out = {"runs": len(rows), "complete": len(ok)}
    if not ok:
        return out
    for key in ("scale_factor_error_ppm", "cross_coupling_error_arcsec", "drift_error_deg_h",
                "scale_factor_error_command_ppm", "tracking_ratio",
                "scale_factor_error_same_misalignment_ppm"):
        have = [r[key] for r in ok if r.get(key) is not None]
        if have:
            out[key] = {a: _stats([h[a] for h in have]) for a in have[0]}
    for key in ("time_s", "max_excursion_arcsec", "propellant_kg", "mission_propellant_kg",
                "pointing_error_arcsec"):
        out[key] = _stats([r[key] for r in ok])
    # Figures that need the other method's flight (same misalignment) or a target: over
    # the runs that have them.
    for key in ("pointing_error_same_misalignment_arcsec",
                "pointing_error_tracker_architecture_arcsec"):
        have = [r[key] for r in ok if r.get(key) is not None]
        if have:
            out[key] = _stats(have)
    have = [r["pointing_decomposition"] for r in ok if r.get("pointing_decomposition")]
    if have:
        out["pointing_decomposition"] = {k: _stats([h[k] for h in have]) for k in have[0]}
    if "prefix_error_ppm" in ok[0]:
        out["prefix_rms_ppm"] = {
            t: {a: float(np.sqrt(np.mean([r["prefix_error_ppm"][t][a] ** 2 for r in ok])))
                for a in ok[0]["prefix_error_ppm"][t]}
            for t in ok[0]["prefix_error_ppm"]}
    return out


def predicted(cfg, legacy_time_s=None, drift_sigma_deg_h=None) -> dict:
    """Analytic 1-sigma scale-factor errors [ppm] of both methods.

    Dither (estimator "optical"): gyro angle random walk and optical-sensor
    noise, each through a least-squares/DFT amplitude estimate::

        sigma^2 = (N sqrt(2/T) / (A w))^2 + (sigma_opt sqrt(2/(n M)) / A)^2

    (N ARW density, T record length, n samples of M frames' mean optics each,
    sigma_opt the optics' white noise per frame, A amplitude, w frequency;
    the "command" estimator has only the first term, plus its tracking bias).
    Legacy: the counted 360 deg is off by the drift residual over the count
    T_c, the ARW over it and the attitude of the hold at both ends (1-sigma
    j at an instant); the drift residual is Mode 3's count over T_d, off by
    its ARW and the hold's attitude at its own ends::

        sigma^2 = ((sigma_d T_c)^2 + N^2 T_c + 2 j^2 + s 2 j^2 T_c / T_d) / (1296000")^2,
        sigma_d^2 = N^2 / T_d + 2 j^2 / T_d^2

    s = 1 for the roll turn: Mode 4's count starts at the frame Mode 3's
    ends, so the attitude of that instant enters both counts, weighted
    -1 and -T_c/T_d (the drift residual over the turn), and adds the cross
    term; s = 0 for the yaw turn, which starts after the roll turn's settle.
    j is :data:`HOLD_JITTER_ARCSEC` unless ``drift_sigma_deg_h`` gives the
    measured spread of Mode 3's drift count per axis [deg/h = arcsec/s]
    (several runs: :func:`compare`): then sigma_d is that spread and
    ``j^2 = (sigma_d^2 - N^2/T_d) T_d^2 / 2`` the jitter it shows, per axis
    and vehicle (the jets' limit cycle, or on the wheels the tail of the
    settle the counts start and end on; docs/comparison.md).

    ``cfg`` is the scenario; ``legacy_time_s`` the mean flown durations of
    the roll and yaw counts, ``{"roll": T_c, "yaw": T_c}`` [s] (None: a 360
    deg turn at the rate command plus 20 %).
    """
    n_arw = cfg.gyro.arw_deg_rt_h * 60.0  # arcsec/sqrt(s)
    d = cfg.dither
    opt_noise = {"roll": cfg.star_tracker.noise_arcsec, "yaw": cfg.sun_sensor.noise_arcsec}
    out = {"dither": {}, "legacy": {}}
    # Each optical sample is the mean of the frames since the last (sim.recorder.record_dither).
    n_frames = d.record_s / d.sample_s * max(1, round(d.sample_s / cfg.mission.frame_s))
    for i, a in ((0, "roll"), (2, "yaw")):
        amp = d.amplitude_urad[i] * units.URAD2RAD * units.RAD2ARCSEC
        if amp == 0:
            continue
        w = 2 * math.pi / d.period_s[i]
        gyro_term = n_arw * math.sqrt(2.0 / d.record_s) / (amp * w)
        opt_term = opt_noise[a] * math.sqrt(2.0 / n_frames) / amp
        out["dither"][a] = FRACTION2PPM * xmath.hypot(gyro_term, opt_term if d.estimator == "optical"
                                            else 0.0)
    t_d = cfg.sequencer.drift_count_s
    for a in AXES:
        sigma_d, j2 = _hold_terms(n_arw, t_d, (drift_sigma_deg_h or {}).get(a))
        # Default: a 360 deg turn at the rate command plus ~20 % for spin-up and settling.
        t_c = (legacy_time_s or {}).get(a, 1.2 * 360.0 / cfg.electronics.rate_command_deg_s)
        shared = 2.0 * j2 * t_c / t_d if a == "roll" else 0.0
        out["legacy"][a] = FRACTION2PPM * math.sqrt((sigma_d * t_c) ** 2 + n_arw ** 2 * t_c
                                                    + 2 * j2 + shared) / 1296000.0
    return out


def _hold_terms(n_arw, t_d, drift_sigma=None):
    """Drift-count 1-sigma [arcsec/s] and hold jitter^2 [arcsec^2] for :func:`predicted`.

    Without a measured drift spread, the jitter is :data:`HOLD_JITTER_ARCSEC`;
    with one, the spread is taken as it is and the jitter is what it leaves
    beyond the ARW (none if the ARW alone explains it).
    """
    if drift_sigma is None:
        j2 = HOLD_JITTER_ARCSEC ** 2
        return math.sqrt(n_arw ** 2 / t_d + 2 * j2 / t_d ** 2), j2
    return float(drift_sigma), max(0.0, drift_sigma ** 2 - n_arw ** 2 / t_d) * t_d ** 2 / 2.0


def on_vehicle(cfg, vehicle=None):
    """Scenario ``cfg`` flown on ``vehicle``: "jets", "wheels" or None (as it says).

    The vehicle is ``actuators.kind``: both methods fly the same one.
    """
    if vehicle is None or vehicle == cfg.actuators.kind:
        return cfg
    from allsky.config import scenario_from_dict

    return scenario_from_dict(cfg.as_dict(), [f'actuators.kind="{vehicle}"'])


def compare(cfg, runs=1, workers=2, on_progress=None, vehicle=None,
            methods=("legacy", "dither"), on_flight=None) -> dict:
    """Fly both methods over ``runs`` seeds from the scenario's; return the results.

    Parameters
    ----------
    cfg : Scenario
        The vehicle both methods fly; seeds ``cfg.mission.seed`` on.
    runs : int
        Number of seeds (pairs of missions).
    workers : int
        Worker processes when ``runs`` > 1 (1: in this process); never more
        than ``runs``.
    on_progress : callable, optional
        ``on_progress(done, total)`` after each pair, in seed order.
    vehicle : {"jets", "wheels"}, optional
        Fly both methods on the jets (PWPF modulators and jets 39-41) or on
        the reaction wheels (:func:`on_vehicle`); None: the scenario's
        ``actuators.kind``.
    methods : sequence of str
        :data:`METHODS` to fly: legacy and dither always, ``"kalman"`` for
        the three-axis Kalman filter's two flights (:func:`fly_three`) and
        ``"smoother"`` for the smoother over Modes 3-5 (:func:`smoother_metrics`).
    on_flight : callable, optional
        ``on_flight(name)`` after each mission of a pair, when the pairs are
        flown in this process (``workers`` 1 or one run): progress inside a
        pair, whose missions take seconds each.

    Returns
    -------
    dict
        ``vehicle`` ("wheels"; absent on the jets, the default vehicle),
        ``runs``, ``seeds`` (first, last), ``legacy`` and ``dither`` (one
        run's metrics, or statistics over the runs),
        ``predicted_scale_factor_sigma_ppm``, ``dither_torque_check`` (the
        dither's feed-forward torque in the wheels' and the jets' envelopes,
        :func:`allsky.studies.envelope_check.flown_dither_check`) and
        ``predicted_scale_factor_sigma_a_priori_ppm`` (the same formulas
        from the noise models alone), ``crlb`` and ``crlb_manoeuvres``
        (:func:`crlb_sections`: the information limit of each method's and
        each manoeuvre's data), in each method's section its
        ``pointing_decomposition`` (:mod:`allsky.studies.pointing`), and
        ``rows`` (per seed); with ``"kalman"``, ``kalman`` and
        ``kalman_dither`` too (:func:`kalman_sections`), with
        ``"smoother"``, ``smoother`` (:func:`smoother_section`). After a
        Ctrl-C (or SIGTERM) with pairs finished: those pairs, ``runs`` their
        number, ``interrupted`` True and ``runs_requested``; with none
        finished, the KeyboardInterrupt goes on.
    """
    from allsky.studies.envelope_check import flown_dither_check
    from allsky.studies.montecarlo import ordered_rows

    cfg = on_vehicle(cfg, vehicle)
    data = cfg.as_dict()
    seeds = range(int(cfg.mission.seed), int(cfg.mission.seed) + runs)
    extra = tuple(m for m in METHODS if m in methods and m not in DEFAULT_METHODS)
    if extra:  # made as they are flown
        jobs, fly_row = ((data, s, extra) for s in seeds), fly_methods
    else:
        jobs, fly_row = ((data, s) for s in seeds), fly_pair
    # A seed whose worker process died twice: a row of that status in every section.
    sections = ("legacy", "dither", *(KALMAN_SECTIONS if "kalman" in extra else ()),
                *(("smoother",) if "smoother" in extra else ()))
    rows, interrupted = ordered_rows(
        fly_row, jobs, workers, on_progress, fly_here=lambda job: fly_row(job, on_flight),
        total=runs, died=lambda job, why: {"seed": job[1], **{
            k: {"status": "worker_died", "abort_reason": why} for k in sections}})
    done = len(rows)
    result = {"runs": done, "seeds": [seeds[0], seeds[done - 1]]}
    if cfg.actuators.kind != "jets":
        result = {"vehicle": cfg.actuators.kind, **result}
    if interrupted:
        result["interrupted"] = True
        result["runs_requested"] = runs
    if done == 1:
        result["legacy"], result["dither"] = rows[0]["legacy"], rows[0]["dither"]
    else:
        result["legacy"], result["dither"] = _aggregate(rows, "legacy"), _aggregate(rows,
                                                                                     "dither")
    result["predicted_scale_factor_sigma_ppm"] = predicted(cfg, _legacy_times(rows),
                                                           _legacy_drift_spread(rows))
    # The same formulas a priori: the angle random walk and the hold jitter of the
    # dead band (HOLD_JITTER_ARCSEC) for the drift count, nothing of these runs' spread;
    # only the counts' durations are the flown ones (the manoeuvre, not its noise).
    result["predicted_scale_factor_sigma_a_priori_ppm"] = predicted(cfg, _legacy_times(rows))
    # The dither's feed-forward torque against the actuators' envelopes (either vehicle).
    result["dither_torque_check"] = flown_dither_check(cfg)
    if "kalman" in methods:
        kalman_sections(result, rows)
    if "smoother" in methods:
        smoother_section(result, rows)
    crlb_sections(result, rows)
    result["rows"] = rows
    return result


def _legacy_times(rows):
    """Mean durations of Mode 4 (roll count) and Mode 5 (yaw count) [s]."""
    ok = [r["legacy"]["mode_time_s"] for r in rows if r["legacy"]["status"] == "complete"]
    if not ok:
        return None
    return {"roll": float(np.mean([t["4"] for t in ok])),
            "yaw": float(np.mean([t["5"] for t in ok]))}


def _legacy_drift_spread(rows):
    """Sample standard deviation of Mode 3's drift error [deg/h], roll and yaw.

    Over the complete legacy runs; None with fewer than two (one run has no spread).
    """
    ok = [r["legacy"]["drift_error_deg_h"] for r in rows
          if r["legacy"]["status"] == "complete" and r["legacy"].get("drift_error_deg_h")]
    if len(ok) < 2:
        return None
    return {a: float(np.std([e[a] for e in ok], ddof=1)) for a in AXES}


# -- the third method: the three-axis Kalman filter (allsky.studies.kalman_mekf) -------

#: Methods :func:`compare` flies: legacy and dither always, the Kalman filter and the
#: smoother on request.
METHODS = ("legacy", "dither", "kalman", "smoother")
#: What ``allsky compare`` flies unless ``--methods`` says otherwise.
DEFAULT_METHODS = ("legacy", "dither")
#: The filter's two flights: section of the result -> the plan whose manoeuvres it filters.
KALMAN_SECTIONS = {"kalman": "legacy", "kalman_dither": "dither"}


#: Keys of one method's section that only it has: the dither's estimator figures and
#: the filter's own statistics. The other keys are every method's (docs/comparison.md).
METHOD_KEYS = {
    "legacy": (),
    "dither": ("scale_factor_error_command_ppm", "tracking_ratio", "prefix_error_ppm",
               "prefix_rms_ppm", "scale_factor_error_same_misalignment_ppm"),
    "kalman": ("filter_sigma", "nees", "filter_s"),
    "kalman_dither": ("filter_sigma", "nees", "filter_s"),
    "smoother": ("filter_sigma", "nees", "filter_s", "iterations"),
}
#: Flights of one seed reported as progress: legacy, dither, dither with the legacy
#: misalignment, the information limit's recording flights; the filter's two flights,
#: the smoother's one (:func:`flights_per_seed`).
FLIGHTS = {"pair": 4, "kalman": 2, "smoother": 1}


def flights_per_seed(methods) -> int:
    """Progress steps (:data:`FLIGHTS`) of one seed flown with ``methods``."""
    return FLIGHTS["pair"] + sum(FLIGHTS[m] for m in ("kalman", "smoother") if m in methods)


def fly_methods(args, on_flight=None):
    """:func:`fly_pair` and the requested further methods for one seed.

    ``args`` is ``(scenario_dict, seed, methods)`` -> metrics by section:
    with ``"kalman"`` the filter's two flights (:func:`fly_three`), with
    ``"smoother"`` the smoother's (:func:`smoother_metrics`). ``on_flight`` as
    for :func:`fly_pair`.
    """
    from allsky.config import scenario_from_dict

    data, seed, methods = args
    row, words = _fly_pair((data, seed), on_flight)
    cfg = scenario_from_dict(data, [f"mission.seed={seed}"])
    if "kalman" in methods:
        for section, plan in KALMAN_SECTIONS.items():
            row[section] = kalman_metrics(cfg, plan, words)
            _flown(on_flight, section)
    if "smoother" in methods:
        row["smoother"] = smoother_metrics(cfg, words)
        _flown(on_flight, "smoother")
    return row


def fly_three(args, on_flight=None):
    """:func:`fly_pair` and the Kalman filter's two flights for one seed.

    ``args`` is ``(scenario_dict, seed)`` -> metrics by method, ``on_flight``
    as for :func:`fly_pair`. ``kalman``: the filter
    through the legacy Modes 3-5, ``kalman_dither``: through Mode 3 and the
    dither hold; each loads its estimate into register 23 and the drift
    counters and flies Mode 6 with it (:func:`allsky.studies.kalman_mekf.fly`).
    """
    return fly_methods((args[0], args[1], ("kalman",)), on_flight)


def kalman_metrics(cfg, plan_name, cross_coupling=None) -> dict:
    """The other methods' rows for the filter flown on ``plan_name``'s manoeuvres.

    ``cfg`` is the scenario, at the run's seed.

    ``pointing_error_same_misalignment_arcsec`` flies Mode 6 a second time
    from the end of the calibration, register 23's cross-coupling words
    replaced by ``cross_coupling`` (the legacy turns', as the dither gets
    them; None: no such flight, the figure None). Besides the other
    methods' rows: ``filter_sigma`` (the filter's own 1-sigma of the
    calibration's quantities, :func:`allsky.studies.kalman_mekf.sigmas`),
    ``nees`` at the end of the calibration and ``filter_s``, the wall time
    of the filter.
    """
    from allsky.studies import kalman_mekf

    f = kalman_mekf.fly(cfg, plan_name, through_mode6=False)
    out, s, snaps = _mode6_twice(f, cross_coupling)
    out["pointing_error_same_misalignment_arcsec"] = snaps.pop("known")
    _decomposition(out, snaps["own"])
    if f.estimate is not None and s["calibration"] is not None:
        est = f.estimate
        sig = kalman_mekf.sigmas(est.params[-1], est.covariances[-1])
        out["filter_sigma"] = {"scale_factor_ppm": sig["scale_factor_ppm"],
                               "cross_coupling_arcsec": sig["cross_coupling_arcsec"],
                               "drift_deg_h": sig["drift_deg_h"]}
        out["nees"] = float(kalman_mekf.nees(f.mission, est)[-1])
        out["filter_s"] = f.filter_s
    return out


def _mode6_twice(f, cross_coupling):
    """Mode 6 of a filter's or the smoother's flight ``f``, and once more with ``cross_coupling``.

    Returns its metrics, its summary and ``{"own": [snapshot before Mode 6],
    "known": the second Mode 6's pointing error or None}``.
    """
    known = None
    snaps = {"own": [], "known": None}
    if not f.mission.finished:
        snaps["own"].append(f.mission.snapshot())
        if cross_coupling is not None:
            known = Mission.from_snapshot(*snaps["own"][0], telemetry=False)
            load_cross_coupling(known.state.word23, cross_coupling)
            known.run()
            snaps["known"] = known.summary()["target"]["pointing_error_arcsec"]
    f.mission.run()  # Mode 6 with the method's own estimate
    out, s = _metrics(f.mission, f.time_s, f.excursion_arcsec, f.propellant_kg, f.durations)
    return out, s, snaps


def smoother_metrics(cfg, cross_coupling=None) -> dict:
    """The other methods' rows for the smoother over the legacy Modes 3-5.

    ``cfg`` and ``cross_coupling`` as for :func:`kalman_metrics`, which it
    follows: ``filter_sigma`` (the smoother's own 1-sigma),
    ``nees`` at the end of Mode 5 (exact rotation error), ``filter_s`` (its
    wall time) and ``iterations`` (Gauss-Newton passes).
    """
    from allsky.studies import kalman_mekf, smoother

    f = smoother.fly(cfg, through_mode6=False)
    out, s, snaps = _mode6_twice(f, cross_coupling)
    out["pointing_error_same_misalignment_arcsec"] = snaps.pop("known")
    _decomposition(out, snaps["own"])
    sm = f.smoothed
    if sm is not None and s["calibration"] is not None:
        sig = kalman_mekf.sigmas(sm.params[-1], sm.covariance)
        out["filter_sigma"] = {"scale_factor_ppm": sig["scale_factor_ppm"],
                               "cross_coupling_arcsec": sig["cross_coupling_arcsec"],
                               "drift_deg_h": sig["drift_deg_h"]}
        e = smoother.errors(f.mission, sm)
        out["nees"] = xmath.dot(e, xmath.solve(sm.covariance, e))
        out["filter_s"] = f.smoother_s
        out["iterations"] = sm.iterations
    return out


def smoother_section(result, rows) -> None:
    """Add ``smoother`` to a :func:`compare` result, in place.

    As :func:`kalman_sections` does for the filter: ``result`` gets the
    section, made from ``rows``, the per-seed rows of the runs.
    """
    _filter_section(result, rows, "smoother")


#: A bound's groups under the names of the methods' error figures.
CRLB_KEYS = {"scale_factor_ppm": "scale_factor_error_ppm",
             "cross_coupling_arcsec": "cross_coupling_error_arcsec",
             "drift_deg_h": "drift_error_deg_h"}


def crlb_sections(result, rows) -> None:
    """Add ``crlb`` and ``crlb_manoeuvres`` to a :func:`compare` result, in place.

    ``crlb_manoeuvres``: per manoeuvre of :data:`allsky.studies.crlb.MANOEUVRES`,
    the bound of every quantity (one run's, or the RMS over the runs: the
    bound of the average variance). ``crlb``: per method section of the
    result, the bound of the manoeuvres it calibrates from
    (:data:`allsky.studies.crlb.METHOD_MANOEUVRE`) under the method's own
    keys (``scale_factor_error_ppm``, ``cross_coupling_error_arcsec``,
    ``drift_error_deg_h``), to set beside its measured spread. ``result``
    gets both, made from ``rows``, the per-seed rows of the runs (each with
    its ``crlb``).
    """
    have = [r["crlb"] for r in rows if r.get("crlb")]
    if not have:
        return
    per = {}
    for name in crlb.MANOEUVRES:
        runs = [h[name] for h in have if name in h]
        if runs:
            per[name] = runs[0] if len(rows) == 1 else {
                "runs": len(runs), **crlb.rms_bounds(runs)}
    result["crlb_manoeuvres"] = per
    result["crlb"] = {}
    for section, name in crlb.METHOD_MANOEUVRE.items():
        if section in result and name in per:
            result["crlb"][section] = {key: {k: per[name][group][k] for k in
                                             (AXES if group == "scale_factor_ppm" else
                                              CC_KEYS if group == "cross_coupling_arcsec"
                                              else BODY_AXES)}
                                       for group, key in CRLB_KEYS.items()}


def kalman_sections(result, rows) -> None:
    """Add ``kalman`` and ``kalman_dither`` to a :func:`compare` result, in place.

    ``result`` gets the sections, made from ``rows``, the per-seed rows of
    the runs (:func:`fly_three`).

    One run: its metrics. Several: the statistics of :func:`_aggregate`, the
    drift errors' too, ``filter_sigma`` as the RMS over the runs of the
    filter's 1-sigma (its analytic prediction, beside the measured spread),
    the mean NEES over the complete runs (15 states; with the scenario's
    fixed gyro errors, not a chi-square test: :data:`CONSISTENCY_NOTE`), and the filter's mean wall time. The predicted
    scale-factor sigmas go into ``predicted_scale_factor_sigma_ppm`` too.
    """
    for section in KALMAN_SECTIONS:
        _filter_section(result, rows, section)


#: Where the filter's chi-square consistency test is (not in a comparison's fixed truth).
CONSISTENCY_NOTE = ("not with the scenario's fixed gyro errors; allsky.studies.consistency "
                    "draws them from the filter's prior (docs/kalman.md, Consistency)")


def _filter_section(result, rows, section) -> None:
    """One filter's or smoother's section from its rows (:func:`kalman_sections`)."""
    from allsky.studies.kalman_mekf import N_STATE

    pred = result["predicted_scale_factor_sigma_ppm"]
    ok = [r[section] for r in rows if r[section]["status"] == "complete"
          and "nees" in r[section]]
    if len(rows) == 1:
        result[section] = rows[0][section]
        if ok:
            pred[section] = dict(ok[0]["filter_sigma"]["scale_factor_ppm"])
        return
    out = _aggregate(rows, section)
    if ok:
        out["filter_sigma"] = {
            group: {k: float(np.sqrt(np.mean([r["filter_sigma"][group][k] ** 2
                                              for r in ok])))
                    for k in ok[0]["filter_sigma"][group]}
            for group in ok[0]["filter_sigma"]}
        # The scenario's one set of gyro errors for every run: the states the data do not
        # show keep a fixed error, so this mean is no chi-square statistic. The test draws
        # the errors from the prior (allsky.studies.consistency).
        out["nees"] = {"mean": float(np.mean([r["nees"] for r in ok])), "states": N_STATE,
                       "truth": "fixed", "chi_square_test": CONSISTENCY_NOTE}
        out["filter_s"] = _stats([r["filter_s"] for r in ok])
        pred[section] = dict(out["filter_sigma"]["scale_factor_ppm"])
    result[section] = out
