"""A single-axis Kalman filter on the emulated gyro, counter and optical sensor.

One axis of the patent's chain gyro 1/2/3 -> summing amplifier 4/5/6 ->
voltage-to-frequency converter 8/10/12 -> up/down counter 14/16/18 is a
rate-integrating gyro read out in whole pulses; the star tracker 105 or sun
sensor 104 gives the angle with white noise. This module

* generates such data, vectorised over many seeded runs
  (:func:`simulate_hardware`): a true angle moving at a constant rate, a gyro
  with angle random walk and a drift bias walking with rate random walk, the
  converter's pulses with the residue carried from frame to frame exactly as
  :func:`allsky.hardware.vfc.vfc` does it, the counter's content, and the
  optical angle;
* filters it with the discrete two-state Kalman filter (drift angle and
  drift bias) whose steady state :func:`allsky.studies.estimator_accuracy.rate_integrating`
  gives in closed form (:func:`filter_counter`), or, fed with the gyro's
  unquantised angle increments, with Farrenkopf's plain rate-gyro filter
  (:func:`filter_rate_gyro`);
* runs the filter's covariance recursion (:func:`covariance_history`) and a
  Monte Carlo check of the errors against the closed form
  (:func:`monte_carlo`).

The summing amplifier passes the gyro rate unchanged here (drift DAC at
zero); a constant offset at the converter's input would be one more part
of the drift bias (``bias0_rad_s``). Scale-factor error, misalignment and
counter overflow are left out.
The model and the filter's equations: ``docs/kalman.md``, sections
"Steady-state accuracy: closed forms" and "A single-axis filter on the
emulated hardware". Angles in rad, times in s, except the converter's own
arcsec and pulses.
"""

import math
from typing import NamedTuple

import numpy as np

from allsky import units
from allsky.gauss import seed
from allsky.hardware.gyro import RRW_STEP_S, gyro_output
from allsky.hardware.star_tracker import new_lock, star_tracker
from allsky.hardware.updown_counter import SATURATE, count
from allsky.hardware.vfc import vfc
from allsky.jit import njit
from allsky.studies import estimator_accuracy
from allsky.units import ARCSEC2RAD


class AxisModel(NamedTuple):
    """Noises, converter scaling and timing of one axis."""

    sigma_v_rad_rt_s: float  #: [rad/s^0.5] gyro angle random walk
    sigma_u_rad_s_rt_s: float  #: [rad/s^1.5] gyro rate random walk (drift-bias walk)
    sigma_n_rad: float  #: [rad] optical angle white noise per sample
    pulse_weight_arcsec: float  #: [arcsec/pulse] converter 8/10/12 scaling
    max_rate_pps: float  #: [pulses/s] converter saturation
    frame_s: float  #: [s] converter and counter frame
    frames_per_sample: int  #: [-] frames between two samples of counter and sensor

    @property
    def dt_s(self) -> float:
        """Sample interval [s]."""
        return self.frame_s * self.frames_per_sample

    @property
    def sigma_e_rad(self) -> float:
        """Counter readout noise [rad], one pulse weight over sqrt(12)."""
        return float(estimator_accuracy.quantization_sigma_rad(
            self.pulse_weight_arcsec * units.ARCSEC2RAD))


def axis_model(cfg, sensor="star_tracker", frames_per_sample=1) -> AxisModel:
    """The :class:`AxisModel` of a scenario's gyro, converters and one optical sensor.

    Parameters
    ----------
    cfg : allsky.config.Scenario
        Reads ``gyro.arw_deg_rt_h``, ``gyro.rrw_deg_h_rt_h``,
        ``electronics.vfc_pulse_weight_arcsec``, ``electronics.vfc_max_rate_pps``,
        ``mission.frame_s`` and ``<sensor>.noise_arcsec``.
    sensor : {"star_tracker", "sun_sensor"}
        The optical sensor (105 or 104).
    frames_per_sample : int
        Frames between samples.

    Returns
    -------
    AxisModel
    """
    return AxisModel(
        sigma_v_rad_rt_s=cfg.gyro.arw_deg_rt_h * units.DEG2RAD / math.sqrt(units.HOUR_S),
        sigma_u_rad_s_rt_s=(cfg.gyro.rrw_deg_h_rt_h * units.DEG2RAD / units.HOUR_S
                            / math.sqrt(units.HOUR_S)),
        sigma_n_rad=getattr(cfg, sensor).noise_arcsec * units.ARCSEC2RAD,
        pulse_weight_arcsec=cfg.electronics.vfc_pulse_weight_arcsec,
        max_rate_pps=cfg.electronics.vfc_max_rate_pps,
        frame_s=cfg.mission.frame_s,
        frames_per_sample=int(frames_per_sample),
    )


