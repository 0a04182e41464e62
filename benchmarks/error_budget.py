"""Measure the calibration and pointing errors over many seeds (noise realisations).

Run: ``python benchmarks/error_budget.py [--runs N] [--set K=V ...]``. Prints, per
figure, the mean, standard deviation and largest magnitude of (stored - truth)
over the runs: drift [deg/h], scale factor [ppm], cross-coupling [arcsec],
final pointing error [arcsec], propellant [kg], mission time [s]. The figures in
docs/error_budget.md come from this script.
"""

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from allsky.config.scenario import load_scenario
from allsky.sim.mission import Mission

RAD2ARCSEC = 206264.80624709636
NAMES = ("drift roll [deg/h]", "drift pitch [deg/h]", "drift yaw [deg/h]",
         "scale factor roll [ppm]", "scale factor yaw [ppm]",
         "roll into pitch [arcsec]", "roll into yaw [arcsec]",
         "yaw into pitch [arcsec]", "yaw into roll [arcsec]",
         "pointing error [arcsec]", "propellant [kg]", "mission time [s]")


def errors(args):
    seed, overrides = args
    m = Mission(load_scenario(overrides=list(overrides) + [f"mission.seed={seed}"]),
                telemetry=False)
    s = m.run()
    if s["status"] != "complete":
        return None
    c, t = s["calibration"], s["truth"]
    return ([c["drift_deg_h"][k] - t["drift_deg_h"][k] for k in ("roll", "pitch", "yaw")]
            + [1e6 * (c["scale_factor"][k] - t["scale_factor"][k]) for k in ("roll", "yaw")]
            + [RAD2ARCSEC * (c["cross_coupling"][k] - t["cross_coupling"][k])
               for k in t["cross_coupling"]]
            + [s["target"]["pointing_error_arcsec"], s["propellant_kg"], s["mission_time_s"]])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], dest="overrides")
    a = ap.parse_args()
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(ex.map(errors, [(s, tuple(a.overrides)) for s in range(a.runs)]))
    ok = np.array([r for r in rows if r is not None])
    print(f"{len(ok)} of {a.runs} missions complete")
    print(f"{'figure':<28}{'mean':>10}{'std':>10}{'max |.|':>10}")
    for i, n in enumerate(NAMES):
        col = ok[:, i]
        print(f"{n:<28}{col.mean():>10.4f}{col.std():>10.4f}{np.abs(col).max():>10.4f}")


if __name__ == "__main__":
    main()
