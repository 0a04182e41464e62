"""Rate gyros 1, 2, 3 (allsky.hardware.gyro) against their error model and its units.

Truth:
- with the noise off, the output is the linear model of the module docstring,
  rate = S (dtheta/dt) + drift, and it saturates at the range;
- unit conversions: 1 deg/h = 3600"/3600 s = 1 "/s; 1 deg/sqrt(h) = 3600"/60 sqrt(s)
  = 60 "/sqrt(s); 1 deg/h/sqrt(h) = 1/60 "/s/sqrt(s); 1 ppm = 1e-6;
  1" = pi/648000 rad;
- white rate noise of density N integrates to an angle random walk of standard
  deviation N sqrt(T); a bias driven by white noise of density K walks with
  standard deviation K sqrt(T) (IEEE Std 952-1997, annex C, angle and rate
  random walk);
- calibration definitions (SPEC section 4): scale factor = true angle /
  counted angle, cross-coupling = counts on the other axis / true angle.
"""

import math

import numpy as np
import pytest

from allsky import gauss, units
from allsky.hardware.gyro import (
    RRW_STEP_S,
    GyroParams,
    gyro_output,
    make_params,
    perfect_calibration,
)

# Default scenario values (src/allsky/scenarios/default.toml).
DRIFT_DEG_H = [1.2, -0.8, 1.5]
SF_PPM = [1500.0, -2000.0, 2500.0]
MISALIGN_ARCSEC = [[0.0, 120.0, -150.0], [180.0, 0.0, 90.0], [-200.0, 60.0, 0.0]]
ARW_DEG_RT_H = 0.001
RRW_DEG_H_RT_H = 0.002
RANGE_DEG_S = 10.0
DT_S = 0.01  # [s] mission frame


RNG = gauss.new_generator()  #: the noise generator these tests' blocks draw from


def seed(s):
    """Seed the generator the blocks draw from."""
    gauss.seed(RNG, s)


def params(drift=DRIFT_DEG_H, sf=SF_PPM, mis=MISALIGN_ARCSEC, arw=0.0, rrw=0.0,
           range_deg_s=RANGE_DEG_S):
    return make_params(drift, sf, mis, arw, rrw, range_deg_s)


def read(p, dtheta_rad, dt_s=DT_S, bias=None, step_bias=False):
    out = np.zeros(3)
    gyro_output(p, np.asarray(dtheta_rad, dtype=float), dt_s,
                np.zeros(3) if bias is None else bias, out, step_bias, RNG)
    return out


def test_make_params_units():
    p = params(arw=ARW_DEG_RT_H, rrw=RRW_DEG_H_RT_H)
    assert isinstance(p, GyroParams)
    # 1 deg/h = 1 arcsec/s.
    assert np.array_equal(p.drift_arcsec_s, DRIFT_DEG_H)
    # ARW 0.001 deg/sqrt(h): after one hour the angle spreads by 0.001 deg = 3.6".
    assert p.arw_arcsec_rt_s * math.sqrt(units.HOUR_S) == pytest.approx(3.6, rel=1e-15)
    # RRW 0.002 deg/h/sqrt(h): after one hour the bias spreads by 0.002 deg/h = 0.002 "/s.
    assert p.rrw_arcsec_s_rt_s * math.sqrt(units.HOUR_S) == pytest.approx(0.002, rel=1e-15)
    assert p.range_arcsec_s == 36000.0  # 10 deg/s
    asec = math.pi / 648000.0
    for i in range(3):
        for j in range(3):
            expected = (1.0 + SF_PPM[i] * 1e-6) * ((i == j) + (i != j) * MISALIGN_ARCSEC[i][j] * asec)
            assert p.sensitivity[i, j] == pytest.approx(expected, rel=1e-15)


def test_make_params_ignores_a_diagonal_misalignment():
    # The diagonal is the scale-factor error's job; a misalignment there is dropped.
    mis = np.array(MISALIGN_ARCSEC)
    np.fill_diagonal(mis, 500.0)
    assert np.array_equal(params(mis=mis).sensitivity, params().sensitivity)