def closed_form(model: AxisModel, quantized=True) -> estimator_accuracy.SteadyStateAccuracy:
    """Closed-form steady state of the filter for ``model``.

    With ``quantized`` the counter readout (``sigma_e`` = pulse weight /
    sqrt(12)), else the unquantised rate gyro (Farrenkopf).
    """
    return estimator_accuracy.rate_integrating(
        model.sigma_v_rad_rt_s, model.sigma_u_rad_s_rt_s, model.sigma_n_rad,
        model.sigma_e_rad if quantized else 0.0, model.dt_s)


# ------------------------------------------------------------------ the hardware model


class HardwareRecord(NamedTuple):
    """Samples of one axis, shape (runs, samples); sample k is at ``(k+1) dt``."""

    time_s: np.ndarray  #: [s] sample times, shape (samples,)
    true_angle_rad: np.ndarray  #: [rad] vehicle angle
    gyro_angle_rad: np.ndarray  #: [rad] exact integral of the gyro output (rate gyro form)
    bias_rad_s: np.ndarray  #: [rad/s] gyro drift bias at the sample
    #: [pulses] up/down counter 14/16/18 content (int64); it starts at 0, the
    #: converter's residue at ``residue0_pulses``, so (counter + residue -
    #: residue0) x pulse weight is the gyro angle (below saturation)
    counter_pulses: np.ndarray
    counter_angle_rad: np.ndarray  #: [rad] counter content x pulse weight
    optical_angle_rad: np.ndarray  #: [rad] star tracker 105 / sun sensor 104 output
    residue0_pulses: np.ndarray  #: [pulses] converter residue at t = 0, shape (runs,)
    bias0_rad_s: np.ndarray  #: [rad/s] drift bias at t = 0, shape (runs,)


def _step_covariance(sigma_v, sigma_u, dt):
    """Covariance of the (gyro drift angle, bias) increments from the noises over ``dt``.

    The drift angle collects ``int(eta_v) + int((dt - s) eta_u ds)``, the
    bias ``int(eta_u)`` (``docs/kalman.md``, Model, with the sign of the
    gyro's drift angle rather than the attitude error).
    """
    return np.array([[sigma_v**2 * dt + sigma_u**2 * dt**3 / 3.0, sigma_u**2 * dt**2 / 2.0],
                     [sigma_u**2 * dt**2 / 2.0, sigma_u**2 * dt]])


def convert(model: AxisModel, rate_arcsec_s, residue_pulses):
    """Pulses of converter 8/10/12 over one frame, vectorised over runs.

    The same arithmetic as :func:`allsky.hardware.vfc.vfc`, element by
    element: rate / pulse weight, clipped at ``max_rate_pps``, plus the
    carried residue, truncated toward zero.

    Parameters
    ----------
    model : AxisModel
    rate_arcsec_s : ndarray
        Gyro rate held over the frame [arcsec/s].
    residue_pulses : ndarray
        Fraction of a pulse carried in [pulses].

    Returns
    -------
    pulses : ndarray of int64
        Whole pulses put out, signed.
    residue : ndarray
        Fraction carried to the next frame [pulses].
    """
    pps = np.clip(rate_arcsec_s / model.pulse_weight_arcsec,
                  -model.max_rate_pps, model.max_rate_pps)
    total = residue_pulses + pps * model.frame_s
    n = np.trunc(total)  # toward zero, as int()
    return n.astype(np.int64), total - n


