"""Is the three-axis filter honest about its errors? NEES, NIS and whiteness.

Each with its chi-square band.

A filter's covariance is a claim about its errors; these tests check the
claim (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to
Tracking and Navigation*, Wiley 2001, sections 5.4 and 11.2):

* **NEES** (normalised estimation error squared) ``e^T P^-1 e`` per block
  of states (attitude 3, drift 3, scale factors 3, misalignments 6) and in
  all 15, at every leg end of the filtered modes: over N runs its mean is
  chi-square(dim N)/N for a consistent filter. The truth must be *drawn
  from the filter's prior*: with the scenario's one set of gyro errors the
  states the data do not show keep their prior error, a fixed number, and
  the statistic is not chi-square at all. Per state, the mean ``e_i^2 /
  P_ii`` (z^2) shows which state is over- (above 1) or under-confident.
* **NIS** (normalised innovation squared) ``nu^2 / s`` per sensor output
  (sun pitch and yaw, tracker yaw and pitch): mean 1 over the accepted
  updates, chi-square(N)/N. It needs no truth.
* **Whiteness**: the normalised innovations of consecutive samples of an
  optimal filter are uncorrelated; the sample autocorrelation at lags 1-5
  has a 95 % band of +-1.96/sqrt(N).

The attitude error is the exact rotation from the estimate to the truth
(:func:`allsky.studies.kalman_mekf.rotation_error`).
"""

import math
from typing import NamedTuple

import numpy as np

from allsky.studies import kalman_mekf as km

#: Blocks of the 15 error states.
BLOCKS = {"attitude": (0, 3), "drift": (3, 6), "scale_factor": (6, 9), "misalignment": (9, 15)}
#: The optical outputs, in the order of :attr:`~allsky.studies.kalman_mekf.Estimate.innovations`.
OUTPUTS = ("sun_pitch", "sun_yaw", "tracker_yaw", "tracker_pitch")
#: Lags [samples] of the whiteness test.
LAGS = (1, 2, 3, 4, 5)
STATES = ("att_roll", "att_pitch", "att_yaw", "drift_roll", "drift_pitch", "drift_yaw",
          "sf_roll", "sf_pitch", "sf_yaw") + tuple(
              f"mis_{i}{j}" for i, j in km.MISALIGNMENT_PAIRS)


def run_statistics(m, est: km.Estimate) -> dict:
    """One run's consistency figures: errors at the leg ends, innovation sums.

    ``m`` is the mission flown (its truth) and ``est`` the filter's
    :class:`~allsky.studies.kalman_mekf.Estimate` over it.

    Returns ``z2`` (checkpoints, 15), ``nees`` (checkpoints,), ``blocks``
    (block -> (checkpoints,)), ``modes`` (the mode of each checkpoint),
    ``nis_sum``, ``nis_count`` (per output) and ``corr`` (per output: the
    sums ``sum z_k z_{k+l}`` for :data:`LAGS`, ``sum z_k^2`` of the pairs'
    first terms and the number of pairs, consecutive accepted samples only).
    """
    ck = est.checkpoints
    z2 = np.empty((ck.size, km.N_STATE))
    nees = np.empty(ck.size)
    blocks = {b: np.empty(ck.size) for b in BLOCKS}
    for c, k in enumerate(ck):
        e = km.errors_at(m, est, int(k))
        cov = est.covariances[c]
        z2[c] = e * e / np.diag(cov)
        nees[c] = float(e @ np.linalg.solve(cov, e))
        for b, (i, j) in BLOCKS.items():
            blocks[b][c] = float(e[i:j] @ np.linalg.solve(cov[i:j, i:j], e[i:j]))
    inn = est.innovations
    nis_sum, nis_count, corr = {}, {}, {}
    for o, name in enumerate(OUTPUTS):
        ok = inn[:, o, 2] == 1.0
        z = np.where(ok, inn[:, o, 0] / np.sqrt(np.where(ok, inn[:, o, 1], 1.0)), 0.0)
        nis_sum[name] = float(np.sum(z[ok] ** 2))
        nis_count[name] = int(ok.sum())
        rows = []
        for lag in LAGS:
            pair = ok[:-lag] & ok[lag:]
            rows.append((float(np.sum(z[:-lag][pair] * z[lag:][pair])),
                         float(np.sum(z[:-lag][pair] ** 2)), int(pair.sum())))
        corr[name] = rows
    return {"z2": z2, "nees": nees, "blocks": blocks,
            "modes": [str(int(est.samples.mode[int(k)])) for k in ck],
            "nis_sum": nis_sum, "nis_count": nis_count, "corr": corr}


