"""The dither method's blocks: generator, feed-forward and detector.

Truth: closed forms. A sinusoid of known amplitude and phase on an FFT bin
is recovered exactly; off the bin, the rectangular DFT leaks and the Hann
window and the least-squares fit do not; with white rate noise of density N
the scale-factor spread over many seeds is N sqrt(2/T)/(A w)
(docs/comparison.md).
"""

import numpy as np
import pytest

from allsky.sequencer import dither
from allsky.sequencer.dither_mode import analyse

DT = 0.1
PERIOD = 51.2  # = 0.1 s x 2**9, the dither document's preferred period
F = 1.0 / PERIOD


def sine(n, amp, phase, f=F, trend=(0.0, 0.0)):
    t = np.arange(n + 1) * DT  # n intervals of whole periods
    return amp * np.sin(2 * np.pi * f * t + phase) + trend[0] + trend[1] * t


@pytest.mark.parametrize("method", ["rect", "hann", "lsq"])
def test_on_bin_sinusoid_recovered_exactly(method):
    x = sine(8192, 20.6, 0.7, trend=(5.0, 0.02))  # a counter's drift ramp on top
    c = dither.lsq_amplitude(x, DT, F) if method == "lsq" else \
        dither.fft_amplitude(x, DT, F, window=method)
    assert abs(c) == pytest.approx(20.6, rel=1e-6 if method != "hann" else 1e-3)
    assert np.angle(c) == pytest.approx(0.7, abs=1e-6 if method != "hann" else 1e-3)


def test_off_bin_leaks_with_rectangular_window_and_not_with_the_fixes():
    f = 1.0 / 47.3  # not a whole number of periods in the record
    x = sine(8192, 20.6, 0.3, f=f, trend=(0.0, 0.01))
    with pytest.raises(ValueError, match="not on an FFT bin"):
        dither.fft_amplitude(x, DT, f)
    assert abs(dither.lsq_amplitude(x, DT, f)) == pytest.approx(20.6, rel=1e-9)
    assert abs(dither.fft_amplitude(x, DT, f, window="hann")) == pytest.approx(20.6, rel=2e-3)


def test_feedforward_torque_is_inertia_times_dither_acceleration():
    j = np.array([[100.0, 1.5, -1.0], [1.5, 650.0, 2.0], [-1.0, 2.0, 680.0]])
    amp_arcsec = np.array([20.6, 0.0, 20.6])
    omega = 2 * np.pi / np.array([51.2, 51.2, 25.6])
    gain = np.array([4.0, 5.0, 6.0])  # V per N m
    p = dither.DitherParams(amp_arcsec, omega, j, gain)
    angle, volts = np.zeros(3), np.zeros(3)
    for t in (0.0, 3.3, 12.8, 40.0):
        dither.dither_command(p, t, angle, volts)
        a = -amp_arcsec / 206264.80624709636 * omega ** 2 * np.sin(omega * t)
        assert np.allclose(angle, amp_arcsec * np.sin(omega * t))
        assert np.allclose(volts / gain, j @ a, rtol=1e-12, atol=1e-18)
        assert np.allclose(dither.feedforward_torque_n_m(j, amp_arcsec / 206264.80624709636,
                                                         omega, t), j @ a)


def synthetic_record(rng, sf_true, n_arw, amp, omega, t_rec, cross=0.0, opt_noise=0.0):
    """A dither record as the hardware sees it: counters integrate the gyro rate."""
    n = round(t_rec / DT) + 1
    t = np.arange(n) * DT
    true_roll = amp * np.sin(omega * t)
    rate_noise = rng.normal(0.0, n_arw / np.sqrt(DT), n)
    counter_roll = (1.0 / sf_true) * true_roll + np.cumsum(rate_noise) * DT
    counter_pitch = cross * true_roll + np.cumsum(rng.normal(0.0, n_arw / np.sqrt(DT), n)) * DT
    rec = np.column_stack([t, counter_roll, counter_pitch, np.zeros(n),
                           true_roll + rng.normal(0, opt_noise, n) if opt_noise else true_roll,
                           np.zeros(n), np.zeros(n)])
    return rec