def simulate_hardware(model: AxisModel, rate_rad_s, samples, seed, bias0_rad_s=0.0,
                      residue0_pulses=None) -> HardwareRecord:
    """Seeded runs of the gyro -> converter -> counter chain and the optical sensor.

    Every frame the gyro's angle increment (true motion + drift bias x frame
    + the integrated noises, drawn jointly Gaussian) is turned into pulses the
    way converter 8/10/12 does it: rate [arcsec/s] / pulse weight, clipped at
    the saturation, plus the carried residue, truncated toward zero; the
    whole pulses go to the counter, the fraction is carried. At every
    ``frames_per_sample``-th frame counter and optical sensor are sampled.

    Parameters
    ----------
    model : AxisModel
    rate_rad_s : array_like, shape (runs,)
        True constant rate of each run [rad/s]; its length sets the number of runs.
    samples : int
        Number of samples per run.
    seed : int
        Seed of the numpy generator; same seed, same record.
    bias0_rad_s : float or array_like
        Drift bias at t = 0 [rad/s].
    residue0_pulses : array_like or None
        Converter residue at t = 0 [pulses]; ``None`` draws it uniform over
        one pulse with the sign of the run's rate (a counter that has been
        counting in that direction for a while).

    Returns
    -------
    HardwareRecord
    """
    rng = np.random.default_rng(seed)
    rate = np.asarray(rate_rad_s, dtype=float)
    runs = rate.size
    frame = model.frame_s
    q = _step_covariance(model.sigma_v_rad_rt_s, model.sigma_u_rad_s_rt_s, frame)
    # Square root of q; written out because q is singular without rate random walk.
    chol = np.zeros((2, 2))
    chol[0, 0] = math.sqrt(q[0, 0])
    if q[1, 1] > 0.0:
        chol[1, 0] = q[1, 0] / chol[0, 0]
        chol[1, 1] = math.sqrt(q[1, 1] - chol[1, 0] ** 2)
    if residue0_pulses is None:
        residue = rng.uniform(0.0, 1.0, runs) * np.where(rate < 0.0, -1.0, 1.0)
    else:
        residue = np.array(np.broadcast_to(residue0_pulses, (runs,)), dtype=float)
    bias = np.array(np.broadcast_to(bias0_rad_s, (runs,)), dtype=float)
    out = HardwareRecord(
        time_s=model.dt_s * np.arange(1, samples + 1),
        true_angle_rad=np.empty((runs, samples)), gyro_angle_rad=np.empty((runs, samples)),
        bias_rad_s=np.empty((runs, samples)), counter_pulses=np.empty((runs, samples), np.int64),
        counter_angle_rad=np.empty((runs, samples)), optical_angle_rad=np.empty((runs, samples)),
        residue0_pulses=residue.copy(), bias0_rad_s=bias.copy())
    theta = np.zeros(runs)  # true angle
    drift = np.zeros(runs)  # gyro angle - true angle
    counter = np.zeros(runs, np.int64)
    weight_rad = model.pulse_weight_arcsec * units.ARCSEC2RAD
    for k in range(samples):
        for _ in range(model.frames_per_sample):
            w = chol @ rng.standard_normal((2, runs))
            increment_rad = rate * frame + bias * frame + w[0]  # gyro angle over the frame
            theta = theta + rate * frame
            drift = drift + bias * frame + w[0]
            bias = bias + w[1]
            pulses, residue = convert(model, increment_rad * units.RAD2ARCSEC / frame,
                                      residue)
            counter += pulses  # up/down counter 14/16/18
        out.true_angle_rad[:, k] = theta
        out.gyro_angle_rad[:, k] = theta + drift
        out.bias_rad_s[:, k] = bias
        out.counter_pulses[:, k] = counter
        out.optical_angle_rad[:, k] = theta + model.sigma_n_rad * rng.standard_normal(runs)
    out.counter_angle_rad[:] = out.counter_pulses * weight_rad
    return out


# ------------------------------------------------------------------ the filter


class Covariance(NamedTuple):
    """The filter's error statistics per sample, shape (samples,) (or scalars)."""

    attitude_pre_rad: np.ndarray  #: [rad] attitude error sigma before the optical update
    attitude_post_rad: np.ndarray  #: [rad] attitude error sigma after it
    bias_pre_rad_s: np.ndarray  #: [rad/s] drift-bias error sigma before the update
    bias_post_rad_s: np.ndarray  #: [rad/s] drift-bias error sigma after it
    attitude_bias_pre_rad2_s: np.ndarray  #: [rad^2/s] attitude-bias covariance before
    attitude_bias_post_rad2_s: np.ndarray  #: [rad^2/s] attitude-bias covariance after
    gain_attitude: np.ndarray  #: [-] attitude update per unit innovation
    gain_attitude_propagated: np.ndarray  #: [-] the part carried to later samples
    gain_bias_per_s: np.ndarray  #: [1/s] bias update per unit (rad) attitude innovation


