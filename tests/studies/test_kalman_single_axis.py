"""Single-axis Kalman filter on the emulated hardware (allsky.studies.kalman_single_axis).

Truth:
- the converter arithmetic is that of ``allsky.hardware.vfc.vfc`` (compared
  element by element, bit for bit), and a counter fed by a converter that
  carries its residue holds the gyro angle in whole pulses, truncated toward
  zero while the motion keeps one sign;
- the default scenario's gyro: 0.001 deg/h^0.5 = 0.06 arcsec/s^0.5 and
  0.002 deg/h/h^0.5 = 0.002/60 arcsec/s^1.5 (``docs/kalman.md``, worked example);
- the filter's covariance recursion converges to the closed-form steady state
  of ``allsky.studies.estimator_accuracy`` (Farrenkopf 1978; the
  rate-integrating extension of ``docs/kalman.md``), to 1e-9 relative;
- seeded Monte Carlo runs of the hardware model, filtered, show the
  closed-form sigmas within 10 %: an RMS over N independent samples has a
  relative standard deviation of about 1/sqrt(2N), here 2 % or less.
"""

import math

import numpy as np
import pytest

from allsky import units
from allsky.config import load_scenario
from allsky.hardware import vfc
from allsky.studies import kalman_single_axis as ks

FIELDS = ("attitude_pre_rad", "attitude_post_rad", "bias_pre_rad_s", "bias_post_rad_s",
          "attitude_bias_pre_rad2_s", "attitude_bias_post_rad2_s", "gain_attitude",
          "gain_attitude_propagated", "gain_bias_per_s")
SIGMAS = FIELDS[:4]


@pytest.fixture(scope="module")
def default_model():
    return ks.axis_model(load_scenario())


def quantization_dominated(default_model):
    """5 arcsec pulses (sigma_e 1.44 arcsec) against the 0.5 arcsec sun sensor 104.

    The gyro's rate random walk is raised to 1 deg/h/h^0.5 so that its bias
    error settles in seconds (sigma_v / sigma_u = 3.6 s) and a short run
    measures it rather than its initial draw.
    """
    cfg = load_scenario()
    return ks.axis_model(cfg, sensor="sun_sensor")._replace(
        pulse_weight_arcsec=5.0,
        sigma_u_rad_s_rt_s=1.0 * units.DEG2RAD / units.HOUR_S / math.sqrt(units.HOUR_S))


def test_default_gyro_converts_to_the_worked_example(default_model):
    m = default_model
    assert m.sigma_v_rad_rt_s * units.RAD2ARCSEC == pytest.approx(0.06, rel=1e-12)
    assert m.sigma_u_rad_s_rt_s * units.RAD2ARCSEC == pytest.approx(0.002 / 60.0, rel=1e-12)
    assert m.sigma_n_rad * units.RAD2ARCSEC == pytest.approx(2.0, rel=1e-12)
    assert m.sigma_e_rad * units.RAD2ARCSEC == pytest.approx(0.1 / math.sqrt(12.0), rel=1e-12)
    assert m.dt_s == 0.01


def test_converter_is_the_hardware_vfc_bit_for_bit(default_model):
    m = default_model._replace(max_rate_pps=2000.0)
    rng = np.random.default_rng(7)
    rate = rng.normal(0.0, 100.0, 5000)  # [arcsec/s]; 1000 pulses/s typical, some saturated
    residue = rng.uniform(-1.0, 1.0, 5000)
    pulses, carried = ks.convert(m, rate, residue)
    p = vfc.VfcParams(m.pulse_weight_arcsec, m.max_rate_pps)
    for i in range(rate.size):
        r = np.array([residue[i]])
        n = vfc.vfc(p, 0, rate[i], m.frame_s, r)
        assert (pulses[i], carried[i]) == (n, r[0])


