"""Closed-form steady-state accuracy of a gyro + angle-sensor Kalman filter.

One axis: a gyro is integrated to propagate the attitude angle between
samples of an angle sensor (star tracker 105, sun sensor 104), and a Kalman
filter estimates the angle and the gyro drift bias. Its steady-state error
covariance has a closed form (Farrenkopf 1978) for a *rate* gyro, and a
simple extension (Markley & Reynolds 2000) for a *rate-integrating* gyro
whose angle readout carries white noise. In ``allsky`` the chain gyro 1/2/3
-> summing amplifier 4/5/6 -> voltage-to-frequency converter 8/10/12 ->
up/down counter 14/16/18 is such a rate-integrating readout: the counter
holds the integrated angle in whole pulses, so its readout error is the
fraction of a pulse, ``sigma_e = pulse_weight / sqrt(12)``
(:func:`quantization_sigma_rad`).

Derivations, assumptions and a worked example: ``docs/kalman.md``, section
"Steady-state accuracy: closed forms". All functions broadcast over numpy
arrays.

Symbols
-------

=============  =======================  ===========  ==========================================
Symbol         Name here                Unit         Meaning
=============  =======================  ===========  ==========================================
sigma_v        ``sigma_v_rad_rt_s``     rad/s^0.5    angle random walk (white rate noise density)
sigma_u        ``sigma_u_rad_s_rt_s``   rad/s^1.5    rate random walk (drift-bias noise density)
sigma_n        ``sigma_n_rad``          rad          angle-sensor white noise per sample
sigma_e        ``sigma_e_rad``          rad          gyro angle-readout white noise per sample
N              ``sigma_n_rad_rt_hz``    rad/Hz^0.5   continuous angle-sensor noise density
dt             ``dt_s``                 s            sample interval (sensor and gyro readout)
S_u            --                       --           ``sigma_u dt^1.5 / sigma_n``
S_v            --                       --           ``sigma_v dt^0.5 / sigma_n``
gamma          --                       --           ``sqrt(4 + S_v^2 + S_u^2 / 12)``
xi             ``xi``                   --           innovation sigma / sigma_n, below
=============  =======================  ===========  ==========================================

Farrenkopf's root: ``xi = (gamma + S_u/2 + sqrt(S_u gamma + S_v^2 + S_u^2/3)) / 2``.

"Pre" is just before the angle-sensor update of a sample (after the gyro
propagation), "post" just after it. Errors are truth minus estimate, and the
attitude error grows as ``-(bias error) * t``, so the attitude-bias
covariance is negative.

Sources: C. R. Farrenkopf, "Analytic steady-state accuracy solutions for two
common spacecraft attitude estimators", J. Guidance and Control 1(4), 1978;
F. L. Markley and R. G. Reynolds, "Analytic steady-state accuracy of a
spacecraft attitude estimator", J. Guidance, Control, and Dynamics 23(6),
2000; F. L. Markley and J. L. Crassidis, *Fundamentals of Spacecraft
Attitude Determination and Control*, Springer 2014, sec. 6.3. The
expressions here are derived anew in ``docs/kalman.md`` and checked against
the discrete Riccati equation in ``tests/studies/test_estimator_accuracy.py``.
"""

from typing import NamedTuple

import numpy as np


class SteadyStateAccuracy(NamedTuple):
    """Steady-state standard deviations, covariances and gains of the discrete filter."""

    attitude_pre_rad: np.ndarray  #: [rad] attitude error sigma before the sensor update
    attitude_post_rad: np.ndarray  #: [rad] attitude error sigma after the sensor update
    bias_pre_rad_s: np.ndarray  #: [rad/s] drift-bias error sigma before the update
    bias_post_rad_s: np.ndarray  #: [rad/s] drift-bias error sigma after the update
    attitude_bias_pre_rad2_s: np.ndarray  #: [rad^2/s] attitude-bias covariance before
    attitude_bias_post_rad2_s: np.ndarray  #: [rad^2/s] attitude-bias covariance after
    gain_attitude: np.ndarray  #: [-] attitude update per unit innovation
    gain_attitude_propagated: np.ndarray  #: [-] the part of it carried to later samples
    gain_bias_per_s: np.ndarray  #: [1/s] drift-bias update per unit (rad) innovation
    xi: np.ndarray  #: [-] Farrenkopf's root, innovation sigma / angle-noise sigma