def covariance_history(model: AxisModel, samples, quantized=True, p0=None) -> Covariance:
    """The filter's covariance recursion over ``samples`` samples.

    States: the gyro's drift angle ``d`` (gyro angle - true angle) and drift
    bias ``b``. Per sample: ``P <- Phi P Phi^T + Q`` with ``Phi = [[1, dt],
    [0, 1]]`` and ``Q`` from the noises, then the update on the measurement
    gyro readout - optical angle ``= d + e - n``, noise variance
    ``R = sigma_n^2 + sigma_e^2``. The attitude statistics follow
    (``docs/kalman.md``): ``P_att^- = P_dd^- + sigma_e^2``,
    ``P_att^+ = sigma_n^2 P_att^- / (P_att^- + sigma_n^2)``, attitude-bias
    covariance ``-P_db^-`` before and ``-sigma_n^2 P_db^- / (P_dd^- + R)``
    after. Written with scalars, not matrices, for speed over long runs.

    Parameters
    ----------
    model : AxisModel
    samples : int
        Number of samples.
    quantized : bool
        Counter readout (``sigma_e`` = pulse weight / sqrt(12)) or, if
        False, the unquantised rate gyro (``sigma_e = 0``, Farrenkopf).
    p0 : array_like (2, 2) or None
        Post-update covariance of (d, b) at t = 0 [rad^2, rad^2/s, rad^2/s^2];
        ``None`` starts at the closed-form steady state.

    Returns
    -------
    Covariance
        Arrays of length ``samples``.
    """
    dt = model.dt_s
    var_n = model.sigma_n_rad**2
    var_e = model.sigma_e_rad**2 if quantized else 0.0
    var_r = var_n + var_e
    q = _step_covariance(model.sigma_v_rad_rt_s, model.sigma_u_rad_s_rt_s, dt)
    q_dd, q_db, q_bb = float(q[0, 0]), float(q[0, 1]), float(q[1, 1])
    if p0 is None:
        p0 = steady_state_post(model, quantized)
    p0 = np.asarray(p0, dtype=float)
    p_dd, p_db, p_bb = float(p0[0, 0]), float(p0[0, 1]), float(p0[1, 1])
    rows = np.empty((9, samples))
    for k in range(samples):
        # Propagation: d gains b dt, plus the integrated noises.
        p_dd, p_db, p_bb = (p_dd + 2.0 * dt * p_db + dt * dt * p_bb + q_dd,
                            p_db + dt * p_bb + q_db, p_bb + q_bb)
        s = p_dd + var_r  # innovation variance
        att_pre = p_dd + var_e
        k_d, k_b = p_dd / s, p_db / s
        rows[:, k] = (att_pre, var_n * att_pre / s, p_bb, 0.0, -p_db, -var_n * p_db / s,
                      att_pre / s, k_d, -k_b)
        # Update; the subtracted products keep the smaller terms' precision.
        p_dd, p_db, p_bb = p_dd * var_r / s, p_db * var_r / s, p_bb - p_db * k_b
        rows[3, k] = p_bb
    return Covariance(np.sqrt(rows[0]), np.sqrt(rows[1]), np.sqrt(rows[2]), np.sqrt(rows[3]),
                      rows[4], rows[5], rows[6], rows[7], rows[8])


def steady_state_post(model: AxisModel, quantized=True) -> np.ndarray:
    """Closed-form post-update covariance of (drift angle, bias), shape (2, 2).

    ``P_dd^+ = R (1 - xi^-2)`` and ``P_db^+ = (R/dt) S_u / xi`` (Farrenkopf's
    table with ``R = sigma_n^2 + sigma_e^2``; the drift angle has the opposite
    sign of the attitude error, so its covariance with the bias is positive).
    ``model`` is the axis's :class:`AxisModel`; ``quantized`` as for
    :func:`closed_form` (with the counter's readout noise ``sigma_e``).
    """
    acc = closed_form(model, quantized)
    var_r = model.sigma_n_rad**2 + (model.sigma_e_rad**2 if quantized else 0.0)
    p_dd = var_r * acc.gain_attitude_propagated
    # P_db^+ = R/dt S_u/xi = -R gain_bias (gain_bias = -S_u/(dt xi)).
    p_db = -var_r * acc.gain_bias_per_s
    return np.array([[p_dd, p_db], [p_db, acc.bias_post_rad_s**2]])


class FilterOutput(NamedTuple):
    """Estimates per sample, shape (runs, samples)."""

    attitude_pre_rad: np.ndarray  #: [rad] before the optical update
    attitude_post_rad: np.ndarray  #: [rad] after it
    bias_pre_rad_s: np.ndarray  #: [rad/s] drift-bias estimate before the update
    bias_post_rad_s: np.ndarray  #: [rad/s] after it