def test_counter_holds_the_gyro_angle_in_whole_pulses(default_model):
    m = default_model
    rate = np.array([1e-4, 3e-3, -2e-3])  # [rad/s]; one sign per run
    rec = ks.simulate_hardware(m, rate, 500, seed=3, residue0_pulses=0.0)
    weight = m.pulse_weight_arcsec * units.ARCSEC2RAD
    in_pulses = rec.gyro_angle_rad / weight
    # Count = integral truncated toward zero (to rounding of the running sums).
    assert np.all(np.abs(rec.counter_pulses) <= np.abs(in_pulses) + 1e-6)
    assert np.all(np.abs(in_pulses) - np.abs(rec.counter_pulses) < 1.0 + 1e-6)
    assert np.array_equal(rec.counter_angle_rad, rec.counter_pulses * weight)
    # Same seed, same record.
    again = ks.simulate_hardware(m, rate, 500, seed=3, residue0_pulses=0.0)
    assert np.array_equal(again.optical_angle_rad, rec.optical_angle_rad)


@pytest.mark.parametrize("quantized", [True, False])
@pytest.mark.parametrize("case", ["default_1s", "quantization_100hz"])
def test_covariance_recursion_converges_to_the_closed_form(default_model, case, quantized):
    if case == "default_1s":
        # 1 s samples: the slow (bias) pole, ~1800 s, settles to 1e-9 within 20 h.
        model, samples = default_model._replace(frames_per_sample=100), 72_000
    else:
        model, samples = quantization_dominated(default_model), 20_000
    start = np.diag([(1e-3) ** 2, (1e-6) ** 2])  # 200 arcsec, 0.2 deg/h: far from steady
    history = ks.covariance_history(model, samples, quantized, start)
    closed = ks.closed_form(model, quantized)
    for name in FIELDS:
        assert getattr(history, name)[-1] == pytest.approx(getattr(closed, name), rel=1e-9), name
    # The first samples are far from it: the recursion, not its start, gets there.
    assert history.attitude_pre_rad[0] > 100.0 * closed.attitude_pre_rad


def test_steady_start_stays_at_the_closed_form(default_model):
    history = ks.covariance_history(default_model, 50)  # p0 = closed-form steady state
    closed = ks.closed_form(default_model)
    for name in FIELDS:
        np.testing.assert_allclose(getattr(history, name), getattr(closed, name), rtol=1e-9)


def test_convergence_figure_data_ends_at_the_closed_form(default_model):
    model = quantization_dominated(default_model)
    data = ks.convergence(model, 200.0, 1e-4, 1e-5)
    assert data.time_s[-1] == pytest.approx(200.0)
    assert data.history.attitude_post_rad[-1] == pytest.approx(data.steady.attitude_post_rad,
                                                               rel=1e-9)
    assert data.history.bias_post_rad_s[-1] == pytest.approx(data.steady.bias_post_rad_s,
                                                             rel=1e-9)


def _assert_sigmas(result, rel=0.10):
    for name in SIGMAS:
        assert getattr(result.measured, name) == pytest.approx(
            getattr(result.predicted, name), rel=rel), name


ATTITUDE = ("attitude_pre_rad", "attitude_post_rad")


def _assert_attitude(result, rel=0.10):
    for name in ATTITUDE:
        assert getattr(result.measured, name) == pytest.approx(
            getattr(result.predicted, name), rel=rel), name


def test_monte_carlo_default_counter_and_star_tracker(default_model):
    # 100 Hz frame and samples; 2000 runs x the last 10 s. The attitude error
    # decorrelates in ~3 s, so >= 6000 independent samples (RMS to ~1 %). The
    # bias error hardly moves in 20 s (pole ~1800 s): it is the injected initial
    # draw, not the filter's, and is not tested here (the emulated runs below).
    result = ks.monte_carlo(default_model, 2000, 2000, seed=101)
    assert result.samples_used == 2000 * 1000
    _assert_attitude(result, rel=0.03)


def test_monte_carlo_default_sensors_long_run_settles_the_bias(default_model):
    # Converter and counter read every 1 s (frame = sample = 1 s) for 9000 s,
    # five bias time constants; 2-6 arcsec/s keeps 20-60 pulses a sample. The
    # last 4500 s of 500 runs hold ~1250 independent bias samples (RMS to 2 %).
    model = default_model._replace(frame_s=1.0)
    result = ks.monte_carlo(model, 500, 9000, seed=104, rate_rad_s=(1e-5, 3e-5))
    _assert_sigmas(result)


