"""A fixed-interval smoother over the calibration modes: the offline reference.

Calibration is post-processed in practice: the whole record of Modes 3-5
is on the ground before anyone needs the answer. The best use of it is a
fixed-interval smoother, which estimates every sample's state from all the
data, before and after. This is the iterated extended Rauch-Tung-Striebel
smoother (Bell, "The iterated Kalman smoother as a Gauss-Newton method",
SIAM J. Optimization 4(3), 1994) on the three-axis filter's model
(:mod:`allsky.studies.kalman_mekf`: attitude, drift and the inverse
sensitivity ``I + E``, 15 error states):

1. the filter runs forward; its trajectory (attitude and parameters at
   every sample) is the first *nominal*;
2. forward: a linear Kalman filter of the error from the nominal, the
   model linearised *at the nominal* (the propagation's rotation, ``I + E``
   and increments; the optics' predictions and gradients), the nominal's
   own mismatch between one sample and the next entering as a known input;
3. backward (Rauch, Tung and Striebel, AIAA J. 3(8), 1965): each sample's
   error from all the data, ``x_k^s = x_k^+ + P_k^+ Phi^T (P_{k+1}^-)^-1
   (x_{k+1}^s - x_{k+1}^-)``;
4. the nominal moves by the smoothed error; 2-4 repeat until it stops
   moving (Gauss-Newton on the whole record's likelihood).

The filter's estimate at the end of Mode 5 was made from a trajectory it
linearised as it went: mid-turn its yaw was uncertain by degrees, and the
models it used then were evaluated there. The smoother re-evaluates every
sample at the best trajectory of the whole record. It reads every frame
(:func:`fly` records them) and reaches the information limit
(:mod:`allsky.studies.crlb`; ``docs/comparison.md``).
"""

import math
import time
from typing import NamedTuple

import numpy as np

from allsky import units
from allsky.jit import njit
from allsky.sim.mission import Mission
from allsky.studies import crlb
from allsky.studies import kalman_mekf as km
from allsky.studies.kalman_mekf import E_INDEX, N_STATE, rotation_error
from allsky.studies.kalman_mekf import load as load_calibration

#: Gauss-Newton passes at most; and when the nominal has stopped moving [sigma].
MAX_ITERATIONS = 6
CONVERGED_SIGMA = 1e-3


class Smoothed(NamedTuple):
    """The smoother's answer over one record."""

    samples: km.Samples  #: the samples from the filter's first (its initial attitude) on
    q: np.ndarray  #: (n, 4) smoothed attitude at every sample
    params: np.ndarray  #: (n, 12) smoothed drift [rad/s] and ``E`` at every sample
    covariance: np.ndarray  #: (15, 15) error covariance at the last sample
    iterations: int  #: Gauss-Newton passes made
    filter: km.Estimate  #: the forward filter it started from


# ----------------------------------------------------------------- vectorised quaternions


def qmul(p, q):
    """Row-wise quaternion product ``p (x) q`` (the filter's ``_compose`` convention).

    ``p`` and ``q`` are (n, 4) arrays of ``[w, x, y, z]`` rows.
    """
    w, x, y, z = p[:, 0], p[:, 1], p[:, 2], p[:, 3]
    dw, dx, dy, dz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.column_stack((w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
                            w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw))


def rotation_quaternion(v):
    """Row-wise quaternions of the rotation vectors ``v`` (n, 3).

    ``[cos(|v|/2), sin(|v|/2) v/|v|]``.
    """
    n = np.linalg.norm(v, axis=1)
    k = np.where(n > 1e-15, np.sin(0.5 * n) / np.where(n > 1e-15, n, 1.0), 0.5)
    return np.column_stack((np.cos(0.5 * n), v * k[:, None]))


