"""The Cramer-Rao bound of the calibration (allsky.studies.crlb).

Truth from closed forms and from an efficient estimator written here from
the physics, not from the module:

* a still vehicle with perfect optics: the drift bound is the angle random
  walk's N / sqrt(T) (the mean of white rate noise); with a perfect gyro it
  is the optics' least-squares slope, sigma_n / sqrt(sum (t - t_mean)^2);
* a long hold with a rate random walk: the bound tends to Farrenkopf's
  steady-state drift and attitude variances (allsky.studies.estimator_accuracy);
* a roll oscillation seen by the tracker, where every output is linear in
  the unknowns: generalised least squares (written out below, with the
  random walk's full covariance) is efficient; its covariance and the
  Monte Carlo spread of its estimates both match the bound.
"""

import math

import numpy as np
import pytest

from allsky import units
from allsky.config import load_scenario
from allsky.studies import crlb, estimator_accuracy
from allsky.studies import kalman_mekf as K

ARW = 0.06 * units.ARCSEC2RAD  # [rad/s^0.5] the default gyro's angle random walk
SUN_N, TRK_N = 0.5 * units.ARCSEC2RAD, 2.0 * units.ARCSEC2RAD  # [rad] default optics


def _model(arw=ARW, rrw=0.0, sun=SUN_N, trk=TRK_N, frame_s=0.01):
    """Sun along inertial x, one star along inertial z, no readout noise."""
    return K.FilterModel(arw_rad_rt_s=arw, rrw_rad_s_rt_s=rrw, sun_noise_rad=sun,
                         tracker_noise_rad=trk, readout_rad=0.0, sun_linear_rad=0.1,
                         sun0_inertial=np.array([1.0, 0.0, 0.0]),
                         sun_rate_inertial=np.zeros(3),
                         stars_inertial=np.array([[0.0, 0.0, 1.0]]), frame_s=frame_s)


def _samples(q, dt, gyro, tracker_yaw=None, sun=True):
    """Samples of a vehicle at attitudes ``q`` (n, 4) with gyro increments ``gyro`` (n, 3)."""
    n = q.shape[0]
    trk = np.zeros((n, 3))
    trk[:, K.VALID] = 1.0
    if tracker_yaw is not None:
        trk[:, 0] = tracker_yaw
    s = np.zeros((n, 3))
    s[:, K.VALID] = 1.0 if sun else 0.0
    t = dt * np.arange(1, n + 1)
    return K.Samples(t, np.full(n, dt), gyro, s, trk, np.zeros(n), q,
                     np.full((n, 3), np.nan), np.zeros(n, dtype=bool))


def _still(n, dt):
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return _samples(q, dt, np.zeros((n, 3)))


def _drift_sigma(cov):
    return np.sqrt(np.diag(cov)[K.BIAS:K.BIAS + 3])


def test_still_vehicle_with_perfect_optics_gives_the_angle_random_walk_limit():
    """sigma_b = N / sqrt(T): the increments are the drift plus white noise."""
    n, dt = 400, 0.1
    model = _model(sun=1e-12, trk=1e-12)
    s = _still(n, dt)
    cov = crlb.bound_covariance(model, crlb.linearise(model, s, np.zeros(12)))
    # The optics see the attitude at every sample from the first to the last:
    # (n - 1) increments between them.
    expected = ARW / math.sqrt((n - 1) * dt)
    assert _drift_sigma(cov) == pytest.approx(np.full(3, expected), rel=1e-4)


def test_still_vehicle_with_a_perfect_gyro_gives_the_optical_slope_limit():
    """sigma_b^2 = 1 / (sum (t - t_mean)^2 sum_outputs 1/sigma^2): roll by the
    tracker's yaw output, pitch by sun pitch and tracker pitch, yaw by sun yaw."""
    n, dt = 400, 0.1
    model = _model(arw=1e-15)
    s = _still(n, dt)
    cov = crlb.bound_covariance(model, crlb.linearise(model, s, np.zeros(12)))
    t = s.time_s
    sxx = np.sum((t - t.mean()) ** 2)
    expected = np.array([1 / math.sqrt(sxx / TRK_N ** 2),
                         1 / math.sqrt(sxx * (1 / SUN_N ** 2 + 1 / TRK_N ** 2)),
                         1 / math.sqrt(sxx / SUN_N ** 2)])
    assert _drift_sigma(cov) == pytest.approx(expected, rel=1e-3)


