"""The information limit of the calibration: Fisher information, Cramer-Rao bound.

How well could *any* method calibrate drift, scale factors and
misalignments from the data the emulator's sensors give along a flown
trajectory? The sensors are the emulator's own models:

* gyros 1/2/3 through converters 8/10/12 into up/down counters 14/16/18:
  the counted angle ``y = S dtheta + b dt + ARW``, with drift ``b``
  walking with the rate random walk and the counter's readout error
  (one pulse weight / sqrt(12), white at the sample);
* sun sensor 104 (pitch and yaw, inside its linear range, Sun present)
  and star tracker 105 (yaw and pitch, locked) with white noise per frame.

The model is the three-axis filter's (:mod:`allsky.studies.kalman_mekf`):
15 error states, attitude (3), drift (3) and the inverse sensitivity's
deviation ``E`` (9: three scale factors, six misalignments), in which the
body increment ``(I + E)(y - b dt)`` is linear. Linearised along the
*true* trajectory, the model is linear and Gaussian; the covariance of the
Kalman filter of that linear model, started from a prior far weaker than
anything the data give, is the inverse of the Fisher information of the
final states (the posterior Cramer-Rao bound of Tichavsky, Muravchik and
Nehorai, IEEE Trans. Signal Processing 46(5), 1998, which for a linear
Gaussian model is exact). No estimator that reads the same data can have a
smaller error covariance, whatever it does (counting, Fourier analysis,
filtering, smoothing), except by knowing more beforehand.

The bound is evaluated per manoeuvre (:data:`MANOEUVRES`): Mode 3's hold,
Mode 4's roll turn, Mode 5's yaw turn, the dither hold, and the calibration
modes of each plan together, each from its own data alone. A state the
data do not show keeps (nearly) the weak prior: its bound is reported as
None (:data:`UNOBSERVABLE_FRACTION`).

:func:`bound` computes it for :class:`~allsky.studies.kalman_mekf.Samples`
(any data with the truth beside it); :func:`mission_bounds` for the legs
of a :class:`~allsky.studies.kalman_mekf.LegRecorder`. Equations and
checks: ``docs/comparison.md``, "The information limit".
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import units, xarrays
from allsky.jit import njit
from allsky.studies import kalman_mekf as km
from allsky.studies.kalman_mekf import E_INDEX

#: How much weaker than the filter's own prior the bound's prior is (in sigma). The
#: data's information dominates every observable state by orders of magnitude; the
#: test ``test_bound_does_not_depend_on_the_weak_prior`` checks that 10x more changes
#: no observable bound by 1 %.
PRIOR_WEAKENING = 10.0
#: A state whose bound is above this fraction of its (weak) prior sigma is reported as
#: not observable (None): the data did not show it.
UNOBSERVABLE_FRACTION = 0.3
#: The manoeuvres of the bound: name -> (plan, modes whose data it uses).
MANOEUVRES = {
    "mode3_hold": ("legacy", ("3",)),
    "mode4_roll_turn": ("legacy", ("4",)),
    "mode5_yaw_turn": ("legacy", ("5",)),
    "dither_hold": ("dither", ("dither",)),
    "modes3_5": ("legacy", ("3", "4", "5")),
    "mode3_and_dither": ("dither", ("3", "dither")),
}
#: The manoeuvres each method of ``allsky compare`` calibrates from.
METHOD_MANOEUVRE = {"legacy": "modes3_5", "dither": "mode3_and_dither",
                    "kalman": "modes3_5", "kalman_dither": "mode3_and_dither",
                    "smoother": "modes3_5"}


def weak_prior(weakening: float = PRIOR_WEAKENING) -> km.Prior:
    """The filter's prior with every sigma ``weakening`` times larger."""
    p = km.DEFAULT_PRIOR
    return km.Prior(*(weakening * v for v in p))


class Linearisation(NamedTuple):
    """The linear model along the true trajectory, one row per sample."""

    dt_s: np.ndarray  #: (n,) [s]
    u_rad: np.ndarray  #: (n, 3) counter increments less the true drift [rad]
    c: np.ndarray  #: (3, 3) ``I + E`` at the truth
    rot: np.ndarray  #: (n, 3, 3) true body rotation over the sample, ``exp(-[d x])``
    h: np.ndarray  #: (n, 4, 3) attitude rows of sun pitch, sun yaw, tracker yaw, pitch
    valid: np.ndarray  #: (n, 4) 1.0 where that output was measured


