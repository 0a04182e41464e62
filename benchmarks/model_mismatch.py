"""The filter under a wrong model: errors, its own sigmas, NEES and pointing.

Run: ``python benchmarks/model_mismatch.py [RUNS] [OUT_JSON] [FIGURE]`` (default 200
seeds, no files). Flies each seed's legacy plan once through Mode 5, runs the
three-axis filter on the same samples under every case of
``allsky.studies.mismatch.CASES`` and flies Mode 6 with each estimate
(``docs/kalman.md``, "Robustness to a wrong model").
"""

import json
import sys
import time

from allsky.config import load_scenario
from allsky.studies import mismatch


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    t0 = time.perf_counter()
    study = mismatch.study_dict(mismatch.study(load_scenario(), runs=runs, workers=2))
    print(f"{study['runs']} seeds in {time.perf_counter() - t0:.0f} s")
    right = "noise x1"
    print(f"{'case':<24}{'sf roll':>9}{'sf yaw':>9}{'sigma r/y':>12}{'cc max':>9}"
          f"{'drift max':>11}{'NEES':>10}{'pointing':>10}")
    for c in study["cases"]:
        n = c["name"]
        r, g = study["rms"][n], study["sigma"][n]
        print(f"{n:<24}{r['scale_factor_ppm']['roll']:>9.2f}{r['scale_factor_ppm']['yaw']:>9.2f}"
              f"{g['scale_factor_ppm']['roll']:>6.2f}/{g['scale_factor_ppm']['yaw']:<5.2f}"
              f"{max(r['cross_coupling_arcsec'].values()):>9.2f}"
              f"{max(r['drift_deg_h'].values()):>11.4f}{study['nees'][n]:>10.1f}"
              f"{study['pointing_arcsec'][n]['rms']:>10.2f}")
    print(f"legacy turns' own pointing, the same seeds: RMS "
          f"{study['legacy_pointing_arcsec']['rms']:.2f} (the filter with the right model: "
          f"{study['pointing_arcsec'][right]['rms']:.2f})")
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as f:
            json.dump(study, f, indent=1)
    if len(sys.argv) > 3:
        from allsky.apps.kalman_plots import mismatch_figure

        mismatch_figure(study).savefig(sys.argv[3], dpi=110)


if __name__ == "__main__":
    main()