def test_long_hold_reaches_farrenkopfs_steady_state():
    """With a rate random walk the bound settles at the steady-state filter's variances.

    1 s samples for 30 000 s (the drift pole is ~1800 s); per axis the
    optics' combined noise (pitch has two outputs).
    """
    rrw = 0.002 * units.DEG2RAD / units.HOUR_S / math.sqrt(units.HOUR_S)
    n, dt = 30000, 1.0
    model = _model(rrw=rrw)
    cov = crlb.bound_covariance(model, crlb.linearise(model, _still(n, dt), np.zeros(12)))
    sig_n = [TRK_N, 1 / math.sqrt(1 / SUN_N ** 2 + 1 / TRK_N ** 2), SUN_N]
    for axis, sn in enumerate(sig_n):
        ss = estimator_accuracy.farrenkopf(ARW, rrw, sn, dt)
        assert math.sqrt(cov[K.BIAS + axis, K.BIAS + axis]) == pytest.approx(
            float(ss.bias_post_rad_s), rel=1e-6)
        assert math.sqrt(cov[axis, axis]) == pytest.approx(float(ss.attitude_post_rad),
                                                           rel=1e-6)


def _oscillation(n, dt, amp_rad, period_s, sf_ppm, rng=None):
    """A roll oscillation theta = A sin(w t) about body x (the Sun's axis).

    Returns the true roll at the initial epoch and the samples, the gyro's
    increments with the roll scale-factor error and (with ``rng``) the angle
    random walk, the tracker's yaw output ``-theta`` (a roll about x turns
    the star on z to ``(0, sin, cos)``, ``atan2(-s_y, s_z) = -theta``) with
    its noise.
    """
    t = dt * np.arange(0, n + 1)
    theta = amp_rad * np.sin(2 * math.pi * t / period_s)
    q = np.column_stack((np.cos(theta / 2), np.sin(theta / 2), np.zeros(n + 1),
                         np.zeros(n + 1)))[1:]
    gyro = np.zeros((n, 3))
    gyro[:, 0] = (1 + sf_ppm * 1e-6) * np.diff(theta)
    yaw = -theta[1:]
    if rng is not None:
        gyro += ARW * math.sqrt(dt) * rng.standard_normal((n, 3))
        yaw = yaw + TRK_N * rng.standard_normal(n)
    return theta[0], _samples(q, dt, gyro, yaw, sun=False)


def _noise_factor(n, dt):
    """Cholesky factor of the noise covariance of :func:`_gls`'s model (the same every run)."""
    from scipy.linalg import cho_factor

    k = np.arange(1, n + 1)
    return cho_factor(ARW ** 2 * dt * np.minimum.outer(k, k) + TRK_N ** 2 * np.eye(n))


def _gls(y_roll, z, dt, factor=None):
    """Generalised least squares of (theta0, b, e) from one axis, written from the physics.

    theta_k = theta0 + (1 + e) sum_j<=k (y_j - b dt) - (ARW sums), z_k = -theta_k + v_k;
    to first order in the small e and b, z_k + Y_k = -theta0 - e Y_k + b t_k + N_k + v_k
    with N the random walk, cov N_i N_j = ARW^2 dt min(i, j) (+1 each).
    Returns the estimates and their covariance.
    """
    from scipy.linalg import cho_solve

    n = y_roll.size
    y_cum = np.cumsum(y_roll)
    t = dt * np.arange(1, n + 1)
    g = np.column_stack((-np.ones(n), t, -y_cum))
    w = cho_solve(factor or _noise_factor(n, dt), g)
    cov = np.linalg.inv(g.T @ w)
    return cov @ (w.T @ (z + y_cum)), cov