def filter_counter(model: AxisModel, counter_angle_rad, optical_angle_rad, drift0_rad,
                   bias0_rad_s, p0=None) -> FilterOutput:
    """Filter counter readouts and optical angles (the rate-integrating form).

    The filter carries the drift-angle estimate ``d^`` and the bias estimate
    ``b^``; the attitude is the counter's angle minus ``d^``. Its innovation
    is the optical angle minus that attitude; ``d^`` takes the carried gain,
    the attitude the full one (the rest is the present readout error, not
    carried, ``docs/kalman.md``). Gains come from :func:`covariance_history`.

    Parameters
    ----------
    model : AxisModel
    counter_angle_rad, optical_angle_rad : array_like, shape (runs, samples)
        Counter content x pulse weight, and the optical sensor's angle [rad].
    drift0_rad, bias0_rad_s : array_like, shape (runs,)
        Estimates at t = 0 of the drift angle (counter angle - true angle) [rad]
        and the bias [rad/s].
    p0 : array_like (2, 2) or None
        Their covariance; ``None`` = the closed-form steady state.

    Returns
    -------
    FilterOutput
    """
    z = np.asarray(counter_angle_rad, dtype=float)
    y = np.asarray(optical_angle_rad, dtype=float)
    gains = covariance_history(model, z.shape[1], True, p0)
    return _run(model.dt_s, gains, z, y, drift0_rad, bias0_rad_s)


def filter_rate_gyro(model: AxisModel, gyro_angle_rad, optical_angle_rad, attitude0_rad,
                     bias0_rad_s, p0=None) -> FilterOutput:
    """Farrenkopf's filter on the gyro's unquantised angle and the optical angle.

    It propagates with the gyro's angle increments and updates on the sensor,
    ``theta^ <- theta^ + (gyro angle increment) - b^ dt``, then ``theta^ +=
    K_theta nu``, ``b^ += K_b nu`` with ``nu`` the optical angle minus
    ``theta^``. Gains from :func:`covariance_history` with ``sigma_e = 0``.

    Parameters
    ----------
    model : AxisModel
    gyro_angle_rad, optical_angle_rad : array_like, shape (runs, samples)
        The gyro's integrated (unquantised) angle and the optical angle [rad].
    attitude0_rad, bias0_rad_s : array_like, shape (runs,)
        Estimates at t = 0 [rad, rad/s]; the gyro angle at t = 0 is taken as 0.
    p0 : array_like (2, 2) or None
        Covariance of (gyro angle - true angle, bias) at t = 0; ``None`` = steady state.

    Returns
    -------
    FilterOutput
    """
    phi = np.asarray(gyro_angle_rad, dtype=float)
    y = np.asarray(optical_angle_rad, dtype=float)
    gains = covariance_history(model, phi.shape[1], False, p0)
    dt = model.dt_s
    theta_hat = np.array(attitude0_rad, dtype=float)
    bias_hat = np.array(bias0_rad_s, dtype=float)
    out = FilterOutput(*(np.empty_like(phi) for _ in range(4)))
    previous = np.zeros(phi.shape[0])
    for k in range(phi.shape[1]):
        theta_hat = theta_hat + (phi[:, k] - previous) - bias_hat * dt
        previous = phi[:, k]
        out.attitude_pre_rad[:, k] = theta_hat
        out.bias_pre_rad_s[:, k] = bias_hat
        nu = y[:, k] - theta_hat
        theta_hat = theta_hat + gains.gain_attitude[k] * nu
        bias_hat = bias_hat + gains.gain_bias_per_s[k] * nu
        out.attitude_post_rad[:, k] = theta_hat
        out.bias_post_rad_s[:, k] = bias_hat
    return out


def _run(dt, gains, z, y, drift0, bias0):
    """The rate-integrating filter's loop over samples, vectorised over runs."""
    drift_hat = np.array(np.broadcast_to(drift0, (z.shape[0],)), dtype=float)
    bias_hat = np.array(np.broadcast_to(bias0, (z.shape[0],)), dtype=float)
    out = FilterOutput(*(np.empty_like(z) for _ in range(4)))
    for k in range(z.shape[1]):
        drift_hat = drift_hat + bias_hat * dt
        attitude = z[:, k] - drift_hat
        out.attitude_pre_rad[:, k] = attitude
        out.bias_pre_rad_s[:, k] = bias_hat
        nu = y[:, k] - attitude
        out.attitude_post_rad[:, k] = attitude + gains.gain_attitude[k] * nu
        drift_hat = drift_hat - gains.gain_attitude_propagated[k] * nu
        bias_hat = bias_hat + gains.gain_bias_per_s[k] * nu
        out.bias_post_rad_s[:, k] = bias_hat
    return out


