"""NEES, NIS and whiteness of the three-axis filter (allsky.studies.consistency).

The statistics are checked against their chi-square distributions on
errors drawn from a known covariance, then on flights whose gyro errors are
drawn from the filter's prior.
"""

import numpy as np

from allsky.config import load_scenario
from allsky.studies import consistency as C
from allsky.studies import kalman_mekf as K


class _Est:
    """Just what :func:`run_statistics` reads, for errors drawn from ``cov``."""


def test_pooled_statistics_of_consistent_errors_are_chi_square(monkeypatch):
    """200 runs of errors drawn from the covariance the 'filter' reports: every block's mean
    NEES inside its 95 % band (the band has 5 % false alarms per block; the seed is fixed),
    z^2 means about 1, NIS of unit-variance innovations 1, white innovations white."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((15, 15))
    cov = a @ a.T / 15 + 0.1 * np.eye(15)
    chol = np.linalg.cholesky(cov)
    errors = iter(chol @ rng.standard_normal((15, 200)).T[..., None])
    monkeypatch.setattr(K, "errors_at", lambda m, est, k: next(errors)[:, 0])
    stats = []
    for _ in range(200):
        est = _Est()
        est.checkpoints = np.array([5])
        est.covariances = cov[None]
        n = 400
        inn = np.full((n, 4, 3), np.nan)
        inn[:, :, 0] = 2.0 * rng.standard_normal((n, 4))
        inn[:, :, 1] = 4.0
        inn[:, :, 2] = 1.0
        est.innovations = inn
        est.samples = K.Samples(*[np.zeros(n)] * 5, np.full(n, 3.0), *[np.zeros(n)] * 3)
        stats.append(C.run_statistics(None, est))
    r = C.summarise(stats)
    assert r.nees_bounds[0] < r.nees_mean[-1] < r.nees_bounds[1]
    for b in C.BLOCKS:
        assert r.blocks_bounds[b][0] < r.blocks_mean[b][-1] < r.blocks_bounds[b][1], b
    assert np.all(np.abs(r.z2_mean[-1] - 1.0) < 2 * r.z2_band)
    for name in C.OUTPUTS:
        lo, hi = r.nis[name]["bounds"]
        assert lo < r.nis[name]["mean"] < hi
        assert np.all(np.abs(r.whiteness[name]["autocorrelation"])
                      < 2 * r.whiteness[name]["band"])


def test_filter_innovations_are_consistent_and_white():
    """Six flights with gyro errors from the prior (Modes 3-5, 10 Hz): the NIS of each
    optical output within its chi-square band (about 7000 updates each: +-3 %), and the
    autocorrelation of the normalised innovations at lags 1-5 within 3 of its band."""
    r = C.campaign(load_scenario(), runs=6, seed=11, plan_name="legacy")
    assert r.runs == 6
    for name in C.OUTPUTS:
        lo, hi = r.nis[name]["bounds"]
        assert lo < r.nis[name]["mean"] < hi, (name, r.nis[name])
        rho = np.asarray(r.whiteness[name]["autocorrelation"])
        assert np.all(np.abs(rho) < 3 * r.whiteness[name]["band"]), (name, rho)
    # The NEES of all 15 states at the end of Mode 5, six runs: inside chi-square(90)/6.
    assert r.nees_bounds[0] < r.nees_mean[-1] < r.nees_bounds[1]
