"""The filter's attitude z^2 over the Mode 3 hold, at the 100 Hz frame, with the exact truth.

Run: ``python benchmarks/hold_consistency.py [RUNS] [--set KEY=VALUE]... [--shift K]``
(default 24 runs). Run ``k`` flies mission seed ``1 + k`` to the end of Mode 3 with
telemetry at every frame and the gyro errors of the ``k``-th draw from the filter's prior
(generator seed 2026, ``kalman_mekf.draw_truth``), filters Mode 3's samples and compares
the attitude estimate with the truth of each sample (``kalman_mekf.rotation_error``),
from 5 s after the filter starts. Prints per run the mean of ``e_i^2 / P_ii`` per axis
(roll, pitch, yaw), the 1/e correlation time of ``e_i / sigma_i`` and the filter's mean
sigma, then the mean over runs with its standard error (the runs' spread / sqrt(RUNS)),
which is what a z^2 figure from a few runs must be read against (``docs/kalman.md``).
``--shift K`` moves the gyro increments K samples later against the optics (a control for
the counters' timing; K < 0 earlier).
"""

import argparse

import numpy as np

from allsky import units
from allsky.config.scenario import load_scenario
from allsky.studies import kalman_mekf as km
from allsky.vehicle import quaternion

SETTLE_S = 5.0  #: [s] after the filter's start, left out (the prior's transient)


def hold_z2(seed, truth, overrides=(), shift=0):
    """z^2 per axis, correlation times [s] and mean sigma [arcsec] of one run's hold."""
    cfg = load_scenario(overrides=[f"mission.seed={seed}", "mission.telemetry_every_frames=1",
                                   *truth, *overrides])
    m, rec = km.recording(cfg, modes=("3",))
    while not m.finished and m.run_mode(rec.hooks).mode != "3":
        pass
    s = km.samples_from_legs(m, rec.legs_flown, ("3",))
    if shift:
        g = np.roll(s.gyro_rad, shift, axis=0)
        s = s._replace(gyro_rad=g)
    est = km.estimate(km.filter_model(m), s)
    ok = np.all(np.isfinite(est.samples.truth_q), axis=1)
    t = est.samples.time_s[ok]
    keep = t > t[0] + SETTLE_S
    a_true = np.array([quaternion.dcm_body_from_inertial(q) for q in est.samples.truth_q[ok]])
    a_est = np.array([quaternion.dcm_body_from_inertial(q) for q in est.q[ok]])
    z = (km.rotation_error(a_est, a_true) / est.sigma[ok, :3])[keep]
    frame = float(m.params.frame_s)
    tau = []
    for a in range(3):
        x = z[:, a] - z[:, a].mean()
        ac = np.correlate(x, x, "full")[x.size - 1:] / (x @ x)
        tau.append(float(np.argmax(ac < np.exp(-1.0))) * frame)
    return (np.mean(z * z, axis=0), np.array(tau),
            est.sigma[ok, :3][keep].mean(axis=0) * units.RAD2ARCSEC)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="?", type=int, default=24)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--shift", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(2026)
    z2 = []
    for k in range(args.runs):
        z, tau, sig = hold_z2(1 + k, km.draw_truth(km.DEFAULT_PRIOR, rng), args.set, args.shift)
        z2.append(z)
        print(f"run {k:3d}  z^2 roll, pitch, yaw {np.round(z, 3)}  correlation [s] "
              f"{np.round(tau, 2)}  sigma [arcsec] {np.round(sig, 4)}", flush=True)
    z2 = np.array(z2)
    err = z2.std(axis=0, ddof=1) / np.sqrt(len(z2))
    print(f"mean z^2 roll, pitch, yaw {np.round(z2.mean(axis=0), 3)} +- {np.round(err, 3)} "
          f"(median {np.round(np.median(z2, axis=0), 3)}) over {len(z2)} runs")


if __name__ == "__main__":
    main()
