"""Trade study: the dither's scale-factor error against amplitude and record.

Each point of a grid of dither amplitudes [µrad] and record lengths [s]
flies the dither mission up to the end of its calibration over ``runs``
seeds; the legacy turns (Modes 4-5), flown over the same seeds, are the
reference. Per point: the RMS scale-factor error of each dithered axis
with the dither's own register 23 (no misalignment known) and with the
legacy turns' cross-coupling words known (the misalignment correction the
dither document assumes, :func:`allsky.sequencer.dither_mode.analyse`),
the analytic 1-sigma (:func:`allsky.studies.compare.predicted`), the
largest excursion from the attitude held (the disruption) and the time the
calibration takes. :func:`crossover` finds, per record length, the
amplitude at which the dither reaches the legacy accuracy.

The amplitude applies to every axis the scenario dithers; the record
length replaces ``dither.record_s``. Every point's scenario is validated
before any flight (a bad value raises :class:`allsky.config.ConfigError`
naming the key).
"""

import itertools
import math

import numpy as np

from allsky import units
from allsky.config import scenario_from_dict
from allsky.sequencer.dither_mode import analyse
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission
from allsky.sim.results import SCALE_FACTOR_AXES, calibration_errors
from allsky.studies.compare import predicted


def point_overrides(cfg, amplitude_urad, record_s) -> list:
    """``--set`` strings of one grid point: ``amplitude_urad`` on each dithered axis.

    ``amplitude_urad`` [urad] goes on the axes scenario ``cfg`` dithers (the
    others stay at 0); ``record_s`` [s] is the record length.
    """
    amp = [float(amplitude_urad) if a != 0.0 else 0.0 for a in cfg.dither.amplitude_urad]
    return [f"dither.amplitude_urad=[{amp[0]!r},{amp[1]!r},{amp[2]!r}]",
            f"dither.record_s={float(record_s)!r}"]


def _calibrate(cfg, plan):
    """Fly ``plan`` to the end of its calibration; the mission and its cost.

    Returns (mission, summary, calibration time [s], largest excursion from
    the attitude held as the calibration starts [arcsec], propellant [kg]).
    """
    m = Mission(cfg, telemetry=False, plan=plan)
    cal = ("4", "5") if plan is LEGACY_PLAN else ("dither",)
    t_cal, prop = 0.0, 0.0
    while not m.finished:
        name = m.plan[m.next_mode]
        if name == cal[0]:
            m.track_excursion()
        p0 = m.state.propellant_kg[0]
        rec = m.run_mode()
        if name in cal:
            t_cal += rec.end_s - rec.start_s
            prop += p0 - m.state.propellant_kg[0]
        if name == cal[-1]:
            break
    excursion = float(m.state.max_excursion_rad[0] * units.RAD2ARCSEC)
    return m, m.summary(), t_cal, excursion, prop


def fly_legacy(args):
    """Legacy reference of one seed: ``(scenario_dict, seed)`` -> figures and words.

    ``args`` is that pair, a job of the sweep's campaign.
    """
    data, seed = args
    cfg = scenario_from_dict(data, [f"mission.seed={seed}"])
    _, s, t_cal, excursion, prop = _calibrate(cfg, LEGACY_PLAN)
    out = {"seed": seed, "status": s["status"], "time_s": t_cal,
           "max_excursion_arcsec": excursion, "propellant_kg": prop}
    if s["status"] != "aborted" and s["calibration"] is not None:
        out["scale_factor_error_ppm"] = calibration_errors(s["calibration"],
                                                           s["truth"])["scale_factor_ppm"]
        out["cross_coupling"] = s["calibration"]["cross_coupling"]
    return out