def dcm_many(q) -> np.ndarray:
    """Body-from-inertial matrices of the quaternions ``q`` (n, 4), row by row.

    :func:`allsky.vehicle.quaternion.dcm_body_from_inertial`, vectorised.
    """
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([w * w + x * x - y * y - z * z, 2 * (x * y + w * z), 2 * (x * z - w * y)], -1),
        np.stack([2 * (x * y - w * z), w * w - x * x + y * y - z * z, 2 * (y * z + w * x)], -1),
        np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z], -1),
    ], axis=1)


def atan2_rows(s, num, num_sign, den):
    """Rows ``J x s`` of ``atan2(num_sign s[num], s[den])`` for body vectors (n, 3).

    ``s`` holds the unit vectors (Sun or star) in body axes, one per row;
    ``num`` and ``den`` are the component indices of the angle's numerator
    and denominator and ``num_sign`` (+1 or -1) the numerator's sign. ``J``
    is the angle's gradient with respect to ``s``: the row ``J x s`` gives
    the output's change [rad] for a small body rotation [rad].
    """
    u = num_sign * s[:, num]
    v = s[:, den]
    d2 = u * u + v * v
    j = np.zeros_like(s)
    j[:, num] += num_sign * v / d2
    j[:, den] += -u / d2
    return np.cross(j, s)


