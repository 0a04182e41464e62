"""What the three-axis Kalman filter adds to a mission's wall time.

Run: ``python benchmarks/kalman_benchmark.py [--repeats N] [--plan legacy|dither]``.

Times, interleaved and after a warm-up (numba's cache compiled):

* the mission as ``allsky compare`` flies it without the filter
  (``Mission(cfg, telemetry=False)``, the whole plan);
* the same plan flown by :func:`allsky.studies.kalman_mekf.fly`: telemetry
  recorded, each leg's counters kept, the filter run on the calibration
  modes' samples, its estimate loaded and Mode 6 flown with it (no truth
  bookkeeping: that is for the NEES, not for flight).

Prints, in wall time and in this process's CPU time, the minimum and the
median of each, the ratios (the target: at most 1.30), the filter's own
share (building its samples and filtering) and its time per sample. On a
shared machine the minima, and CPU time, are the steadier figures.
"""

import argparse
import statistics
import time

from allsky.config.scenario import load_scenario
from allsky.sim.mission import DITHER_PLAN, LEGACY_PLAN, Mission
from allsky.studies import kalman_mekf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    ap.add_argument("--plan", choices=("legacy", "dither"), default="legacy")
    a = ap.parse_args()
    cfg = load_scenario()
    plan = LEGACY_PLAN if a.plan == "legacy" else DITHER_PLAN

    def plain():
        Mission(cfg, telemetry=False, plan=plan).run()

    def with_filter():
        return kalman_mekf.fly(cfg, a.plan, truth=False)

    plain()
    f = with_filter()  # compile and warm up
    clocks = {"wall": time.perf_counter, "cpu": time.process_time}
    runs = {(c, k): [] for c in clocks for k in ("plain", "filter")}
    filt, samples = [], f.estimate.samples.time_s.size
    for _ in range(a.repeats):
        for k, fn in (("plain", plain), ("filter", with_filter)):
            t0 = {c: clk() for c, clk in clocks.items()}
            out = fn()
            for c, clk in clocks.items():
                runs[c, k].append(clk() - t0[c])
        filt.append(out.filter_s)
    print(f"plan {a.plan}, {a.repeats} repeats, {samples} filter samples "
          f"({cfg.mission.telemetry_every_frames} frames each)")
    for c in clocks:
        lo = {k: min(runs[c, k]) for k in ("plain", "filter")}
        med = {k: statistics.median(runs[c, k]) for k in ("plain", "filter")}
        for k, v in lo.items():
            print(f"  {c:>4} mission {k:>7}: min {v * 1e3:7.1f} ms, "
                  f"median {med[k] * 1e3:7.1f} ms")
        print(f"  {c:>4} ratio with/without the filter: min {lo['filter'] / lo['plain']:.3f}, "
              f"median {med['filter'] / med['plain']:.3f} (target <= 1.30)")
    plain_lo = min(runs["wall", "plain"])
    print(f"  filter alone (samples + filtering, wall): min {min(filt) * 1e3:.1f} ms = "
          f"{min(filt) / samples * 1e6:.2f} us per sample, "
          f"{min(filt) / plain_lo * 100:.1f} % of the mission")

if __name__ == "__main__":
    main()
