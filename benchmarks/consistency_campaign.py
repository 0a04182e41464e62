"""Consistency of the three-axis filter: NEES per block and state, NIS, whiteness.

Run: ``python benchmarks/consistency_campaign.py [RUNS] [OUT_JSON]`` (default 200). Flies
RUNS missions per configuration, the gyro errors drawn from the filter's prior
(the chi-square test) or the scenario's own (fixed truth, the comparison's),
and prints the pooled statistics of ``allsky.studies.consistency``
(``docs/kalman.md``, "Consistency").
"""

import json
import sys
import time

import numpy as np

from allsky.config import load_scenario
from allsky.studies import consistency

CONFIGS = {
    "legacy, drawn from the prior": ("legacy", True, []),
    "dither, drawn from the prior": ("dither", True, []),
    "legacy, the scenario's errors": ("legacy", False, []),
    "legacy on wheels, drawn from the prior": ("legacy", True, ['actuators.kind="wheels"']),
    "legacy on wheels, the scenario's errors": ("legacy", False, ['actuators.kind="wheels"']),
}


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    out = {}
    np.set_printoptions(precision=4, suppress=True, linewidth=200)
    for name, (plan, drawn, overrides) in CONFIGS.items():
        t0 = time.perf_counter()
        r = consistency.campaign(load_scenario(overrides=overrides), runs=runs, seed=2026,
                                 plan_name=plan, workers=2, truth_from_prior=drawn)
        out[name] = consistency.report_dict(r)
        print(f"\n{name}: {r.runs} runs ({r.aborted} aborted), "
              f"{time.perf_counter() - t0:.0f} s")
        print(f"  NEES (15) per leg end {r.nees_mean}, 95 % {np.round(r.nees_bounds, 2)}")
        for b, v in r.blocks_mean.items():
            print(f"  {b:<13}{v}  95 % {np.round(r.blocks_bounds[b], 2)}")
        print(f"  z^2 per state (rows: leg ends; 95 % band 1 +- {r.z2_band:.2f})")
        print("  " + " ".join(f"{s[:9]:>9}" for s in consistency.STATES))
        for row in r.z2_mean:
            print("  " + " ".join(f"{v:>9.2f}" for v in row))
        for k, v in r.nis.items():
            print(f"  NIS {k:<14}{v['mean']:.4f}  95 % {v['bounds'][0]:.4f}-{v['bounds'][1]:.4f}"
                  f"  ({v['count']} updates)")
        for k, v in r.whiteness.items():
            print(f"  whiteness {k:<14}{np.round(v['autocorrelation'], 4)}  band "
                  f"+-{v['band']:.4f}")
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