def _outputs(model, q, time_s, tracker):
    """Predicted optics [rad] and their attitude rows at attitudes ``q`` (n, 4).

    Sun pitch, sun yaw, tracker yaw, tracker pitch (the filter's models), the
    tracker's star chosen as the filter chooses it.
    """
    a = crlb.dcm_many(q)
    sun_i = model.sun0_inertial + np.outer(time_s, model.sun_rate_inertial)
    sun_i /= np.linalg.norm(sun_i, axis=1)[:, None]
    s_sun = np.einsum("nij,nj->ni", a, sun_i)
    stars = np.asarray(model.stars_inertial, dtype=float)
    s_all = np.einsum("nij,mj->nmi", a, stars)
    with np.errstate(divide="ignore", invalid="ignore"):
        ey = np.arctan2(-s_all[..., 1], s_all[..., 2]) - tracker[:, None, 0]
        ep = np.arctan2(s_all[..., 0], s_all[..., 2]) - tracker[:, None, 1]
    miss = np.where(s_all[..., 2] > 0.0, ey * ey + ep * ep, np.inf)
    rows = np.arange(q.shape[0])
    star = np.argmin(miss, axis=1)
    s_trk = s_all[rows, star]
    z = np.column_stack((np.arctan2(-s_sun[:, 2], s_sun[:, 0]), np.arctan2(s_sun[:, 1], s_sun[:, 0]),
                         np.arctan2(-s_trk[:, 1], s_trk[:, 2]),
                         np.arctan2(s_trk[:, 0], s_trk[:, 2])))
    h = np.stack([crlb.atan2_rows(s_sun, 2, -1.0, 0), crlb.atan2_rows(s_sun, 1, 1.0, 0),
                  crlb.atan2_rows(s_trk, 1, -1.0, 2), crlb.atan2_rows(s_trk, 0, 1.0, 2)],
                 axis=1)
    ok = np.column_stack((s_sun[:, 0] > 0.0, s_sun[:, 0] > 0.0,
                          np.isfinite(miss[rows, star]), np.isfinite(miss[rows, star])))
    return z, h, ok


def _sensitivity_rows(p):
    """``I + E`` of parameter vectors (n, 12) -> (n, 3, 3)."""
    c = np.empty((p.shape[0], 3, 3))
    for a in range(3):
        for j in range(3):
            c[:, a, j] = p[:, E_INDEX[a, j] - 3] + (1.0 if a == j else 0.0)
    return c