def fly_dither(args):
    """One grid point and seed: ``(scenario_dict, overrides, seed, words)`` -> figures.

    ``args`` is that tuple, a job of the sweep's campaign: ``overrides`` are
    the point's ``--set`` strings (:func:`point_overrides`), ``words`` the
    legacy cross-coupling words of the seed (None: the estimate with
    misalignment known is not formed).
    """
    data, overrides, seed, words = args
    cfg = scenario_from_dict(data, [*overrides, f"mission.seed={seed}"])
    m, s, t_cal, excursion, prop = _calibrate(cfg, DITHER_PLAN)
    out = {"seed": seed, "status": s["status"], "time_s": t_cal,
           "max_excursion_arcsec": excursion, "propellant_kg": prop}
    if m.dither_estimates is None:
        return out
    d, p = cfg.dither, m.params
    truth = s["truth"]["scale_factor"]
    key = "scale_factor_optical" if d.estimator == "optical" else "scale_factor_command"
    out["scale_factor_error_ppm"] = {
        a: units.FRACTION2PPM * (e[key] - truth[a]) for a, e in m.dither_estimates.items()
        if a in SCALE_FACTOR_AXES}
    if words is not None:
        est = analyse(m.dither_record, d.sample_s, d.lead_in_s, d.record_s,
                      p.dither.amplitude_arcsec, p.dither.omega_rad_s, d.detector,
                      optics_frames=p.dither_sample_frames, cross_coupling=words)
        out["scale_factor_error_same_misalignment_ppm"] = {
            a: units.FRACTION2PPM * (e[key] - truth[a]) for a, e in est.items()
            if a in SCALE_FACTOR_AXES}
    return out


def _rms(values):
    v = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(v ** 2))) if v.size else None


def _summarise(rows):
    """RMS errors per axis and mean costs over the complete rows of one point."""
    ok = [r for r in rows if r["status"] != "aborted" and "scale_factor_error_ppm" in r]
    out = {"runs": len(rows), "complete": len(ok)}
    if not ok:
        return out
    for key in ("scale_factor_error_ppm", "scale_factor_error_same_misalignment_ppm"):
        if key in ok[0]:
            out[key.replace("_error_", "_rms_error_")] = {
                a: _rms([r[key][a] for r in ok]) for a in ok[0][key]}
            out[key.replace("_error_", "_mean_error_")] = {
                a: float(np.mean([r[key][a] for r in ok])) for a in ok[0][key]}
    for key in ("time_s", "propellant_kg"):
        out[key] = float(np.mean([r[key] for r in ok]))
    out["max_excursion_arcsec"] = float(np.max([r["max_excursion_arcsec"] for r in ok]))
    out["mean_excursion_arcsec"] = float(np.mean([r["max_excursion_arcsec"] for r in ok]))
    return out


def crossover(points, legacy_rms_ppm, key="scale_factor_rms_error_same_misalignment_ppm"):
    """Amplitude at which the dither reaches the legacy, per record length and axis.

    Interpolated log-log between the first two neighbouring amplitudes
    that bracket the legacy RMS (``legacy_rms_ppm`` per axis); None where
    no amplitude of the grid gets there. ``points`` are :func:`sweep`'s.
    Returns ``{record_s: {axis: {"amplitude_urad": ..., "time_s": ...,
    "max_excursion_arcsec": ..., "bracketed": ...}}}`` (costs interpolated
    the same way); ``bracketed`` is False when the smallest amplitude of the
    grid already gets there (the crossover is at most that point). ``key``
    names the points' figure compared: the RMS error with the legacy
    misalignment known, or ``"scale_factor_rms_error_ppm"`` for the dither's
    own register 23.
    """
    out = {}
    for t in sorted({p["record_s"] for p in points}):
        line = sorted((p for p in points if p["record_s"] == t and key in p),
                      key=lambda p: p["amplitude_urad"])
        out[f"{t:g}"] = {}
        for a, ref in legacy_rms_ppm.items():
            found = None
            first = line[0][key].get(a) if line else None
            if first is not None and first <= ref:
                found = {"amplitude_urad": line[0]["amplitude_urad"],
                         "time_s": line[0]["time_s"],
                         "max_excursion_arcsec": line[0]["max_excursion_arcsec"],
                         "bracketed": False}
            for p, q in itertools.pairwise(line) if found is None else ():
                e0, e1 = p[key].get(a), q[key].get(a)
                if e0 is None or e1 is None or not (e0 > ref >= e1):
                    continue
                f = math.log(e0 / ref) / math.log(e0 / e1)

                def between(k, p=p, q=q, f=f):
                    return math.exp(math.log(p[k]) + f * (math.log(q[k]) - math.log(p[k])))

                found = {"amplitude_urad": between("amplitude_urad"),
                         "time_s": p["time_s"] + f * (q["time_s"] - p["time_s"]),
                         "max_excursion_arcsec": between("max_excursion_arcsec"),
                         "bracketed": True}
                break
            out[f"{t:g}"][a] = found
    return out