def test_estimate_is_unbiased_and_its_spread_matches_the_formula():
    rng = np.random.default_rng(7)
    n_arw, amp, omega, t_rec = 0.06, 20.6, 2 * np.pi / PERIOD, 819.2
    sf_true, cross = 1.0 / (1.0 + 1500e-6), 180.0 / 206264.8
    est, xs = [], []
    for _ in range(400):
        rec = synthetic_record(rng, sf_true, n_arw, amp, omega, t_rec, cross=cross)
        e = analyse(rec, DT, 0.0, t_rec, np.array([amp, 0, 0]), np.array([omega, 1, 1]))
        est.append(e["roll"]["scale_factor_optical"])
        xs.append(e["roll"]["cross"]["pitch"])
    est, xs = np.array(est), np.array(xs)
    sigma = dither.scale_factor_sigma(n_arw, t_rec, amp, omega)
    assert sigma == pytest.approx(1.17e-3, rel=0.01)
    # Unbiased: the mean is within 3 standard errors of the truth.
    assert abs(est.mean() - sf_true) < 3 * sigma / np.sqrt(est.size)
    # Spread within 15 % of N sqrt(2/T)/(A w) (400 samples: ~3.5 % sampling error).
    assert est.std() == pytest.approx(sigma, rel=0.15)
    # Cross-axis term recovered with the same absolute noise.
    assert abs(xs.mean() - cross) < 3 * sigma / np.sqrt(xs.size)
    assert xs.std() == pytest.approx(sigma, rel=0.15)


def test_command_estimator_is_biased_by_tracking():
    rng = np.random.default_rng(1)
    rec = synthetic_record(rng, 1.0, 0.0, 20.6 * 1.03, 2 * np.pi / PERIOD, 819.2)
    e = analyse(rec, DT, 0.0, 819.2, np.array([20.6, 0, 0]), np.array([2 * np.pi / PERIOD, 1, 1]))
    assert e["roll"]["scale_factor_optical"] == pytest.approx(1.0, abs=1e-9)
    assert e["roll"]["scale_factor_command"] == pytest.approx(1 / 1.03, rel=1e-6)
    assert e["roll"]["tracking_ratio"] == pytest.approx(1.03, rel=1e-6)


def test_optical_noise_adds_its_own_term():
    """Gyro ARW and white optical noise: sigma^2 = (N sqrt(2/T)/(A w))^2 + (s sqrt(2/n)/A)^2."""
    rng = np.random.default_rng(11)
    n_arw, amp, omega, t_rec, s_opt = 0.06, 20.6, 2 * np.pi / PERIOD, 819.2, 2.0
    est = []
    for _ in range(400):
        rec = synthetic_record(rng, 1.0, n_arw, amp, omega, t_rec, opt_noise=s_opt)
        e = analyse(rec, DT, 0.0, t_rec, np.array([amp, 0, 0]), np.array([omega, 1, 1]))
        est.append(e["roll"]["scale_factor_optical"])
    gyro_term = dither.scale_factor_sigma(n_arw, t_rec, amp, omega)
    opt_term = s_opt * np.sqrt(2.0 / (t_rec / DT)) / amp
    assert np.std(est) == pytest.approx(np.hypot(gyro_term, opt_term), rel=0.15)
    assert abs(np.mean(est) - 1.0) < 3 * np.hypot(gyro_term, opt_term) / np.sqrt(len(est))


def test_on_the_target_only_the_biased_command_estimate_exists():
    """Holding on gyro-derived errors there is no optical reference: only estimate 1,
    which carries the loop's tracking error (several per cent, against ppm-level truth)."""
    from allsky.config.scenario import load_scenario
    from allsky.sequencer.dither_mode import target_hold_dither
    from allsky.sim.mission import Mission

    for sf in ("[3000,0,3000]", "[-3000,0,-3000]"):
        m = Mission(load_scenario(overrides=[f"gyro.scale_factor_error_ppm={sf}",
                                             "dither.record_s=409.6"]), telemetry=False)
        s = m.run()
        assert s["status"] == "complete"
        est = target_hold_dither(m)
        assert np.isnan(est["roll"]["scale_factor_optical"])
        err = est["roll"]["scale_factor_command"] - s["truth"]["scale_factor"]["roll"]
        assert 0.01 < abs(err) < 0.05