def _rotations(d):
    """``exp(-[d x])`` of rotation vectors (n, 3), the filter's step rotation."""
    ang = np.linalg.norm(d, axis=1)
    axis = np.where(ang[:, None] > 1e-12, d / np.where(ang > 1e-12, ang, 1.0)[:, None], 0.0)
    cos, sin = np.cos(ang), np.sin(ang)
    ax = np.zeros((d.shape[0], 3, 3))
    ax[:, 0, 1], ax[:, 0, 2], ax[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    ax[:, 1, 0], ax[:, 2, 0], ax[:, 2, 1] = axis[:, 2], -axis[:, 1], axis[:, 0]
    return (cos[:, None, None] * np.eye(3) + (1 - cos)[:, None, None]
            * axis[:, :, None] * axis[:, None, :] - sin[:, None, None] * ax)


# ----------------------------------------------------------------- the two passes


@njit
def _propagate(P, rot, c, u, dt, arw2, rrw2, tmat):
    """``P <- Phi P Phi^T + Q`` for one sample (the filter's sparse attitude rows)."""
    for a in range(3):
        e_a = E_INDEX[a]
        for col in range(N_STATE):
            acc = rot[a, 0] * P[0, col] + rot[a, 1] * P[1, col] + rot[a, 2] * P[2, col]
            acc -= dt * (c[a, 0] * P[3, col] + c[a, 1] * P[4, col] + c[a, 2] * P[5, col])
            acc += u[0] * P[e_a[0], col] + u[1] * P[e_a[1], col] + u[2] * P[e_a[2], col]
            tmat[a, col] = acc
    for a in range(3):
        for b in range(a, 3):
            e_b = E_INDEX[b]
            v = tmat[a, 0] * rot[b, 0] + tmat[a, 1] * rot[b, 1] + tmat[a, 2] * rot[b, 2]
            v -= dt * (tmat[a, 3] * c[b, 0] + tmat[a, 4] * c[b, 1] + tmat[a, 5] * c[b, 2])
            v += u[0] * tmat[a, e_b[0]] + u[1] * tmat[a, e_b[1]] + u[2] * tmat[a, e_b[2]]
            if a == b:
                v += arw2 * dt
            P[a, b] = v
            P[b, a] = v
        for col in range(3, N_STATE):
            P[a, col] = tmat[a, col]
            P[col, a] = tmat[a, col]
    for i in range(3):
        P[3 + i, 3 + i] += rrw2 * dt


@njit
def _phi_times(x, rot, c, u, dt, out):
    """``out = Phi x`` (15)."""
    for i in range(3, N_STATE):
        out[i] = x[i]
    for a in range(3):
        e_a = E_INDEX[a]
        out[a] = (rot[a, 0] * x[0] + rot[a, 1] * x[1] + rot[a, 2] * x[2]
                  - dt * (c[a, 0] * x[3] + c[a, 1] * x[4] + c[a, 2] * x[5])
                  + u[0] * x[e_a[0]] + u[1] * x[e_a[1]] + u[2] * x[e_a[2]])


@njit
def _forward(dt, u, c, rot, off, zres, h, valid, rvar, arw2, rrw2, gate2, x0, P0,
             xm, xp, Pp, tmat, ph, tmp):
    """The linear filter of the error from the nominal; keeps ``x^-``, ``x^+``, ``P^+``."""
    n = dt.shape[0]
    for i in range(N_STATE):
        xp[0, i] = x0[i]
        xm[0, i] = x0[i]
        for j in range(N_STATE):
            Pp[0, i, j] = P0[i, j]
    for k in range(1, n):
        for i in range(N_STATE):
            for j in range(N_STATE):
                Pp[k, i, j] = Pp[k - 1, i, j]
        P = Pp[k]
        _propagate(P, rot[k], c[k], u[k], dt[k], arw2, rrw2, tmat)
        _phi_times(xp[k - 1], rot[k], c[k], u[k], dt[k], tmp)
        for i in range(N_STATE):
            xm[k, i] = tmp[i] + off[k, i]
            xp[k, i] = xm[k, i]
        for m in range(4):
            if valid[k, m] < 0.5:
                continue
            h0, h1, h2 = h[k, m, 0], h[k, m, 1], h[k, m, 2]
            nu = zres[k, m] - (h0 * xp[k, 0] + h1 * xp[k, 1] + h2 * xp[k, 2])
            for i in range(N_STATE):
                ph[i] = P[i, 0] * h0 + P[i, 1] * h1 + P[i, 2] * h2
            s = h0 * ph[0] + h1 * ph[1] + h2 * ph[2] + rvar[m]
            if nu * nu > gate2 * s:
                continue
            g = nu / s
            for i in range(N_STATE):
                xp[k, i] += ph[i] * g
            for i in range(N_STATE):
                ki = ph[i] / s
                for j in range(N_STATE):
                    P[i, j] -= ki * ph[j]
            for i in range(N_STATE):
                for j in range(i + 1, N_STATE):
                    v = 0.5 * (P[i, j] + P[j, i])
                    P[i, j] = v
                    P[j, i] = v


@njit
def _cholesky_solve(A, b, L, out):
    """``out = A^-1 b`` for a symmetric positive definite ``A`` (Cholesky, in scratch ``L``)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = math.sqrt(s) if s > 0.0 else 1e-300
            else:
                L[i, j] = s / L[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * out[k]
        out[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= L[k, i] * out[k]
        out[i] = s / L[i, i]


@njit
def _backward(dt, u, c, rot, arw2, rrw2, xm, xp, Pp, xs, Pm, L, tmat, d, v, w):
    """RTS: ``x_k^s = x_k^+ + P_k^+ Phi^T (P_{k+1}^-)^-1 (x_{k+1}^s - x_{k+1}^-)``."""
    n = dt.shape[0]
    for i in range(N_STATE):
        xs[n - 1, i] = xp[n - 1, i]
    for k in range(n - 2, -1, -1):
        for i in range(N_STATE):
            for j in range(N_STATE):
                Pm[i, j] = Pp[k, i, j]
        _propagate(Pm, rot[k + 1], c[k + 1], u[k + 1], dt[k + 1], arw2, rrw2, tmat)
        for i in range(N_STATE):
            d[i] = xs[k + 1, i] - xm[k + 1, i]
        _cholesky_solve(Pm, d, L, v)
        # w = Phi^T v: the identity below the attitude rows, plus their transpose.
        for j in range(N_STATE):
            w[j] = v[j] if j >= 3 else 0.0
        for a in range(3):
            e_a = E_INDEX[a]
            r = rot[k + 1]
            cc = c[k + 1]
            for j in range(3):
                w[j] += r[a, j] * v[a]
                w[3 + j] -= dt[k + 1] * cc[a, j] * v[a]
                w[e_a[j]] += u[k + 1, j] * v[a]
        for i in range(N_STATE):
            acc = 0.0
            for j in range(N_STATE):
                acc += Pp[k, i, j] * w[j]
            xs[k, i] = xp[k, i] + acc


# ----------------------------------------------------------------- driving it


def _pass(model, s, gyro, qn, pn, x0, P0, gate2):
    """One Gauss-Newton pass about the nominal ``qn``, ``pn`` (n, 4), (n, 12)."""
    n = qn.shape[0]
    dt = s.dt_s
    cn = _sensitivity_rows(pn)
    # Propagation of sample k from the nominal at k-1 (row 0 has none).
    u = np.zeros((n, 3))
    u[1:] = gyro[1:] - pn[:-1, 0:3] * dt[1:, None]
    c = np.repeat(np.eye(3)[None], n, axis=0)
    c[1:] = cn[:-1]
    d = np.einsum("nij,nj->ni", c, u)
    rot = _rotations(d)
    q_pred = qn.copy()
    q_pred[1:] = qmul(qn[:-1], rotation_quaternion(d[1:]))
    q_pred /= np.linalg.norm(q_pred, axis=1)[:, None]
    off = np.zeros((n, N_STATE))
    off[1:, 0:3] = rotation_error(crlb.dcm_many(qn[1:]), crlb.dcm_many(q_pred[1:]))
    off[1:, 3:] = pn[:-1] - pn[1:]
    z, h, ok = _outputs(model, qn, s.time_s, s.tracker)
    meas = np.column_stack((s.sun[:, 0], s.sun[:, 1], s.tracker[:, 0], s.tracker[:, 1]))
    valid = np.column_stack((s.sun[:, km.VALID], s.sun[:, km.VALID], s.tracker[:, km.VALID],
                             s.tracker[:, km.VALID])) * ok
    valid[0] = 0.0  # the first sample made the initial attitude
    zres = meas - z
    xm, xp = np.empty((n, N_STATE)), np.empty((n, N_STATE))
    Pp = np.empty((n, N_STATE, N_STATE))
    arw2, rrw2 = model.arw_rad_rt_s ** 2, model.rrw_rad_s_rt_s ** 2
    _forward(dt, np.ascontiguousarray(u), np.ascontiguousarray(c), np.ascontiguousarray(rot),
             off, np.ascontiguousarray(zres), np.ascontiguousarray(h),
             np.ascontiguousarray(valid), crlb.measurement_variances(model), arw2, rrw2,
             gate2, x0, P0, xm, xp, Pp, np.empty((3, N_STATE)), np.empty(N_STATE),
             np.empty(N_STATE))
    xs = np.empty((n, N_STATE))
    _backward(dt, u, c, rot, arw2, rrw2, xm, xp, Pp, xs, np.empty((N_STATE, N_STATE)),
              np.zeros((N_STATE, N_STATE)), np.empty((3, N_STATE)), np.empty(N_STATE),
              np.empty(N_STATE), np.empty(N_STATE))
    return xs, Pp[-1].copy()


def smooth(model: km.FilterModel, samples: km.Samples, prior: km.Prior = km.DEFAULT_PRIOR,
           max_iterations=MAX_ITERATIONS) -> Smoothed:
    """Smooth ``samples`` (all of a record's calibration modes) with ``prior``.

    ``model`` is the filter's design
    (:func:`allsky.studies.kalman_mekf.filter_model`) and ``max_iterations``
    the most Gauss-Newton passes (fewer once the corrections fall below
    :data:`CONVERGED_SIGMA` sigmas). The filter
    (:func:`allsky.studies.kalman_mekf.estimate`) gives the first nominal; the
    record starts at its initial sample (the first to see Sun and star), whose
    attitude by TRIAD is the prior's mean.
    """
    est = km.estimate(model, samples, prior)
    first = est.first
    s = km.Samples(*[a[first:] for a in samples])
    q0 = km.triad(model, samples.time_s[first], samples.sun[first], samples.tracker[first])
    qn = np.vstack((q0, est.q))
    pn = np.vstack((np.zeros(12), est.params))
    gyro = np.asarray(s.gyro_rad, dtype=float)
    P0 = km.prior_covariance(prior)
    sig0 = np.sqrt(np.diag(P0))
    cov = P0
    it = 0
    for it in range(1, max_iterations + 1):
        x0 = np.concatenate((rotation_error(crlb.dcm_many(qn[:1]), crlb.dcm_many(q0[None]))[0],
                             -pn[0]))
        xs, cov = _pass(model, s, gyro, qn, pn, x0, P0, km.GATE_SIGMA ** 2)
        qn = qmul(qn, rotation_quaternion(xs[:, 0:3]))
        qn /= np.linalg.norm(qn, axis=1)[:, None]
        pn = pn + xs[:, 3:]
        sig = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        if np.max(np.abs(xs[-1, 3:]) / sig[3:]) < CONVERGED_SIGMA and np.max(
                np.abs(xs[:, 0:3])) < CONVERGED_SIGMA * sig[0:3].min() + 1e-9 * sig0[0]:
            break
    cov = cov.copy()
    for i in range(3):  # the present counter readout error, as the filter's (kalman_mekf)
        cov[i, i] += model.readout_rad ** 2
    return Smoothed(s, qn, pn, cov, it, est)


# ----------------------------------------------------------------- a flight with it


class Flight(NamedTuple):
    """A legacy mission whose calibration is the smoother's."""

    mission: Mission  #: the mission flown
    smoothed: Smoothed  #: None when the mission aborted before the end of Mode 5
    time_s: float  #: [s] calibration time (Modes 4-5)
    durations: dict  #: [s] per calibration mode
    excursion_arcsec: float  #: [arcsec] largest excursion during the calibration modes
    propellant_kg: float  #: [kg] used by the calibration modes
    smoother_s: float  #: [s] wall time of building the samples and smoothing
    bounds: dict  #: :func:`allsky.studies.crlb.mission_bounds` of the same record


def fly(cfg, prior: km.Prior = km.DEFAULT_PRIOR, through_mode6=True, bounds=None) -> Flight:
    """Fly the legacy plan, smooth Modes 3-5 (every frame), then fly Mode 6 with it.

    ``cfg`` is the scenario (flown recording every frame) and ``prior`` the
    smoother's :class:`~allsky.studies.kalman_mekf.Prior`; without
    ``through_mode6`` the flight ends after the calibration. ``bounds``
    (manoeuvre name -> modes) also evaluates
    :func:`allsky.studies.crlb.mission_bounds` on the same record before
    Mode 6. Calibration time, excursion and propellant as
    :mod:`allsky.studies.compare` measures them.
    """
    from allsky.sim.mission import LEGACY_PLAN
    from allsky.sim.results import fly_calibrating

    modes = km.FILTER_MODES["legacy"]
    m, rec = km.recording(crlb.recording_config(cfg), plan=LEGACY_PLAN, modes=modes)
    found = {"sm": None, "wall": 0.0, "bounds": {}}

    def calibrate(mm):
        if not mm.finished:
            t0 = time.perf_counter()
            samples = km.samples_from_legs(mm, rec.legs_flown, modes)
            found["sm"] = smooth(km.filter_model(mm), samples, prior)
            load_calibration(mm, found["sm"].params[-1], by="the smoother")
            found["wall"] = time.perf_counter() - t0
            if bounds:
                found["bounds"] = crlb.mission_bounds(mm, rec.legs_flown, bounds)
        return through_mode6

    t_cal, prop, durations = fly_calibrating(m, km.CALIBRATION_MODES["legacy"], on_end=calibrate,
                                             hooks=rec.hooks)
    return Flight(m, found["sm"], t_cal, durations,
                  float(m.state.max_excursion_rad[0] * units.RAD2ARCSEC), prop, found["wall"],
                  found["bounds"])


def errors(m, sm: Smoothed) -> np.ndarray:
    """True minus smoothed error state (15) at the last sample.

    The attitude as the exact rotation (:func:`rotation_error`), then the
    parameters. ``sm`` is the :class:`Smoothed` result over mission ``m``'s
    samples (with their truth).
    """
    s = sm.samples
    k = s.time_s.size - 1
    att = rotation_error(crlb.dcm_many(sm.q[k:k + 1]), crlb.dcm_many(s.truth_q[k:k + 1]))[0]
    return np.concatenate([att, km.true_parameters(m, s.truth_bias_rad_s[k]) - sm.params[k]])