# ------------------------------------------------------------------ Monte Carlo


class MonteCarloResult(NamedTuple):
    """Measured RMS errors over runs and a late window, beside the closed form."""

    measured: Covariance  #: RMS errors (sigmas) and mean products (covariances), scalars
    predicted: estimator_accuracy.SteadyStateAccuracy  #: closed form
    samples_used: int  #: [-] runs x window samples pooled in each RMS


def monte_carlo(model: AxisModel, runs, samples, seed, rate_rad_s=(1e-3, 5e-3),
                quantized=True, window=0.5, bias0_rad_s=0.0) -> MonteCarloResult:
    """Seeded Monte Carlo of the filter on :func:`simulate_hardware` data.

    Each run moves at a constant rate drawn uniform in ``rate_rad_s`` with a
    random sign (so the counter's fraction of a pulse runs through its range
    and is nearly white). The filter starts at the steady state: its initial
    estimates are the truth minus errors drawn from the closed-form
    post-update covariance (the bias error settles with a time constant of
    about ``sigma_v / sigma_u``, some 1800 s for the default gyro, longer
    than is worth simulating). The counter's mean readout error, half a
    pulse behind the motion, is put in the initial drift-angle estimate; it
    is an offset, not noise (:func:`allsky.studies.estimator_accuracy.quantization_sigma_rad`).

    Parameters
    ----------
    model : AxisModel
    runs, samples : int
        Number of runs and samples per run.
    seed : int
        Seeds the rates, the initial errors and the hardware record.
    rate_rad_s : (float, float)
        Range of the magnitude of the true rate [rad/s].
    quantized : bool
        Filter the counter (True) or, with Farrenkopf's filter, the gyro's
        unquantised angle (False).
    window : float
        Fraction of each run, at its end, pooled in the RMS.
    bias0_rad_s : float
        True drift bias at t = 0 [rad/s].

    Returns
    -------
    MonteCarloResult
    """
    rng = np.random.default_rng(seed)
    rate = rng.uniform(*rate_rad_s, runs) * rng.choice((-1.0, 1.0), runs)
    p0 = steady_state_post(model, quantized)
    err0 = np.linalg.cholesky(p0) @ rng.standard_normal((2, runs))
    rec = simulate_hardware(model, rate, samples, int(rng.integers(2**63)), bias0_rad_s)
    bias_hat0 = rec.bias0_rad_s - err0[1]
    if quantized:
        # The counter angle - true angle is the drift angle + (residue at t = 0 -
        # residue now) x weight; the filter's drift angle holds the mean of that,
        # residue0 - half a pulse with the sign of the motion.
        offset_rad = ((rec.residue0_pulses - 0.5 * np.sign(rate))
                      * model.pulse_weight_arcsec * units.ARCSEC2RAD)
        est = filter_counter(model, rec.counter_angle_rad, rec.optical_angle_rad,
                             offset_rad - err0[0], bias_hat0, p0)
    else:
        est = filter_rate_gyro(model, rec.gyro_angle_rad, rec.optical_angle_rad,
                               err0[0], bias_hat0, p0)  # attitude error = -(drift error)
    first = round(samples * (1.0 - window))
    late = slice(first, samples)
    a_pre = (rec.true_angle_rad - est.attitude_pre_rad)[:, late]
    a_post = (rec.true_angle_rad - est.attitude_post_rad)[:, late]
    b_pre = (rec.bias_rad_s - est.bias_pre_rad_s)[:, late]
    b_post = (rec.bias_rad_s - est.bias_post_rad_s)[:, late]

    def rms(x):
        return float(np.sqrt(np.mean(x * x)))

    measured = Covariance(rms(a_pre), rms(a_post), rms(b_pre), rms(b_post),
                          float(np.mean(a_pre * b_pre)), float(np.mean(a_post * b_post)),
                          np.nan, np.nan, np.nan)
    return MonteCarloResult(measured, closed_form(model, quantized), a_pre.size)


# ------------------------------------------------------------------ figure data


