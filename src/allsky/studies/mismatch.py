"""Robustness to what the engineer got wrong: the filter with a wrong model.

The three-axis filter (:mod:`allsky.studies.kalman_mekf`) is designed with
a data sheet (the gyro's angle and rate random walks, the optics' noise),
the sensors' mounting and the star catalog. Each can be wrong:

* **noise data sheet** x0.5 ... x2: every noise the filter assumes scaled
  by ``k`` (the truth unchanged), or the gyro's and the optics' apart;
* **star tracker 105 misaligned** by an angle the filter does not know
  (about body x, which the tracker's yaw output sees as roll, or about its
  boresight, body z);
* **sun sensor 104 biased** by a constant on both outputs;
* **catalog error**: the tracked star's direction in the filter's catalog
  off by an angle.

A misaligned or biased sensor and a catalog error are applied to what the
filter reads and assumes, not to the flight: the flown sensor is the
reference the mission holds on, and the filter is told a slightly wrong
story about it. This is the same to the filter as a sensor that really
sits that far from where its data sheet puts it.

Only the filter depends on these. The legacy turns count the angle between
two optical nulls of the same sensor, which a fixed offset does not move;
the dither takes amplitudes at its frequency, which a constant does not
reach. Neither reads a noise figure. (A real misalignment of the optical
reference moves every method's final pointing alike, through Mode 6's
open-loop targeting from that reference; that is not calibration.)

:func:`study` flies each seed's legacy plan once through Mode 5, runs the
filter on the same samples under every case of :data:`CASES`, loads each
estimate and flies Mode 6 from the same state: the errors, the filter's own
sigmas beside them, and the final pointing.
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import units
from allsky.studies import kalman_mekf as km
from allsky.studies.kalman_mekf import load as load_calibration


class Case(NamedTuple):
    """One wrong model: what the filter assumes or reads."""

    name: str  #: the case in words, its key in the results (``catalog 20"``)
    group: str  #: noise, tracker, sun, catalog
    value: float  #: the group's figure: a scale, an angle [arcsec]
    gyro_noise_scale: float = 1.0  #: ARW and RRW the filter assumes, x
    optics_noise_scale: float = 1.0  #: sun and tracker noise the filter assumes, x
    tracker_rotation_arcsec: tuple = (0.0, 0.0, 0.0)  #: tracker frame off body (x, y, z)
    sun_bias_arcsec: float = 0.0  #: added to both sun sensor outputs
    #: [arcsec] every catalog star of the window displaced by this angle, across itself
    catalog_error_arcsec: float = 0.0


def _cases():
    out = []
    for k in (0.5, 0.71, 1.0, 1.41, 2.0):
        out.append(Case(f"noise x{k:g}", "noise", k, k, k))
    for k in (0.5, 2.0):
        out.append(Case(f"gyro noise x{k:g}", "gyro noise", k, gyro_noise_scale=k))
        out.append(Case(f"optics noise x{k:g}", "optics noise", k, optics_noise_scale=k))
    for a in (10.0, 30.0, 100.0):
        out.append(Case(f"tracker about x {a:g}\"", "tracker about x", a,
                        tracker_rotation_arcsec=(a, 0.0, 0.0)))
        out.append(Case(f"tracker about z {a:g}\"", "tracker about z", a,
                        tracker_rotation_arcsec=(0.0, 0.0, a)))
    for b in (5.0, 20.0, 60.0):
        out.append(Case(f"sun bias {b:g}\"", "sun bias", b, sun_bias_arcsec=b))
    for c in (5.0, 20.0, 60.0):
        out.append(Case(f"catalog {c:g}\"", "catalog", c, catalog_error_arcsec=c))
    return tuple(out)


#: The wrong models of :func:`study`; the first with ``value`` 1 of "noise" is the truth.
CASES = _cases()


def _rotation(v_arcsec):
    """``exp(-[v x])`` for a small rotation vector [arcsec] (exact)."""
    v = np.asarray(v_arcsec, dtype=float) * units.ARCSEC2RAD
    a = np.linalg.norm(v)
    if a == 0.0:
        return np.eye(3)
    k = v / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) - math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


def wrong_model(model: km.FilterModel, case: Case) -> km.FilterModel:
    """The filter's :class:`~allsky.studies.kalman_mekf.FilterModel` under ``case``.

    ``model`` is the filter's right model
    (:func:`~allsky.studies.kalman_mekf.filter_model`).
    """
    stars = np.array(model.stars_inertial, dtype=float)
    if case.catalog_error_arcsec:
        # Every star of the window displaced by the angle, about an axis across it.
        for i, s in enumerate(stars):
            across = np.cross(s, [0.0, 0.0, 1.0] if abs(s[2]) < 0.9 else [1.0, 0.0, 0.0])
            across /= np.linalg.norm(across)
            stars[i] = _rotation(case.catalog_error_arcsec * across).T @ s
    return model._replace(
        arw_rad_rt_s=model.arw_rad_rt_s * case.gyro_noise_scale,
        rrw_rad_s_rt_s=model.rrw_rad_s_rt_s * case.gyro_noise_scale,
        sun_noise_rad=model.sun_noise_rad * case.optics_noise_scale,
        tracker_noise_rad=model.tracker_noise_rad * case.optics_noise_scale,
        readout_rad=model.readout_rad * case.optics_noise_scale,
        stars_inertial=stars)


def wrong_samples(samples: km.Samples, case: Case) -> km.Samples:
    """The samples as the filter reads them under ``case``.

    ``samples`` are the flight's
    (:class:`~allsky.studies.kalman_mekf.Samples`), left as they are. The
    tracker's outputs turned by its misalignment, the sun sensor's biased.
    """
    sun, trk = samples.sun.copy(), samples.tracker.copy()
    if any(case.tracker_rotation_arcsec):
        r = _rotation(case.tracker_rotation_arcsec)
        ok = trk[:, km.VALID] > 0.5
        # The star in the tracker frame from its outputs (yaw = atan2(-s_y, s_z), pitch =
        # atan2(s_x, s_z)), seen from a frame turned by r, and back to outputs.
        v = np.column_stack((np.tan(trk[:, 1]), -np.tan(trk[:, 0]), np.ones(len(trk))))
        v = v @ r.T
        trk[ok, 0] = np.arctan2(-v[ok, 1], v[ok, 2])
        trk[ok, 1] = np.arctan2(v[ok, 0], v[ok, 2])
    if case.sun_bias_arcsec:
        ok = sun[:, km.VALID] > 0.5
        sun[ok, 0:2] += case.sun_bias_arcsec * units.ARCSEC2RAD
    return samples._replace(sun=sun, tracker=trk)


def _pointing(history, arrays, params=None):
    """Mode 6 flown from the end of the calibration with ``params`` loaded.

    None: with what the calibration stored.
    """
    from allsky.sim.mission import Mission

    m = Mission.from_snapshot(history, arrays, telemetry=False)
    if params is not None:
        load_calibration(m, params, by="the mismatch study")
    m.run()
    return m.summary()["target"]["pointing_error_arcsec"] if m.status == "complete" else None


def run_seed(job) -> dict | None:
    """One seed, ``(scenario_dict, seed, cases)``: per case errors, sigmas, pointing.

    ``job`` is that tuple (``cases`` the :class:`Case` entries). None when the
    seed's mission aborted before the end of its calibration.
    ``legacy_pointing_arcsec``: Mode 6 with the legacy turns' own calibration,
    which no case changes.
    """
    from allsky.config import scenario_from_dict
    from allsky.sim.results import fly_calibrating

    data, seed, cases = job
    cfg = scenario_from_dict(data, [f"mission.seed={seed}"])
    m, rec = km.recording(cfg, modes=km.FILTER_MODES["legacy"])
    snaps = []
    fly_calibrating(m, km.CALIBRATION_MODES["legacy"],
                    on_end=lambda mm: snaps.append(mm.snapshot()) or False, hooks=rec.hooks)
    if m.finished or not snaps:
        return None
    samples = km.samples_from_legs(m, rec.legs_flown, km.FILTER_MODES["legacy"])
    model = km.filter_model(m)
    truth = m.summary()["truth"]
    out = {"legacy_pointing_arcsec": _pointing(*snaps[0])}
    for case in cases:
        est = km.estimate(wrong_model(model, case), wrong_samples(samples, case))
        p = est.params[-1]
        cal = km.calibration(p)
        sig = km.sigmas(p, est.covariances[-1])
        err = {"scale_factor_ppm": {a: units.FRACTION2PPM * (cal["scale_factor"][a]
                                                            - truth["scale_factor"][a])
                                    for a in ("roll", "yaw")},
               "cross_coupling_arcsec": {k: units.RAD2ARCSEC * (cal["cross_coupling"][k]
                                                                - truth["cross_coupling"][k])
                                         for k in cal["cross_coupling"]},
               "drift_deg_h": {a: cal["drift_deg_h"][a] - truth["drift_deg_h"][a]
                               for a in cal["drift_deg_h"]}}
        e = km.errors_at(m, est, int(est.checkpoints[-1]))
        nees = float(e @ np.linalg.solve(est.covariances[-1], e))
        out[case.name] = {"error": err, "sigma": {k: sig[k] for k in err},
                          "nees": nees, "pointing_arcsec": _pointing(*snaps[0], p)}
    return out


class Study(NamedTuple):
    """The filter under every wrong model, over seeds."""

    cases: tuple  #: the :class:`Case` list
    runs: int  #: seeds that completed the calibration
    rms: dict  #: case -> group -> key -> RMS error over the seeds
    sigma: dict  #: case -> group -> key -> RMS of the filter's own sigma
    nees: dict  #: case -> mean NEES (15 states) at the end of Mode 5
    pointing: dict  #: case -> {"mean", "rms"} final pointing [arcsec]
    legacy_pointing: dict  #: {"mean", "rms"} the legacy turns' own, the same seeds [arcsec]


def study(cfg, runs=20, workers=1, cases=CASES) -> Study:
    """:func:`run_seed` over ``runs`` seeds from ``cfg.mission.seed``, pooled.

    ``cfg`` is the scenario, ``cases`` the :class:`Case` entries flown and
    ``workers`` the processes that fly the seeds (1: this one).
    """
    data = cfg.as_dict()
    jobs = [(data, int(cfg.mission.seed) + k, cases) for k in range(runs)]
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(run_seed, jobs))
    else:
        rows = [run_seed(j) for j in jobs]
    rows = [r for r in rows if r is not None]
    rms, sigma, nees, pointing = {}, {}, {}, {}
    for case in cases:
        rs = [r[case.name] for r in rows]
        rms[case.name] = {g: {k: float(np.sqrt(np.mean([x["error"][g][k] ** 2 for x in rs])))
                              for k in rs[0]["error"][g]} for g in rs[0]["error"]}
        sigma[case.name] = {g: {k: float(np.sqrt(np.mean([x["sigma"][g][k] ** 2 for x in rs])))
                                for k in rs[0]["sigma"][g]} for g in rs[0]["sigma"]}
        nees[case.name] = float(np.mean([x["nees"] for x in rs]))
        pts = [x["pointing_arcsec"] for x in rs if x["pointing_arcsec"] is not None]
        pointing[case.name] = {"mean": float(np.mean(pts)),
                               "rms": float(np.sqrt(np.mean(np.square(pts))))}
    legacy = [r["legacy_pointing_arcsec"] for r in rows if r["legacy_pointing_arcsec"]]
    return Study(tuple(cases), len(rows), rms, sigma, nees, pointing,
                 {"mean": float(np.mean(legacy)), "rms": float(np.sqrt(np.mean(np.square(legacy))))})


def study_dict(s: Study) -> dict:
    """Study ``s`` (:class:`Study`) as JSON-ready data."""
    return {"runs": s.runs, "cases": [c._asdict() for c in s.cases], "rms": s.rms,
            "sigma": s.sigma, "nees": s.nees, "pointing_arcsec": s.pointing,
            "legacy_pointing_arcsec": s.legacy_pointing}