class ContinuousAccuracy(NamedTuple):
    """Steady-state accuracy of the continuous (Kalman-Bucy) filter.

    Holds the standard deviations and the covariance.
    """

    attitude_rad: np.ndarray  #: [rad] attitude error sigma
    bias_rad_s: np.ndarray  #: [rad/s] drift-bias error sigma
    attitude_bias_rad2_s: np.ndarray  #: [rad^2/s] attitude-bias covariance


def _nonnegative(name, value):
    a = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(a)) or np.any(a < 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return a


def _positive(name, value):
    a = _nonnegative(name, value)
    if np.any(a == 0.0):
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return a


def _scalar(a):
    """0-d arrays as numpy scalars, anything else unchanged."""
    return a[()]


def _farrenkopf_normalised(s_v, s_u):
    """``(xi^2 - 1, xi)`` for the dimensionless S_v, S_u, without cancellation.

    ``xi + 1/xi = S_u/2 + gamma = 2 + w`` with ``w = S_u/2 + (gamma - 2) >= 0``
    written as a sum of non-negative terms, so ``xi - 1 = (w + sqrt(w (w + 4))) / 2``
    keeps full relative precision even when the noises are tiny and xi -> 1.
    """
    tail = s_v**2 + s_u**2 / 12.0
    gamma = np.sqrt(4.0 + tail)
    w = 0.5 * s_u + tail / (gamma + 2.0)  # xi + 1/xi - 2
    # w (w + 4) = S_u gamma + S_v^2 + S_u^2/3, the radicand of Farrenkopf's xi
    xi_m1 = 0.5 * (w + np.sqrt(w * (w + 4.0)))
    xi = 1.0 + xi_m1
    return xi_m1 * (xi + 1.0), xi


def farrenkopf(sigma_v_rad_rt_s, sigma_u_rad_s_rt_s, sigma_n_rad, dt_s) -> SteadyStateAccuracy:
    """Steady-state accuracy of the rate-gyro + angle-sensor filter (Farrenkopf 1978).

    Two error states, attitude angle and gyro drift bias; the gyro rate,
    with white noise ``sigma_v`` and a bias walking with ``sigma_u``, is
    integrated over ``dt`` between angle-sensor samples of white noise
    ``sigma_n``. With ``s = sigma_n^2 xi^2`` the innovation variance::

        P_att^- = sigma_n^2 (xi^2 - 1)          P_att^+ = sigma_n^2 (1 - xi^-2)
        P_bias^-+ = sigma_n^2/dt^2 (S_u (xi - 1/xi) +- S_u^2/2)
        P_ab^- = -sigma_n^2/dt S_u xi           P_ab^+ = -sigma_n^2/dt S_u / xi

    Parameters
    ----------
    sigma_v_rad_rt_s : float or array_like
        Angle random walk [rad/s^0.5], >= 0.
    sigma_u_rad_s_rt_s : float or array_like
        Rate random walk [rad/s^1.5], >= 0.
    sigma_n_rad : float or array_like
        Angle-sensor noise per sample [rad], > 0.
    dt_s : float or array_like
        Sample interval [s], > 0.

    Returns
    -------
    SteadyStateAccuracy
        Sigmas, covariances and gains; ``gain_attitude_propagated`` equals
        ``gain_attitude`` for a rate gyro.

    Raises
    ------
    ValueError
        On a negative or non-finite noise, or a zero ``sigma_n_rad`` or ``dt_s``.
    """
    return rate_integrating(sigma_v_rad_rt_s, sigma_u_rad_s_rt_s, sigma_n_rad, 0.0, dt_s)


def rate_integrating(sigma_v_rad_rt_s, sigma_u_rad_s_rt_s, sigma_n_rad, sigma_e_rad,
                     dt_s) -> SteadyStateAccuracy:
    """Steady-state accuracy with a rate-integrating gyro read out with noise.

    After Markley & Reynolds.

    The gyro reports its integrated angle with white readout noise
    ``sigma_e`` at every sample. The drift part of the gyro angle follows
    Farrenkopf's model, observed through the sensor-minus-gyro angle with
    white noise of variance ``R = sigma_n^2 + sigma_e^2``; xi and S_u, S_v
    are therefore formed with ``sqrt(R)`` in place of ``sigma_n``. Then::

        P_att^- = R xi^2 - sigma_n^2            P_att^+ = sigma_n^2 (1 - sigma_n^2 / (R xi^2))
        P_bias^-+ = R/dt^2 (S_u (xi - 1/xi) +- S_u^2/2)     (Farrenkopf's with R)
        P_ab^- = -R/dt S_u xi                   P_ab^+ = -sigma_n^2/dt S_u / xi

    Of the attitude gain ``1 - sigma_n^2/(R xi^2)`` only ``1 - xi^-2`` is
    carried to later samples; the rest, ``sigma_e^2/(R xi^2)``, estimates the
    present readout error, which is white. ``sigma_e = 0`` gives
    :func:`farrenkopf` exactly.

    Parameters
    ----------
    sigma_v_rad_rt_s : float or array_like
        Angle random walk [rad/s^0.5], >= 0.
    sigma_u_rad_s_rt_s : float or array_like
        Rate random walk [rad/s^1.5], >= 0.
    sigma_n_rad : float or array_like
        Angle-sensor noise per sample [rad], > 0.
    sigma_e_rad : float or array_like
        Gyro angle-readout noise per sample [rad], >= 0.
    dt_s : float or array_like
        Sample interval [s], > 0.

    Returns
    -------
    SteadyStateAccuracy
        Sigmas, covariances and gains.

    Raises
    ------
    ValueError
        On a negative or non-finite noise, or a zero ``sigma_n_rad`` or ``dt_s``.
    """
    sigma_v = _nonnegative("sigma_v_rad_rt_s", sigma_v_rad_rt_s)
    sigma_u = _nonnegative("sigma_u_rad_s_rt_s", sigma_u_rad_s_rt_s)
    sigma_n = _positive("sigma_n_rad", sigma_n_rad)
    sigma_e = _nonnegative("sigma_e_rad", sigma_e_rad)
    dt = _positive("dt_s", dt_s)
    sigma_v, sigma_u, sigma_n, sigma_e, dt = np.broadcast_arrays(
        sigma_v, sigma_u, sigma_n, sigma_e, dt)

    var_n = sigma_n**2
    var_r = var_n + sigma_e**2  # sensor-minus-gyro noise variance
    sigma_r = np.sqrt(var_r)
    s_u = sigma_u * dt**1.5 / sigma_r
    s_v = sigma_v * np.sqrt(dt) / sigma_r
    xi2_m1, xi = _farrenkopf_normalised(s_v, s_u)
    innovation_var = var_r * xi**2  # sensor innovation variance, R xi^2 = P_att^- + sigma_n^2

    # Sums of non-negative terms only, so small variances keep their precision.
    att_pre = var_r * xi2_m1 + sigma_e**2
    att_post = var_n * att_pre / innovation_var
    bias_scale = var_r / dt**2
    bias_common = s_u * xi2_m1 / xi  # S_u (xi - 1/xi)
    bias_pre = bias_scale * (bias_common + 0.5 * s_u**2)
    bias_post = bias_scale * (bias_common - 0.5 * s_u**2)
    ab_pre = -var_r / dt * s_u * xi
    ab_post = -var_n / dt * s_u / xi
    # Attitude gain = 1 - sigma_n^2/(R xi^2): the part 1 - xi^-2 estimates the
    # drift angle and is carried on; sigma_e^2/(R xi^2) estimates this readout's error.
    gain_propagated = xi2_m1 / xi**2

    return SteadyStateAccuracy(
        attitude_pre_rad=_scalar(np.sqrt(att_pre)),
        attitude_post_rad=_scalar(np.sqrt(att_post)),
        bias_pre_rad_s=_scalar(np.sqrt(bias_pre)),
        # Clipped at 0: the difference can round to -1 ulp when S_u dominates.
        bias_post_rad_s=_scalar(np.sqrt(np.maximum(bias_post, 0.0))),
        attitude_bias_pre_rad2_s=_scalar(ab_pre),
        attitude_bias_post_rad2_s=_scalar(ab_post),
        gain_attitude=_scalar(gain_propagated + sigma_e**2 / innovation_var),
        gain_attitude_propagated=_scalar(gain_propagated),
        gain_bias_per_s=_scalar(-s_u / (dt * xi)),
        xi=_scalar(xi),
    )


def continuous(sigma_v_rad_rt_s, sigma_u_rad_s_rt_s, sigma_n_rad_rt_hz) -> ContinuousAccuracy:
    """Steady-state accuracy of the continuous-time filter (the ``dt -> 0`` limit).

    The angle sensor is a continuous measurement with white noise of density
    ``N`` (the discrete ``sigma_n^2 dt`` held fixed as ``dt -> 0``). The
    continuous algebraic Riccati equation gives::

        P_att = N sqrt(sigma_v^2 + 2 sigma_u N)
        P_bias = sigma_u sqrt(sigma_v^2 + 2 sigma_u N)
        P_ab = -sigma_u N

    Parameters
    ----------
    sigma_v_rad_rt_s : float or array_like
        Angle random walk [rad/s^0.5], >= 0.
    sigma_u_rad_s_rt_s : float or array_like
        Rate random walk [rad/s^1.5], >= 0.
    sigma_n_rad_rt_hz : float or array_like
        Angle-sensor noise density [rad/Hz^0.5 = rad s^0.5], > 0.

    Returns
    -------
    ContinuousAccuracy
        Attitude and bias sigmas and their covariance.

    Raises
    ------
    ValueError
        On a negative or non-finite noise, or a zero ``sigma_n_rad_rt_hz``.
    """
    sigma_v = _nonnegative("sigma_v_rad_rt_s", sigma_v_rad_rt_s)
    sigma_u = _nonnegative("sigma_u_rad_s_rt_s", sigma_u_rad_s_rt_s)
    density = _positive("sigma_n_rad_rt_hz", sigma_n_rad_rt_hz)
    root = np.sqrt(sigma_v**2 + 2.0 * sigma_u * density)  # [rad/s^0.5]
    return ContinuousAccuracy(
        attitude_rad=_scalar(np.sqrt(density * root)),
        bias_rad_s=_scalar(np.sqrt(sigma_u * root)),
        attitude_bias_rad2_s=_scalar(-sigma_u * density),
    )


def quantization_sigma_rad(pulse_weight_rad):
    """Readout noise [rad] of a counter holding the integrated angle in whole pulses.

    The count misses the true integral by the fraction of a pulse still on
    the converter's integrator (voltage-to-frequency converters 8/10/12 carry
    it, up/down counters 14/16/18 hold the whole pulses). Taken as uniform
    over one pulse, its standard deviation is ``pulse_weight / sqrt(12)``;
    treating it as white between samples holds when the angle moves through
    several pulses per sample. Its mean (half a pulse, with the sign of the
    motion) is a constant offset, not noise.

    Parameters
    ----------
    pulse_weight_rad : float or array_like
        Angle per pulse [rad], >= 0.

    Returns
    -------
    float or ndarray
        ``sigma_e`` [rad] for :func:`rate_integrating`.
    """
    return _scalar(_nonnegative("pulse_weight_rad", pulse_weight_rad) / np.sqrt(12.0))