def test_optics_averaged_over_the_sample_are_corrected_for_the_boxcar():
    """Optics as the mean of 10 frames before each sample: gain and lag divided out exactly."""
    frames, amp, omega, t_rec = 10, 20.6, 2 * np.pi / 25.6, 819.2
    n = round(t_rec / DT) + 1
    t = np.arange(n) * DT
    lag = np.arange(frames) * DT / frames
    optics = np.mean([amp * np.sin(omega * (t - d)) for d in lag], axis=0)
    counter = amp * np.sin(omega * t) / 1.002  # gyro 0.2 % high: SF = 1.002
    rec = np.column_stack([t, np.zeros(n), np.zeros(n), counter, np.zeros(n), np.zeros(n),
                           optics])
    args = (rec, DT, 0.0, t_rec, np.array([0, 0, amp]), np.array([1, 1, omega]))
    exact = analyse(*args, optics_frames=frames)["yaw"]
    assert exact["scale_factor_optical"] == pytest.approx(1.002, rel=1e-12)
    assert exact["tracking_ratio"] == pytest.approx(1.0, rel=1e-12)
    # Uncorrected, the 0.045 s lag and the gain cost about 86 ppm (boxcar_response).
    raw = analyse(*args)["yaw"]["scale_factor_optical"]
    assert (raw / 1.002 - 1) == pytest.approx(-86e-6, rel=0.05)


def test_dither_record_averages_the_optics_of_the_frames_since_the_last_sample():
    from allsky.sim.recorder import N_REC, record_dither

    rec = np.full((4, N_REC), np.nan)  # an uncleared buffer
    rows = np.zeros(1, dtype=np.int64)
    counters = np.zeros(3)
    yaw_seen = []
    for frame in range(7, 31):  # a leg starting off the 10-frame grid
        fine = np.array([0.0, float(frame), 1.0])  # sun yaw output = frame number
        record_dither(rec, rows, 10, 0.01 * frame, frame, counters, 1.0, fine,
                      np.array([0.0, 0.0, 1.0]))
        yaw_seen.append(-float(frame))
    assert rows[0] == 4
    # The leg's first frame is a point sample; then frames 8-10, 11-20, 21-30.
    assert np.allclose(rec[:, 0], [0.07, 0.10, 0.20, 0.30])
    assert np.allclose(rec[:, 6], [-7.0, -9.0, -15.5, -25.5])


def test_known_cross_coupling_removes_the_yaw_bias_of_the_roll_the_loop_adds():
    """Yaw dither with roll = rho x yaw: a roll-into-yaw word c biases SF_yaw by ~ -c rho."""
    amp, omega, t_rec, c, rho = 20.6, 2 * np.pi / 25.6, 819.2, -972e-6, -0.178
    n = round(t_rec / DT) + 1
    t = np.arange(n) * DT
    yaw = amp * np.sin(omega * t)
    roll = rho * yaw
    rec = np.column_stack([t, roll, np.zeros(n), yaw + c * roll, roll, np.zeros(n), yaw])
    args = (rec, DT, 0.0, t_rec, np.array([0, 0, amp]), np.array([1, 1, omega]))
    biased = analyse(*args)["yaw"]["scale_factor_optical"]
    assert (biased - 1.0) == pytest.approx(-c * rho, rel=1e-3)
    words = {"roll_into_pitch": 0.0, "roll_into_yaw": c, "yaw_into_pitch": 0.0,
             "yaw_into_roll": 0.0}
    fixed = analyse(*args, cross_coupling=words)["yaw"]["scale_factor_optical"]
    assert fixed == pytest.approx(1.0, abs=1e-12)