def linearise(model: km.FilterModel, samples: km.Samples, params_true) -> Linearisation:
    """The linear model of the samples along the truth.

    ``samples`` are the recorded samples
    (:class:`~allsky.studies.kalman_mekf.Samples`), their true attitude
    ``samples.truth_q`` the truth with ``params_true``; ``model`` is the
    filter's (its noises and the stars of the tracker's window).

    ``params_true`` (12) is :func:`~allsky.studies.kalman_mekf.true_parameters`:
    drift [rad/s] and ``E``. The attitude rows of every optical output are
    those of the filter's measurement models at the true attitude; the
    tracker's star is the catalog star of the window whose outputs at the
    true attitude are nearest the measured ones.
    """
    q = np.asarray(samples.truth_q, dtype=float)
    if np.isnan(q).any():
        raise ValueError("the bound needs the true attitude at every sample")
    p = np.asarray(params_true, dtype=float)
    e = np.zeros((3, 3))
    for a in range(3):
        for j in range(3):
            e[a, j] = p[km.E_INDEX[a, j] - 3]
    c = np.eye(3) + e
    dt = np.asarray(samples.dt_s, dtype=float)
    u = np.asarray(samples.gyro_rad, dtype=float) - np.outer(dt, p[0:3])
    d = xarrays.matvec_rows(c, u)  # (I + E) u, row by row
    ang = xarrays.norm_rows(d)
    axis = np.where(ang[:, None] > 1e-15, d / np.where(ang > 1e-15, ang, 1.0)[:, None], 0.0)
    cos, sin = xarrays.cos_many(ang), xarrays.sin_many(ang)
    ax = np.zeros((d.shape[0], 3, 3))  # [a x]
    ax[:, 0, 1], ax[:, 0, 2], ax[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    ax[:, 1, 0], ax[:, 2, 0], ax[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    rot = (cos[:, None, None] * np.eye(3) + (1 - cos)[:, None, None]
           * axis[:, :, None] * axis[:, None, :] - sin[:, None, None] * ax)
    a_body = dcm_many(q)
    # The Sun as the loop has it (sim.frame_loop.sun_inertial): linear in time, renormalised.
    sun_i = model.sun0_inertial + np.outer(samples.time_s, model.sun_rate_inertial)
    sun_i /= xarrays.norm_rows(sun_i)[:, None]
    s_sun = xarrays.matvec_rows(a_body, sun_i)
    h = np.zeros((q.shape[0], 4, 3))
    valid = np.zeros((q.shape[0], 4))
    sun_ok = (samples.sun[:, km.VALID] > 0.5) & (s_sun[:, 0] > 0.0)
    h[:, 0] = atan2_rows(s_sun, 2, -1.0, 0)  # pitch = atan2(-s_z, s_x)
    h[:, 1] = atan2_rows(s_sun, 1, 1.0, 0)  # yaw = atan2(s_y, s_x)
    valid[:, 0] = valid[:, 1] = sun_ok
    trk_ok = samples.tracker[:, km.VALID] > 0.5
    stars = np.asarray(model.stars_inertial, dtype=float)
    s_all = xarrays.matvec_rows(a_body[:, None], stars[None])  # (n, stars, 3)
    ey = xarrays.atan2_many(-s_all[..., 1], s_all[..., 2]) - samples.tracker[:, None, 0]
    ep = xarrays.atan2_many(s_all[..., 0], s_all[..., 2]) - samples.tracker[:, None, 1]
    miss = np.where(s_all[..., 2] > 0.0, ey * ey + ep * ep, np.inf)
    star = np.argmin(miss, axis=1)
    s_trk = s_all[np.arange(q.shape[0]), star]
    trk_ok &= np.isfinite(miss[np.arange(q.shape[0]), star])
    h[:, 2] = atan2_rows(s_trk, 1, -1.0, 2)  # yaw = atan2(-s_y, s_z)
    h[:, 3] = atan2_rows(s_trk, 0, 1.0, 2)  # pitch = atan2(s_x, s_z)
    valid[:, 2] = valid[:, 3] = trk_ok
    h[valid == 0.0] = 0.0
    return Linearisation(dt, u, c, rot, h, valid)


@njit
def _riccati(dt_s, u, c, rot, h, valid, rvar, arw2, rrw2, P, tmat, ph):
    """The Kalman filter's covariance recursion of the linear model, ``P`` in place.

    The propagation is the filter's (:func:`allsky.studies.kalman_mekf.run_filter`)
    with the true rotation, ``I + E`` and increments; each valid output a
    scalar update of variance ``rvar`` (no gate, no second-order term: the
    model is linear).
    """
    n = dt_s.shape[0]
    ns = P.shape[0]
    for k in range(n):
        dt = dt_s[k]
        for a in range(3):
            e_a = E_INDEX[a]
            for col in range(ns):
                acc = rot[k, a, 0] * P[0, col] + rot[k, a, 1] * P[1, col] \
                    + rot[k, a, 2] * P[2, col]
                acc -= dt * (c[a, 0] * P[3, col] + c[a, 1] * P[4, col] + c[a, 2] * P[5, col])
                acc += u[k, 0] * P[e_a[0], col] + u[k, 1] * P[e_a[1], col] \
                    + u[k, 2] * P[e_a[2], col]
                tmat[a, col] = acc
        for a in range(3):
            for b in range(a, 3):
                e_b = E_INDEX[b]
                v = tmat[a, 0] * rot[k, b, 0] + tmat[a, 1] * rot[k, b, 1] \
                    + tmat[a, 2] * rot[k, b, 2]
                v -= dt * (tmat[a, 3] * c[b, 0] + tmat[a, 4] * c[b, 1] + tmat[a, 5] * c[b, 2])
                v += u[k, 0] * tmat[a, e_b[0]] + u[k, 1] * tmat[a, e_b[1]] \
                    + u[k, 2] * tmat[a, e_b[2]]
                if a == b:
                    v += arw2 * dt
                P[a, b] = v
                P[b, a] = v
            for col in range(3, ns):
                P[a, col] = tmat[a, col]
                P[col, a] = tmat[a, col]
        for i in range(3):
            P[3 + i, 3 + i] += rrw2 * dt
        for m in range(4):
            if valid[k, m] < 0.5:
                continue
            h0, h1, h2 = h[k, m, 0], h[k, m, 1], h[k, m, 2]
            for i in range(ns):
                ph[i] = P[i, 0] * h0 + P[i, 1] * h1 + P[i, 2] * h2
            s = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + rvar[m]
            for i in range(ns):
                ki = ph[i] / s
                for j in range(ns):
                    P[i, j] -= ki * ph[j]
            # Keep it symmetric to the last bit.
            for i in range(ns):
                for j in range(i + 1, ns):
                    v = 0.5 * (P[i, j] + P[j, i])
                    P[i, j] = v
                    P[j, i] = v


def measurement_variances(model: km.FilterModel) -> np.ndarray:
    """[rad^2] Variance of sun pitch, sun yaw, tracker yaw, tracker pitch per sample.

    From ``model``, the filter's :class:`~allsky.studies.kalman_mekf.FilterModel`.

    The optics' white noise and the counters' readout error (the attitude
    the counters carry is off by it at every sample: ``docs/kalman.md``,
    "Rate-integrating gyro with readout noise").
    """
    sun = model.sun_noise_rad ** 2 + model.readout_rad ** 2
    trk = model.tracker_noise_rad ** 2 + model.readout_rad ** 2
    return np.array([sun, sun, trk, trk])


def bound_covariance(model: km.FilterModel, lin: Linearisation,
                     prior: km.Prior | None = None) -> np.ndarray:
    """The Cramer-Rao bound (15 x 15) of the error states at the last sample.

    ``model`` gives the noises, ``lin`` (:func:`linearise`) the linear model
    along the truth, and ``prior`` is the (weak) prior the recursion starts
    from; None: :func:`weak_prior`.
    """
    P = km.prior_covariance(weak_prior() if prior is None else prior)
    _riccati(lin.dt_s, np.ascontiguousarray(lin.u_rad), np.ascontiguousarray(lin.c),
             np.ascontiguousarray(lin.rot), np.ascontiguousarray(lin.h),
             np.ascontiguousarray(lin.valid), measurement_variances(model),
             model.arw_rad_rt_s ** 2, model.rrw_rad_s_rt_s ** 2, P, np.empty((3, km.N_STATE)),
             np.empty(km.N_STATE))
    return P


def bound(model: km.FilterModel, samples: km.Samples, params_true,
          prior: km.Prior | None = None) -> dict:
    """The Cramer-Rao bound of the calibration's quantities from ``samples``.

    ``model`` is the filter's (its noises), ``params_true`` the 12 true
    parameters (:func:`truth_of`) the model is linearised about and ``prior``
    the weak prior the recursion starts from (None: :func:`weak_prior`). A
    bound above :data:`UNOBSERVABLE_FRACTION` of the weak prior's own sigma is
    reported as None: the data do not show that quantity.

    Returns
    -------
    dict
        The keys of :func:`allsky.studies.kalman_mekf.sigmas` (drift [deg/h],
        register 23's scale factors [ppm] and cross-coupling factors
        [arcsec], each gyro's scale factor [ppm] and misalignment [arcsec]),
        each 1-sigma bound, None where the data do not show the quantity;
        ``samples`` (how many), ``duration_s``.
    """
    weak = weak_prior() if prior is None else prior
    cov = bound_covariance(model, linearise(model, samples, params_true), weak)
    out = km.sigmas(params_true, cov)
    # The weak prior's own sigmas in the same terms: what "nothing learnt" looks like.
    ref = km.sigmas(params_true, km.prior_covariance(weak))
    for group, values in out.items():
        for k, v in values.items():
            if v > UNOBSERVABLE_FRACTION * ref[group][k]:
                values[k] = None
    out["samples"] = int(samples.time_s.size)
    out["duration_s"] = float(samples.time_s[-1] - samples.time_s[0] + samples.dt_s[0])
    return out


def truth_of(m, samples: km.Samples) -> np.ndarray:
    """The true parameter vector (12): constant gyro and integrator drift, and E.

    Read from mission ``m``'s parameters, constant over the flight, so the
    same for every stretch of ``samples`` it recorded (``samples`` is not
    read). The drift's random walk is left out of the linearisation point:
    over a sample it moves the increments by far less than their noise.
    """
    drift = (np.asarray(m.params.gyro.drift_arcsec_s, dtype=float)
             + np.asarray(m.params.vfc.integrator_drift_arcsec_s, dtype=float))
    return km.true_parameters(m, drift * units.ARCSEC2RAD)


def mission_bounds(m, legs_flown, manoeuvres, prior: km.Prior | None = None) -> dict:
    """:func:`bound` for each manoeuvre ``name -> modes`` the mission recorded.

    ``legs_flown`` are the legs a :class:`~allsky.studies.kalman_mekf.LegRecorder`
    kept of mission ``m``'s flight, ``manoeuvres`` maps each manoeuvre's name
    to its modes, and ``prior`` is passed to :func:`bound`. A manoeuvre whose
    modes were not flown (an aborted mission) is left out.
    """
    model = km.filter_model(m)
    out = {}
    for name, modes in manoeuvres.items():
        if not any(leg.mode in modes for leg in legs_flown):
            continue
        s = km.samples_from_legs(m, legs_flown, modes)
        out[name] = bound(model, s, truth_of(m, s), prior)
    return out


def recording_config(cfg):
    """``cfg`` recording every frame: the bound reads every sample the sensors gave.

    Telemetry does not change the flight (only what is kept of it).
    """
    from allsky.config import scenario_from_dict

    if int(cfg.mission.telemetry_every_frames) == 1:
        return cfg
    return scenario_from_dict(cfg.as_dict(), ["mission.telemetry_every_frames=1"])


def fly_recording(cfg, plan_name, modes):
    """Fly ``plan_name`` through its calibration, recording every frame of ``modes``.

    ``cfg`` is the scenario; ``plan_name`` "legacy" or "dither".

    Returns the :class:`~allsky.studies.kalman_mekf.Recorded` mission and
    legs, stopped after the plan's calibration modes (Mode 6 not flown).
    """
    from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN
    from allsky.sim.results import fly_calibrating

    plan = LEGACY_PLAN if plan_name == "legacy" else DITHER_PLAN
    recorded = km.recording(recording_config(cfg), plan=plan, modes=modes)
    fly_calibrating(recorded.mission, km.CALIBRATION_MODES[plan_name], on_end=lambda mm: False,
                    hooks=recorded.recorder.hooks)
    return recorded


def flown_bounds(cfg, manoeuvres=None) -> dict:
    """The bound of every manoeuvre of :data:`MANOEUVRES` (or ``manoeuvres``).

    Flies scenario ``cfg`` once per plan needed, recording every frame of
    the modes its manoeuvres use, and evaluates each manoeuvre on its own
    data. ``manoeuvres`` names keys of :data:`MANOEUVRES`.
    """
    wanted = MANOEUVRES if manoeuvres is None else {k: MANOEUVRES[k] for k in manoeuvres}
    out = {}
    for plan_name in ("legacy", "dither"):
        mine = {k: modes for k, (plan, modes) in wanted.items() if plan == plan_name}
        if not mine:
            continue
        modes = tuple(sorted({mode for ms in mine.values() for mode in ms}))
        m, rec = fly_recording(cfg, plan_name, modes)
        out.update(mission_bounds(m, rec.legs_flown, mine))
    return {k: out[k] for k in wanted if k in out}


def information_ratio(a: dict, b: dict, group="scale_factor_ppm", key="roll") -> float | None:
    """The information of manoeuvre ``a`` over that of ``b``, on one quantity.

    ``a`` and ``b`` are bounds (:func:`bound`); the quantity is ``key``
    (``"roll"``) of ``group`` (``"scale_factor_ppm"``). The ratio of the
    variances' inverses, ``(sigma_b / sigma_a)^2``; None if either does not
    show it.
    """
    sa, sb = a[group][key], b[group][key]
    if sa is None or sb is None:
        return None
    return (sb / sa) ** 2


def rms_bounds(bounds: list) -> dict | None:
    """The RMS over runs of per-run bounds.

    ``bounds`` are the runs' :func:`bound` dicts; the result has the same
    groups and keys, None where any run has None (None for no runs).
    """
    if not bounds:
        return None
    out = {}
    for group, values in bounds[0].items():
        if not isinstance(values, dict):
            continue
        out[group] = {}
        for k in values:
            have = [b[group][k] for b in bounds]
            out[group][k] = (None if any(v is None for v in have)
                             else float(math.sqrt(np.mean(np.square(have)))))
    return out
