"""The fixed-interval smoother over the calibration modes (allsky.studies.smoother).

Truth from geometry and from the information limit: the exact rotation
error at any angle; on a linear case the smoother's errors scatter as the
Cramer-Rao bound says (it is efficient); on a flown mission its covariance
is the bound evaluated at the truth, and its errors are consistent with it.
"""

import math

import numpy as np
import pytest

from allsky import units
from allsky.config import load_scenario
from allsky.studies import crlb, smoother
from allsky.studies import kalman_mekf as K

from .test_crlb import _model, _oscillation


def test_rotation_error_is_the_whole_rotation():
    """A 170 deg turn about a skew axis comes back as 170 deg about that axis.

    The small-angle form (half the skew part) would give sin(170 deg) = 0.17 rad.
    """
    axis = np.array([1.0, -2.0, 0.5]) / math.sqrt(5.25)
    ang = math.radians(170.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    turn = np.eye(3) - math.sin(ang) * k + (1 - math.cos(ang)) * k @ k  # exp(-[a x] ang)
    a_est = crlb.dcm_many(np.array([[0.3, 0.1, -0.5, 0.8]]) / math.sqrt(0.99))
    e = smoother.rotation_error(a_est, turn @ a_est)[0]
    assert e == pytest.approx(ang * axis, abs=1e-12)


def test_smoother_is_efficient_on_a_linear_case():
    """Roll oscillation (10 deg, 20 s) for 60 s at 10 Hz: over 150 noise draws the
    smoother's drift and roll E errors scatter as the bound (150 runs: +-6 %, 1 sigma)."""
    n, dt, amp, period, sf = 600, 0.1, math.radians(10.0), 20.0, 1000.0
    model = _model(frame_s=dt)
    e_true = 1 / (1 + sf * 1e-6) - 1
    truth = np.zeros(12)
    truth[K.E_INDEX[0, 0] - 3] = e_true
    _, clean = _oscillation(n, dt, amp, period, sf)
    cov = crlb.bound_covariance(model, crlb.linearise(model, clean, truth))
    bound = np.sqrt([cov[K.BIAS, K.BIAS], cov[K.SF, K.SF]])
    rng = np.random.default_rng(5)
    err = []
    for _ in range(150):
        _, s = _oscillation(n, dt, amp, period, sf, rng)
        s = s._replace(sun=np.column_stack((np.zeros((n, 2)), np.ones(n))))
        sm = smoother.smooth(model, s)
        err.append([sm.params[-1, 0] - truth[0], sm.params[-1, 3] - e_true])
    spread = np.sqrt(np.mean(np.square(err), axis=0))
    assert spread == pytest.approx(bound, rel=0.2)


@pytest.fixture(scope="module")
def flight():
    return smoother.fly(load_scenario(overrides=["mission.seed=2"]), through_mode6=False,
                        bounds={"modes3_5": ("3", "4", "5")})


def test_smoother_covariance_is_the_bound_at_the_truth(flight):
    """Linearised at its converged trajectory the smoother's covariance is the Cramer-Rao
    bound linearised at the truth: the trajectories differ by arcsec, the sigmas by < 1 %."""
    sm, b = flight.smoothed, flight.bounds["modes3_5"]
    sig = K.sigmas(sm.params[-1], sm.covariance)
    for group in ("scale_factor_ppm", "cross_coupling_arcsec", "drift_deg_h"):
        for k, v in sig[group].items():
            assert v == pytest.approx(b[group][k], rel=0.01), (group, k)
    assert sm.iterations < smoother.MAX_ITERATIONS


def test_smoother_errors_are_consistent(flight):
    """The final error state (exact rotation) against the covariance: NEES of 15 states
    within chi-square(15)'s 99.9 % bounds, and no quantity beyond 4 sigma."""
    from scipy.stats import chi2

    e = smoother.errors(flight.mission, flight.smoothed)
    cov = flight.smoothed.covariance
    nees = float(e @ np.linalg.solve(cov, e))
    lo, hi = chi2.ppf([0.0005, 0.9995], K.N_STATE)
    assert lo < nees < hi
    assert np.all(np.abs(e) < 4 * np.sqrt(np.diag(cov)))
    # The attitude error at the end is sub-arcsec (the optics hold it).
    assert np.all(np.abs(e[:3]) * units.RAD2ARCSEC < 1.0)