def test_known_rotation_about_roll_gives_the_model_output_exactly():
    p = params()
    rate_deg_s = 1.0
    dtheta = np.array([rate_deg_s * units.DEG2RAD * DT_S, 0.0, 0.0])
    out = read(p, dtheta)
    s = p.sensitivity
    # 1 deg/s about body x: gyro i reads S[i, 0] * 3600 "/s plus its drift.
    expected = s[:, 0] * 3600.0 + np.array(DRIFT_DEG_H)
    assert np.allclose(out, expected, rtol=1e-14, atol=0)
    assert out[0] == pytest.approx(3600.0 * (1 + 1500e-6) + 1.2, rel=1e-14)


@pytest.mark.parametrize("dtheta", [[2e-4, -1e-4, 3e-5], [0.0, 0.0, -5e-4], [0.0, 0.0, 0.0]])
def test_general_increment_matches_the_linear_model(dtheta):
    p = params()
    out = read(p, dtheta)
    expected = p.sensitivity @ np.array(dtheta) / DT_S * units.RAD2ARCSEC + p.drift_arcsec_s
    assert np.allclose(out, expected, rtol=1e-14, atol=1e-12)


def test_saturation_at_the_range():
    p = params()
    big = 20.0 * units.DEG2RAD * DT_S  # 20 deg/s against a 10 deg/s range
    assert np.array_equal(read(p, [big, -big, big]), [36000.0, -36000.0, 36000.0])
    # Just inside the range the output is unclipped.
    inside = read(p, [9.0 * units.DEG2RAD * DT_S, 0.0, 0.0])
    assert 32000.0 < inside[0] < 36000.0


@pytest.mark.parametrize("axis, name, others", [
    (0, "roll", {"roll_into_pitch": 1, "roll_into_yaw": 2}),
    (2, "yaw", {"yaw_into_pitch": 1, "yaw_into_roll": 0}),
])
def test_perfect_calibration_is_what_a_full_turn_measures(axis, name, others):
    # Turn 360 deg about one body axis at 1.5 deg/s (the rate command) and count
    # the integrated gyro outputs, drift and noise off (SPEC section 4 definitions).
    p = params(drift=[0.0, 0.0, 0.0])
    rate_rad_s = 1.5 * units.DEG2RAD
    n = round(2 * math.pi / rate_rad_s / DT_S)
    dtheta = np.zeros(3)
    dtheta[axis] = 2 * math.pi / n
    counted_arcsec = read(p, dtheta) * DT_S * n  # every frame reads the same
    true_arcsec = 360.0 * 3600.0
    cal = perfect_calibration(p)
    assert cal["scale_factor"][name] == pytest.approx(true_arcsec / counted_arcsec[axis], rel=1e-13)
    for key, other in others.items():
        assert cal["cross_coupling"][key] == pytest.approx(
            counted_arcsec[other] / true_arcsec, rel=1e-12)
    # And against the scenario numbers: 1 / (1 + sf).
    assert cal["scale_factor"][name] == pytest.approx(1.0 / (1.0 + SF_PPM[axis] * 1e-6), rel=1e-15)


def test_perfect_calibration_drift_is_the_bias():
    cal = perfect_calibration(params())
    assert cal["drift_deg_h"] == {"roll": 1.2, "pitch": -0.8, "yaw": 1.5}


def integrated_angles(p, n_trials, n_frames, dt_s):
    """Integrated output [arcsec] of each trial (drift-free, at rest)."""
    out = np.zeros(3)
    zero = np.zeros(3)
    bias = np.zeros(3)
    angles = np.zeros((n_trials, 3))
    for t in range(n_trials):
        acc = np.zeros(3)
        for _ in range(n_frames):
            gyro_output(p, zero, dt_s, bias, out, False, RNG)
            acc += out
        angles[t] = acc * dt_s
    return angles


