"""Strapped-down rate gyros 1, 2, 3 (roll, pitch, yaw).

Error model, per frame of length ``dt``::

    rate_arcsec_s = S @ (dtheta_body / dt) * RAD2ARCSEC + drift + b_rw + n_arw
    S = diag(1 + scale_factor_error) @ (I + M)

``dtheta_body`` is the body-angle increment over the frame (so the gyro
sees the exact mean rate of the frame, as its pulse train would); ``M`` holds
the input-axis misalignments (row i: gyro i's sensitivity to body x, y, z,
zero diagonal). ``drift`` is the constant bias, ``b_rw`` a rate random walk,
``n_arw`` the angle random walk as white rate noise of density ``N`` with
standard deviation ``N / sqrt(dt)`` over a frame. The output saturates at
the gyro's range. The output is in the electronics' unit, arcsec/s.
"""

from typing import NamedTuple

import numpy as np

from allsky import units, xmath
from allsky.gauss import standard_normal
from allsky.jit import njit_stage
from allsky.units import RAD2ARCSEC
from allsky.vocabulary import AXES

#: [s] interval between steps of the rate random walk
RRW_STEP_S = 1.0


class GyroParams(NamedTuple):
    """Gyro triad parameters (all rates in arcsec/s)."""

    sensitivity: np.ndarray  #: [-] 3x3 matrix S = diag(1+sf) (I+M)
    drift_arcsec_s: np.ndarray  #: [arcsec/s] constant bias per gyro (1 arcsec/s = 1 deg/h)
    arw_arcsec_rt_s: float  #: [arcsec/sqrt(s)] angle random walk density
    rrw_arcsec_s_rt_s: float  #: [arcsec/s/sqrt(s)] rate random walk density
    range_arcsec_s: float  #: [arcsec/s] output saturation


def make_params(drift_deg_h, scale_factor_error_ppm, misalignment_arcsec, arw_deg_rt_h,
                rrw_deg_h_rt_h, range_deg_s) -> GyroParams:
    """Build :class:`GyroParams` from scenario units.

    Parameters
    ----------
    drift_deg_h : sequence of 3 float
        [deg/h] constant bias of gyros 1, 2, 3 (roll, pitch, yaw).
    scale_factor_error_ppm : sequence of 3 float
        [ppm] scale-factor error of each gyro.
    misalignment_arcsec : 3x3 array_like
        [arcsec] input-axis misalignments: row i is gyro i's sensitivity to
        body x, y, z; the diagonal is ignored.
    arw_deg_rt_h : float
        [deg/sqrt(h)] angle random walk density.
    rrw_deg_h_rt_h : float
        [deg/h/sqrt(h)] rate random walk density.
    range_deg_s : float
        [deg/s] output saturation, either sign.
    """
    m = np.array(misalignment_arcsec, dtype=float) * units.ARCSEC2RAD
    np.fill_diagonal(m, 0.0)
    sf = np.array(scale_factor_error_ppm, dtype=float) * units.PPM2FRACTION
    s = xmath.matmul(np.diag(1.0 + sf), np.eye(3) + m)
    return GyroParams(
        sensitivity=s,
        drift_arcsec_s=np.array(drift_deg_h, dtype=float) * units.DEG_H2ARCSEC_S,
        # deg/sqrt(h) -> arcsec/sqrt(s): 3600 arcsec/deg / 60 sqrt(s)/sqrt(h)
        arw_arcsec_rt_s=float(arw_deg_rt_h) * 60.0,
        # deg/h/sqrt(h) -> arcsec/s/sqrt(s)
        rrw_arcsec_s_rt_s=float(rrw_deg_h_rt_h) / 60.0,
        range_arcsec_s=float(range_deg_s) * units.DEG2ARCSEC,
    )


@njit_stage
def gyro_output(p, dtheta_rad, dt_s, bias_rw_arcsec_s, out_rate_arcsec_s, step_bias, rng):
    """Measured rates [arcsec/s] for a frame's body-angle increment [rad].

    ``bias_rw_arcsec_s`` (3) is the rate-random-walk state. It is advanced
    only when ``step_bias`` is true, by a step of ``K sqrt(RRW_STEP_S)``: once
    a second is plenty for a walk of a few 0.001 deg/h over a mission, and
    saves three random draws per frame.

    Parameters
    ----------
    p : GyroParams
        The gyro triad.
    dtheta_rad : array of 3 float
        [rad] body-angle increment of the frame (body x, y, z).
    dt_s : float
        [s] frame length; the gyros see the frame's mean rate.
    out_rate_arcsec_s : array of 3 float
        [arcsec/s] written: the rates of gyros 1, 2, 3, saturated at the range.
    rng : numpy.ndarray
        (1,) uint64 state of the noise generator (``allsky.gauss``), advanced
        by the random-walk and angle-noise draws.
    """
    s = p.sensitivity
    k = RAD2ARCSEC / dt_s
    sig_arw = p.arw_arcsec_rt_s / np.sqrt(dt_s)
    sig_rrw = p.rrw_arcsec_s_rt_s * np.sqrt(RRW_STEP_S)
    for i in range(3):
        if step_bias and sig_rrw > 0.0:
            bias_rw_arcsec_s[i] += sig_rrw * standard_normal(rng)
        r = (s[i, 0] * dtheta_rad[0] + s[i, 1] * dtheta_rad[1] + s[i, 2] * dtheta_rad[2]) * k
        r += p.drift_arcsec_s[i] + bias_rw_arcsec_s[i]
        if sig_arw > 0.0:
            r += sig_arw * standard_normal(rng)
        if r > p.range_arcsec_s:
            r = p.range_arcsec_s
        elif r < -p.range_arcsec_s:
            r = -p.range_arcsec_s
        out_rate_arcsec_s[i] = r


def perfect_calibration(p: GyroParams, integrator_drift_arcsec_s=(0.0, 0.0, 0.0)) -> dict:
    """The values a perfect Modes 3-5 calibration would store for these gyros.

    Drift = gyro drift plus the integrator drift of the chain to converters
    8/10/12 (``integrator_drift_arcsec_s``), which Mode 3 counts together;
    both are also given apart. Scale factor = true angle / counted angle;
    cross-coupling = counts on the other axis per unit true angle (SPEC section 4).
    ``p`` is the gyro triad (:class:`GyroParams`).
    """
    s = p.sensitivity
    gyro_drift = [float(d) for d in p.drift_arcsec_s]
    integrator = [float(d) for d in integrator_drift_arcsec_s]
    # Sum only where the integrator drifts: adding 0.0 would turn a -0.0 drift into +0.0.
    total = [g + i if i != 0.0 else g for g, i in zip(gyro_drift, integrator)]
    axes = AXES
    return {
        "drift_deg_h": dict(zip(axes, total)),
        "gyro_drift_deg_h": dict(zip(axes, gyro_drift)),
        "integrator_drift_deg_h": dict(zip(axes, integrator)),
        "scale_factor": {"roll": float(1.0 / s[0, 0]), "yaw": float(1.0 / s[2, 2])},
        "cross_coupling": {"roll_into_pitch": float(s[1, 0]), "roll_into_yaw": float(s[2, 0]),
                           "yaw_into_pitch": float(s[1, 2]), "yaw_into_roll": float(s[0, 2])},
    }
