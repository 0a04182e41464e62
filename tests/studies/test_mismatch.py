"""The filter under a wrong model (allsky.studies.mismatch).

Truth from geometry (a turned tracker frame, a biased sun sensor, a displaced
star) and from the Kalman filter's invariance: scaling every noise and the
prior's weight alike leaves the gains, so the estimate, unchanged.
"""

import math

import numpy as np
import pytest

from allsky import units
from allsky.config import load_scenario
from allsky.studies import kalman_mekf as K
from allsky.studies import mismatch as MM


def _samples(yaw_rad, pitch_rad, sun=(0.0, 0.0)):
    n = len(yaw_rad)
    trk = np.column_stack((yaw_rad, pitch_rad, np.ones(n)))
    s = np.tile([sun[0], sun[1], 1.0], (n, 1))
    return K.Samples(np.arange(n, dtype=float), np.ones(n), np.zeros((n, 3)), s, trk,
                     np.zeros(n), np.full((n, 4), np.nan), np.full((n, 3), np.nan),
                     np.zeros(n, dtype=bool))


def test_a_tracker_turned_about_x_shifts_the_yaw_output_by_the_angle():
    """A star on the boresight seen from a frame turned by 30" about x: yaw output -30",
    pitch output 0, to 1e-12 rad; about z (the boresight) nothing moves."""
    case = MM.Case("t", "tracker about x", 30.0, tracker_rotation_arcsec=(30.0, 0.0, 0.0))
    got = MM.wrong_samples(_samples([0.0], [0.0]), case).tracker[0]
    assert got[0] == pytest.approx(-30.0 * units.ARCSEC2RAD, abs=1e-12)
    assert got[1] == pytest.approx(0.0, abs=1e-12)
    about_z = MM.Case("t", "tracker about z", 30.0, tracker_rotation_arcsec=(0.0, 0.0, 30.0))
    assert MM.wrong_samples(_samples([0.0], [0.0]), about_z).tracker[0, :2] == \
        pytest.approx([0.0, 0.0], abs=1e-15)
    # Off the boresight (pitch output 10 deg) a turn about z moves the star across the slit
    # by the angle times tan(10 deg): the tracker's yaw output is -roll + yaw tan(pitch)
    # (docs/comparison.md).
    off = MM.wrong_samples(_samples([0.0], [math.radians(10.0)]), about_z).tracker[0]
    assert off[0] == pytest.approx(30.0 * units.ARCSEC2RAD * math.tan(math.radians(10.0)),
                                   rel=1e-6)


def test_a_sun_bias_and_a_catalog_error_are_what_they_say():
    bias = MM.Case("s", "sun bias", 20.0, sun_bias_arcsec=20.0)
    got = MM.wrong_samples(_samples([0.0], [0.0], sun=(1e-4, -2e-4)), bias).sun[0]
    assert got[:2] == pytest.approx(np.array([1e-4, -2e-4]) + 20.0 * units.ARCSEC2RAD,
                                    abs=1e-15)
    m = K.filter_model(K.recording(load_scenario(), modes=()).mission)
    wrong = MM.wrong_model(m, MM.Case("c", "catalog", 60.0, catalog_error_arcsec=60.0))
    ang = np.arccos(np.clip(np.sum(wrong.stars_inertial * m.stars_inertial, axis=1), -1, 1))
    assert ang * units.RAD2ARCSEC == pytest.approx(np.full(len(ang), 60.0), rel=1e-6)


def test_a_common_noise_scale_changes_the_sigmas_not_the_estimate():
    """All data-sheet noises x2 (and the prior's weight with them, here by a prior twice
    as wide): the gains are the same, so the estimate; every sigma doubles. Not to the
    last digit: the output's second-order term the filter adds to the noise grows as the
    covariance squared (k^4, not k^2); it moves the estimate by 1e-4 of itself."""
    cfg = load_scenario()
    m, rec = K.recording(cfg, modes=K.FILTER_MODES["legacy"])
    from allsky.sim.results import fly_calibrating

    fly_calibrating(m, K.CALIBRATION_MODES["legacy"], on_end=lambda mm: False, hooks=rec.hooks)
    s = K.samples_from_legs(m, rec.legs_flown, K.FILTER_MODES["legacy"])
    model = K.filter_model(m)
    base = K.estimate(model, s)
    case = MM.Case("n", "noise", 2.0, 2.0, 2.0)
    wide = K.Prior(*(2.0 * v for v in K.DEFAULT_PRIOR))
    two = K.estimate(MM.wrong_model(model, case), s, wide)
    np.testing.assert_allclose(two.params[-1], base.params[-1], rtol=1e-3, atol=1e-12)
    np.testing.assert_allclose(two.sigma[-1], 2.0 * base.sigma[-1], rtol=1e-3)