def test_angle_random_walk_grows_as_n_sqrt_t():
    p = params(drift=[0, 0, 0], sf=[0, 0, 0], mis=np.zeros((3, 3)), arw=ARW_DEG_RT_H)
    seed(11)
    t_s = 1.0
    angles = integrated_angles(p, 2000, round(t_s / DT_S), DT_S).ravel()
    sigma = p.arw_arcsec_rt_s * math.sqrt(t_s)  # IEEE 952 annex C: N sqrt(T)
    # 6000 samples: the sample std has a relative standard error 1/sqrt(2*6000) = 0.9 %.
    assert np.std(angles) == pytest.approx(sigma, rel=0.05)
    assert abs(np.mean(angles)) < 5 * sigma / math.sqrt(angles.size)


def test_arw_does_not_depend_on_the_frame():
    # The same density over a coarser frame gives the same spread of the angle.
    p = params(drift=[0, 0, 0], sf=[0, 0, 0], mis=np.zeros((3, 3)), arw=ARW_DEG_RT_H)
    seed(12)
    angles = integrated_angles(p, 2000, 10, 0.1).ravel()
    assert np.std(angles) == pytest.approx(p.arw_arcsec_rt_s * 1.0, rel=0.05)


def test_noise_is_the_generators_normal_sequence():
    # One frame at rest with only ARW on: out[i] = N / sqrt(dt) * z_i with z the
    # standard normals of the noise generator for that seed.
    p = params(drift=[0, 0, 0], sf=[0, 0, 0], mis=np.zeros((3, 3)), arw=ARW_DEG_RT_H)
    seed(3)
    out = read(p, [0.0, 0.0, 0.0])
    rng = gauss.new_generator(3)
    z = np.array([gauss.standard_normal(rng) for _ in range(3)])
    assert np.allclose(out, p.arw_arcsec_rt_s / math.sqrt(DT_S) * z, rtol=1e-14, atol=0)


def test_rate_random_walk_grows_as_k_sqrt_t():
    p = params(drift=[0, 0, 0], sf=[0, 0, 0], mis=np.zeros((3, 3)), rrw=RRW_DEG_H_RT_H)
    seed(21)
    n_trials, n_steps = 2000, 25
    zero = np.zeros(3)
    out = np.zeros(3)
    quarter = np.zeros((n_trials, 3))
    final = np.zeros((n_trials, 3))
    for t in range(n_trials):
        bias = np.zeros(3)
        for k in range(n_steps):
            # The bias steps once per RRW_STEP_S of mission time.
            gyro_output(p, zero, DT_S, bias, out, True, RNG)
            if k + 1 == n_steps // 4 + 1:
                quarter[t] = out
        assert np.array_equal(out, bias)  # no ARW or drift: the output is the walk
        final[t] = bias
    k_density = p.rrw_arcsec_s_rt_s
    t_final = n_steps * RRW_STEP_S
    t_quarter = (n_steps // 4 + 1) * RRW_STEP_S
    assert np.std(final) == pytest.approx(k_density * math.sqrt(t_final), rel=0.05)
    assert np.std(quarter) == pytest.approx(k_density * math.sqrt(t_quarter), rel=0.05)


def test_bias_does_not_walk_between_steps():
    p = params(drift=[0, 0, 0], rrw=RRW_DEG_H_RT_H)
    bias = np.array([0.1, -0.2, 0.3])
    seed(1)
    read(p, [0, 0, 0], bias=bias, step_bias=False)
    assert np.array_equal(bias, [0.1, -0.2, 0.3])


def test_same_seed_same_output():
    p = params(arw=ARW_DEG_RT_H, rrw=RRW_DEG_H_RT_H)
    runs = []
    for _ in range(2):
        seed(42)
        bias = np.zeros(3)
        runs.append(np.array([read(p, [1e-5, 0, 0], bias=bias, step_bias=k % 100 == 0)
                              for k in range(300)]))
    assert np.array_equal(runs[0], runs[1])
    seed(43)
    assert not np.array_equal(read(p, [1e-5, 0, 0]), runs[0][0])