class Convergence(NamedTuple):
    """Filter sigmas against time from an uncertain start, and the closed form."""

    time_s: np.ndarray  #: [s] sample times
    history: Covariance  #: per sample
    steady: estimator_accuracy.SteadyStateAccuracy  #: closed form


def convergence(model: AxisModel, duration_s, attitude0_rad, bias0_rad_s,
                quantized=True) -> Convergence:
    """Data for a figure: the filter's sigmas converging to the closed form.

    Attitude and bias sigmas, before and after each update, against time.

    Parameters
    ----------
    model : AxisModel
    duration_s : float
        Length of the record [s].
    attitude0_rad, bias0_rad_s : float
        Initial uncertainty (1 sigma) of drift angle and bias [rad, rad/s].
    quantized : bool
        Counter readout or unquantised rate gyro.

    Returns
    -------
    Convergence
    """
    samples = math.ceil(duration_s / model.dt_s - 1e-9)  # 200 / 0.01 is 20000.000000000004
    p0 = np.diag([attitude0_rad**2, bias0_rad_s**2])
    return Convergence(model.dt_s * np.arange(1, samples + 1),
                       covariance_history(model, samples, quantized, p0),
                       closed_form(model, quantized))


# ------------------------------------------------------------------ on the emulator's blocks


class EmulatedResult(NamedTuple):
    """RMS errors of the filter on the emulator's own blocks, and the closed form."""

    measured: Covariance  #: RMS errors over runs and the late window (gains nan)
    predicted: estimator_accuracy.SteadyStateAccuracy  #: closed form
    samples_used: int  #: [-] runs x window samples pooled in each RMS
    duration_s: float  #: [s] length of each run


@njit
def _emulated_runs(gyro_p, vfc_p, trk_p, frame_s, fps, samples, late_from, rates, seeds,
                   amplitude, gains, weight_rad, counter_bits, rng, dtheta, bias_rw, gyro_out, residue, counter,
                   overflow, trk_out, lock, q, sums):
    """Runs of one axis through the emulator's gyro, converter, counter and tracker.

    Per run: the body rolls (about x, the Sun line) back and forth at
    ``+-rates[r]`` between ``+-amplitude`` (a triangle wave, reversing on frame
    boundaries): the star stays in the tracker's slit while the converter's
    fraction of a pulse sweeps its range. Every frame :func:`allsky.hardware.gyro.gyro_output` measures it (drift,
    rate random walk stepped once a second as the frame loop steps it, angle
    random walk), converter 8 (:func:`allsky.hardware.vfc.vfc`) turns it into
    pulses for counter 14 (:func:`allsky.hardware.updown_counter.count`);
    every ``fps`` frames the counter and the star tracker 105's yaw output
    (:func:`allsky.hardware.star_tracker.star_tracker`; a star on inertial z,
    whose yaw output is minus the roll) are filtered as :func:`filter_counter`
    does (``lock`` is the tracker's memory, :func:`allsky.hardware.star_tracker.new_lock`:
    the one star never leaves the slit). Counter 14 has the scenario's word length and
    saturates (a run that reaches its end is refused). The estimates start at the truth (zero
    error); the squared errors
    from sample ``late_from`` on are summed into ``sums`` (runs, 6): attitude
    before and after the update, bias before and after, and the two
    attitude-bias products.
    """
    k_att, k_carry, k_bias = gains[0], gains[1], gains[2]
    dt = frame_s * fps
    rrw_every = max(1, round(RRW_STEP_S / frame_s))
    for r in range(rates.shape[0]):
        seed(rng, seeds[r])
        for i in range(3):
            bias_rw[i] = 0.0
            residue[i] = 0.0
            dtheta[i] = 0.0
        counter[0] = 0
        theta = 0.0
        quarter = max(1, round(amplitude / (abs(rates[r]) * frame_s)))
        drift_hat = 0.0  # counter angle - true angle at t = 0
        bias_hat = gyro_p.drift_arcsec_s[0] * ARCSEC2RAD  # the truth: zero error
        frame = 0
        for k in range(samples):
            for _ in range(fps):
                c = frame % (4 * quarter)
                dtheta[0] = rates[r] * frame_s * (1.0 if c < quarter or c >= 3 * quarter
                                                  else -1.0)
                gyro_output(gyro_p, dtheta, frame_s, bias_rw, gyro_out, frame % rrw_every == 0,
                            rng)
                count(counter, 0, vfc(vfc_p, 0, gyro_out[0], frame_s, residue), counter_bits,
                      SATURATE, overflow, 0)
                theta += dtheta[0]
                frame += 1
            h = 0.5 * theta
            q[0], q[1], q[2], q[3] = math.cos(h), math.sin(h), 0.0, 0.0
            star_tracker(trk_p, q, lock, trk_out, rng)
            y = -trk_out[0] * ARCSEC2RAD
            z = counter[0] * weight_rad
            bias_true = (gyro_p.drift_arcsec_s[0] + bias_rw[0]) * ARCSEC2RAD
            drift_hat += bias_hat * dt
            attitude = z - drift_hat
            nu = y - attitude
            post = attitude + k_att * nu
            if k >= late_from:
                e_pre, e_post = theta - attitude, theta - post
                b_pre = bias_true - bias_hat
                sums[r, 0] += e_pre * e_pre
                sums[r, 1] += e_post * e_post
                sums[r, 2] += b_pre * b_pre
                sums[r, 4] += e_pre * b_pre
            drift_hat -= k_carry * nu
            bias_hat += k_bias * nu
            if k >= late_from:
                b_post = bias_true - bias_hat
                sums[r, 3] += b_post * b_post
                sums[r, 5] += (theta - post) * b_post