def test_bound_equals_generalised_least_squares_and_its_monte_carlo_spread():
    """Linear case: roll 10 deg at 20 s, 60 s at 10 Hz, tracker 2" and ARW 0.06"/s^0.5.

    The bound's drift and E_roll (the roll gyro's inverse scale factor)
    against GLS's covariance (an independent derivation: 1e-3), and against
    the spread of GLS's estimates over 1500 noise draws (1500 runs: the
    sample sigma is good to 1.8 %, 1-sigma).
    """
    n, dt, amp, period, sf = 600, 0.1, math.radians(10.0), 20.0, 1000.0
    model = _model(frame_s=dt)
    _, clean = _oscillation(n, dt, amp, period, sf)
    e_true = 1 / (1 + sf * 1e-6) - 1
    truth = np.zeros(12)
    truth[K.E_INDEX[0, 0] - 3] = e_true
    cov = crlb.bound_covariance(model, crlb.linearise(model, clean, truth))
    bound = np.sqrt([cov[K.BIAS, K.BIAS], cov[K.SF, K.SF]])
    _, gls_cov = _gls(clean.gyro_rad[:, 0], clean.tracker[:, 0], dt)
    assert bound == pytest.approx(np.sqrt(np.diag(gls_cov))[1:], rel=1e-3)
    rng = np.random.default_rng(27)
    factor = _noise_factor(n, dt)
    est = []
    for _ in range(1500):
        _, s = _oscillation(n, dt, amp, period, sf, rng)
        beta, _ = _gls(s.gyro_rad[:, 0], s.tracker[:, 0], dt, factor)
        est.append([beta[1], beta[2] - e_true])
    spread = np.std(est, axis=0, ddof=1)
    assert spread == pytest.approx(bound, rel=0.06)
    # ... and unbiased: the means within 4 standard errors.
    assert np.all(np.abs(np.mean(est, axis=0)) < 4 * bound / math.sqrt(1500))


def test_bound_does_not_depend_on_the_weak_prior():
    """Observable states: a prior 10x weaker again moves no bound by 1 %."""
    n, dt = 600, 0.1
    model = _model(frame_s=dt)
    _, s = _oscillation(n, dt, math.radians(10.0), 20.0, 1000.0)
    lin = crlb.linearise(model, s, np.zeros(12))
    a = crlb.bound_covariance(model, lin, crlb.weak_prior(10.0))
    b = crlb.bound_covariance(model, lin, crlb.weak_prior(100.0))
    observable = [K.BIAS, K.BIAS + 1, K.BIAS + 2, K.SF]
    assert np.sqrt(np.diag(a)[observable]) == pytest.approx(np.sqrt(np.diag(b)[observable]),
                                                            rel=1e-2)


@pytest.fixture(scope="module")
def flown():
    return crlb.flown_bounds(load_scenario(overrides=["mission.seed=1"]))


def test_mode3_hold_shows_drift_only(flown):
    """40 s of hold: no scale factor or misalignment, the drift a little above N/sqrt(T)."""
    hold = flown["mode3_hold"]
    assert all(v is None for v in hold["scale_factor_ppm"].values())
    assert all(v is None for v in hold["misalignment_arcsec"].values())
    arw_limit = 0.06 / math.sqrt(40.0)  # [deg/h = arcsec/s] 0.0095
    for a in ("roll", "pitch", "yaw"):
        assert arw_limit < hold["drift_deg_h"][a] < 1.2 * arw_limit


def test_more_data_never_loosens_the_bound(flown):
    """Modes 3-5 together bound every quantity at least as tightly as each mode alone."""
    whole = flown["modes3_5"]
    for part in ("mode3_hold", "mode4_roll_turn", "mode5_yaw_turn"):
        for group in ("drift_deg_h", "scale_factor_ppm", "cross_coupling_arcsec",
                      "misalignment_arcsec"):
            for k, v in flown[part][group].items():
                if v is not None:
                    assert whole[group][k] <= v * (1 + 1e-9), (part, group, k)


def test_turns_carry_a_million_times_the_dither_holds_information(flown):
    """Roll scale factor: the turns' bound ~1 ppm, the dither hold's ~1200 ppm."""
    ratio = crlb.information_ratio(flown["modes3_5"], flown["dither_hold"])
    assert 3e5 < ratio < 1e7
    # The dither hold's bound beside the dither method's analytic figure (1265 ppm roll,
    # 598 yaw, docs/comparison.md): the bound cannot be above what a method reaches.
    assert flown["dither_hold"]["scale_factor_ppm"]["roll"] < 1265.0
    assert flown["dither_hold"]["scale_factor_ppm"]["yaw"] < 598.0