def test_monte_carlo_default_rate_gyro_farrenkopf(default_model):
    result = ks.monte_carlo(default_model, 2000, 2000, seed=102, quantized=False)
    _assert_attitude(result, rel=0.03)
    # The 0.1 arcsec pulses cost little: within 4 % of the rate gyro's attitude sigma.
    counter = ks.closed_form(default_model)
    assert counter.attitude_pre_rad / result.predicted.attitude_pre_rad == pytest.approx(
        1.0, abs=0.04)


def test_filter_on_the_emulators_own_blocks_from_zero_error():
    """The emulator's gyro (drift, ARW, RRW stepped once a second), converter 8, counter 14
    and star tracker 105, sampled every 1 s for 9000 s (five bias time constants), the
    filter started at the truth: every error is its own. 24 runs x the last 4500 s:
    attitude to ~1.5 %, the bias's ~60 independent samples to ~10 % (1 sigma)."""
    r = ks.emulated_monte_carlo(load_scenario(), 24, 9000.0, 100, seed=7)
    for name in ATTITUDE:
        assert getattr(r.measured, name) == pytest.approx(getattr(r.predicted, name), rel=0.05)
    for name in ("bias_pre_rad_s", "bias_post_rad_s"):
        assert getattr(r.measured, name) == pytest.approx(getattr(r.predicted, name), rel=0.3)


@pytest.mark.slow
def test_filter_on_the_emulators_own_blocks_at_the_frame_rate():
    """The same at 10 ms samples, 200 runs of 9000 s (some 180 million frames)."""
    r = ks.emulated_monte_carlo(load_scenario(), 200, 9000.0, 1, seed=8)
    for name in ATTITUDE:
        assert getattr(r.measured, name) == pytest.approx(getattr(r.predicted, name), rel=0.06)
    for name in ("bias_pre_rad_s", "bias_post_rad_s"):
        assert getattr(r.measured, name) == pytest.approx(getattr(r.predicted, name), rel=0.15)


def test_monte_carlo_quantization_dominated(default_model):
    model = quantization_dominated(default_model)
    assert model.sigma_e_rad > 2.5 * model.sigma_n_rad
    # Rates of 0.6-1.7 deg/s run the counter through 4-12 pulses a frame, so the
    # fraction left on the converter is close to white. 1000 runs x the last
    # 15 s (4 bias time constants): > 4000 independent samples each.
    result = ks.monte_carlo(model, 1000, 3000, seed=103, rate_rad_s=(1e-2, 3e-2))
    _assert_sigmas(result)
    # Ignoring the quantisation would be off by far more than the tolerance.
    unquantized = ks.closed_form(model, quantized=False)
    assert result.measured.attitude_pre_rad > 2.0 * unquantized.attitude_pre_rad


def test_closed_form_straddles_the_kalman_bucy_limit(default_model):
    """At the 10 ms frame the default sensors are near the continuous limit, written here:
    N = sigma_n sqrt(dt), P_att = N sqrt(sigma_v^2 + 2 sigma_u N), P_bias = sigma_u
    sqrt(sigma_v^2 + 2 sigma_u N); pre- and post-update straddle it, within dt/(4 tau)
    (tau = N / sqrt(sigma_v^2 + 2 sigma_u N))."""
    m = default_model
    cf = ks.closed_form(m, quantized=False)
    n = m.sigma_n_rad * math.sqrt(m.dt_s)
    root = math.sqrt(m.sigma_v_rad_rt_s**2 + 2 * m.sigma_u_rad_s_rt_s * n)
    att, tau = math.sqrt(n * root), n / root
    assert cf.attitude_post_rad < att < cf.attitude_pre_rad
    for got in (cf.attitude_post_rad, cf.attitude_pre_rad):
        assert abs(got / att - 1) < m.dt_s / (4 * tau) * 1.01
    assert cf.bias_post_rad_s == pytest.approx(math.sqrt(m.sigma_u_rad_s_rt_s * root), rel=2e-3)