#: [rad] Half the roll swing of :func:`emulated_monte_carlo` (inside the tracker's slit).
SWING_RAD = math.radians(1.5)


def emulated_monte_carlo(cfg, runs, duration_s, frames_per_sample, seed,
                         rate_rad_s=(1e-3, 5e-3), window=0.5) -> EmulatedResult:
    """The filter on the emulator's own gyro, converter, counter and star tracker.

    Unlike :func:`monte_carlo`, nothing here shares the filter's noise
    model: the data come from the blocks the frame loop flies
    (:func:`_emulated_runs`; the scenario's gyro with its drift, angle and
    rate random walks, the gyro's sensitivity taken as one), and the filter
    starts at the truth, so that every error it shows is its own. Runs last
    ``duration_s``, several of the bias's time constants (about 1800 s for
    the default gyro), and the last ``window`` of each is pooled.

    Parameters
    ----------
    cfg : allsky.config.Scenario
    runs : int
    duration_s : float
        [s] Length of each run.
    frames_per_sample : int
        Frames between the filter's samples.
    seed : int
        Seeds the rates and each run's noise.
    rate_rad_s : (float, float)
        Range of the magnitude of the roll rate [rad/s] (random sign), swung
        between +-:data:`SWING_RAD`.
    window : float
        Fraction of each run, at its end, pooled in the RMS.
    """
    from allsky.sim.mission import build_params

    model = axis_model(cfg, "star_tracker", frames_per_sample)
    p = build_params(cfg)
    g = p.gyro._replace(sensitivity=np.eye(3))
    trk = p.tracker._replace(stars_inertial=np.array([[0.0, 0.0, 1.0]]))
    samples = math.ceil(duration_s / model.dt_s - 1e-9)
    cov = covariance_history(model, 1, True)  # starts, and stays, at the steady state
    gains = np.array([cov.gain_attitude[0], cov.gain_attitude_propagated[0],
                      cov.gain_bias_per_s[0]])
    rng = np.random.default_rng(seed)
    rates = rng.uniform(*rate_rad_s, runs) * rng.choice((-1.0, 1.0), runs)
    seeds = rng.integers(0, 2**62, runs)
    late_from = round(samples * (1.0 - window))
    sums = np.zeros((runs, 6))
    overflow_flag = np.zeros(6, dtype=np.bool_)
    _emulated_runs(g, p.vfc, trk, float(p.frame_s), int(frames_per_sample), samples, late_from,
                   rates, seeds, SWING_RAD, gains, model.pulse_weight_arcsec * units.ARCSEC2RAD,
                   int(p.electronics.counter_bits), np.zeros(1, dtype=np.uint64), np.zeros(3), np.zeros(3), np.zeros(3),
                   np.zeros(3), np.zeros(3, dtype=np.int64), overflow_flag,
                   np.zeros(3), new_lock(), np.zeros(4), sums)
    if overflow_flag[0]:
        raise ValueError("counter 14 saturated: a shorter run or a slower rate")
    used = runs * (samples - late_from)
    tot = sums.sum(axis=0) / used
    measured = Covariance(*(float(np.sqrt(v)) for v in tot[0:4]), float(tot[4]), float(tot[5]),
                          np.nan, np.nan, np.nan)
    return EmulatedResult(measured, closed_form(model, True), used, samples * model.dt_s)