def sweep(cfg, amplitudes_urad, records_s, runs=1, workers=2, on_progress=None) -> dict:
    """Fly the grid of dither amplitudes x record lengths and the legacy reference.

    Parameters
    ----------
    cfg : Scenario
        The vehicle; seeds ``cfg.mission.seed`` on; its dithered axes take
        each amplitude.
    amplitudes_urad, records_s : sequence of float
        [µrad] dither amplitudes and [s] record lengths of the grid.
    runs : int
        Seeds per grid point (and legacy missions).
    workers : int
        Worker processes (1: in this process).
    on_progress : callable, optional
        ``on_progress(done, total)`` after each mission.

    Returns
    -------
    dict
        ``legacy`` (RMS scale-factor error per axis [ppm], time [s], largest
        excursion [arcsec] and propellant [kg]), ``points`` (one per grid
        point: ``amplitude_urad``, ``record_s``, the RMS and mean errors with
        and without misalignment known, ``predicted_sigma_ppm``, ``time_s``,
        ``max_excursion_arcsec``, ``propellant_kg``), ``crossover``
        (:func:`crossover`), ``runs``, ``seeds`` and ``interrupted``: True
        when Ctrl-C stopped the grid, ``points`` then holding those whose
        every seed was flown (Ctrl-C during the reference raises
        KeyboardInterrupt).
    """
    from allsky.studies.montecarlo import ordered_rows

    data = cfg.as_dict()
    seeds = [int(cfg.mission.seed) + k for k in range(runs)]
    grid = [(float(a), float(t)) for t in records_s for a in amplitudes_urad]
    # Validate every point before flying any (a bad value names its key).
    point_cfgs = [scenario_from_dict(data, point_overrides(cfg, a, t)) for a, t in grid]
    total = runs * (1 + len(grid))

    def phase(fly, jobs, before):
        progress = None if on_progress is None else (
            lambda done, n: on_progress(before + done, total))
        return ordered_rows(fly, jobs, workers, progress)

    legacy_rows, interrupted = phase(fly_legacy, [(data, s) for s in seeds], 0)
    if interrupted:  # the reference needs every seed: stop, as before the first row
        raise KeyboardInterrupt
    words = {r["seed"]: r.get("cross_coupling") for r in legacy_rows}
    jobs = [(data, point_overrides(cfg, a, t), s, words[s]) for a, t in grid for s in seeds]
    dither_rows, interrupted = phase(fly_dither, jobs, runs)
    legacy = _summarise(legacy_rows)
    points = []
    finished = len(dither_rows) // runs  # Ctrl-C: the points whose every seed was flown
    for k, ((a, t), pc) in enumerate(zip(grid[:finished], point_cfgs)):
        rows = dither_rows[k * runs:(k + 1) * runs]
        points.append({"amplitude_urad": a, "record_s": t, **_summarise(rows),
                       "predicted_sigma_ppm": predicted(pc)["dither"], "rows": rows})
    ref = legacy.get("scale_factor_rms_error_ppm", {})
    return {"runs": runs, "seeds": [seeds[0], seeds[-1]], "interrupted": bool(interrupted),
            "legacy": {**legacy, "rows": legacy_rows}, "points": points,
            "crossover": crossover(points, ref) if ref else {},
            "crossover_own_register": (crossover(points, ref, "scale_factor_rms_error_ppm")
                                       if ref else {})}