class Report(NamedTuple):
    """Consistency over runs drawn from the prior (:func:`campaign`)."""

    runs: int  #: runs that reached the end of their calibration
    aborted: int  #: runs that did not (no estimate to test)
    nees_mean: np.ndarray  #: (checkpoints,) mean NEES of all 15 states at each leg end
    nees_bounds: tuple  #: two-sided 95 % bounds of that mean
    blocks_mean: dict  #: block -> (checkpoints,) mean block NEES
    blocks_bounds: dict  #: block -> its 95 % bounds
    z2_mean: np.ndarray  #: (checkpoints, 15) mean z^2 per state
    z2_band: float  #: the 95 % half-width of a z^2 mean about 1 (chi-square(runs)/runs)
    nis: dict  #: output -> {"mean", "bounds", "count"}
    whiteness: dict  #: output -> {"lags", "autocorrelation", "band"}


def _chi2_bounds(dof, n):
    from scipy.stats import chi2

    lo, hi = chi2.ppf([0.025, 0.975], dof * n) / n
    return float(lo), float(hi)


def summarise(stats: list, aborted: int = 0) -> Report:
    """Pool per-run :func:`run_statistics` into a :class:`Report`.

    ``stats`` are the runs' figures (at least one); ``aborted`` counts the
    runs that gave none, carried into the report.
    """
    n = len(stats)
    width = min(s["nees"].size for s in stats)

    def tail(a):  # the first legs, and the last leg end of each run (its calibration's end)
        return np.concatenate([a[:width - 1], a[-1:]])

    nees = np.array([tail(s["nees"]) for s in stats])
    z2 = np.array([tail(s["z2"]) for s in stats])
    blocks = {b: np.array([tail(s["blocks"][b]) for s in stats]) for b in BLOCKS}
    nis = {}
    whiteness = {}
    for name in OUTPUTS:
        count = sum(s["nis_count"][name] for s in stats)
        if count == 0:
            continue
        total = sum(s["nis_sum"][name] for s in stats)
        nis[name] = {"mean": total / count, "bounds": _chi2_bounds(1, count), "count": count}
        rho, pairs = [], []
        for li in range(len(LAGS)):
            num = sum(s["corr"][name][li][0] for s in stats)
            den = sum(s["corr"][name][li][1] for s in stats)
            npair = sum(s["corr"][name][li][2] for s in stats)
            rho.append(num / den if den > 0 else float("nan"))
            pairs.append(npair)
        whiteness[name] = {"lags": list(LAGS), "autocorrelation": rho,
                           "band": 1.96 / math.sqrt(max(min(pairs), 1))}
    return Report(n, aborted, nees.mean(axis=0), _chi2_bounds(km.N_STATE, n),
                  {b: v.mean(axis=0) for b, v in blocks.items()},
                  {b: _chi2_bounds(j - i, n) for b, (i, j) in BLOCKS.items()},
                  z2.mean(axis=0), float(_chi2_bounds(1, n)[1] - 1.0), nis, whiteness)


def _run(job):
    from allsky.config import scenario_from_dict

    data, seed, truth, plan_name, prior = job
    cfg = scenario_from_dict(data, [f"mission.seed={seed}", *truth])
    f = km.fly(cfg, plan_name, prior, through_mode6=False)
    return None if f.estimate is None else run_statistics(f.mission, f.estimate)


def campaign(cfg, runs=50, seed=0, plan_name="legacy", prior: km.Prior = km.DEFAULT_PRIOR,
             workers=1, truth_from_prior=True) -> Report:
    """Fly ``runs`` missions and pool their consistency figures.

    Run ``k`` flies mission seed ``cfg.mission.seed + k``; with
    ``truth_from_prior`` its gyro drift, scale factors and misalignments
    are the ``k``-th draw from ``prior`` (generator seeded with ``seed``,
    :func:`allsky.studies.kalman_mekf.draw_truth`), otherwise the
    scenario's own (not a chi-square test of the states the data do not
    show). ``cfg`` is the scenario, ``plan_name`` the plan whose calibration
    the filter follows ("legacy" or "dither") and ``workers`` the processes
    that fly the runs.
    """
    rng = np.random.default_rng(seed)
    data = cfg.as_dict()
    jobs = [(data, int(cfg.mission.seed) + k,
             km.draw_truth(prior, rng) if truth_from_prior else [], plan_name, prior)
            for k in range(runs)]
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_run, jobs))
    else:
        rows = [_run(j) for j in jobs]
    done = [r for r in rows if r is not None]
    return summarise(done, runs - len(done))


def report_dict(r: Report) -> dict:
    """Report ``r`` (:class:`Report`) as JSON-ready data."""
    return {"runs": r.runs, "aborted": r.aborted,
            "nees": {"mean": r.nees_mean.tolist(), "bounds_95": list(r.nees_bounds),
                     "states": km.N_STATE},
            "blocks": {b: {"mean": v.tolist(), "bounds_95": list(r.blocks_bounds[b]),
                           "states": BLOCKS[b][1] - BLOCKS[b][0]}
                       for b, v in r.blocks_mean.items()},
            "z2": {"states": list(STATES), "mean": r.z2_mean.tolist(),
                   "band_95": r.z2_band},
            "nis": r.nis, "whiteness": r.whiteness}
