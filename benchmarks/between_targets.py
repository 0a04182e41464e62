"""The three ways to a next target side by side: time, gas and pointing per target.

Run: ``python benchmarks/between_targets.py [SCENARIO] [--seeds N]``. Flies the
scenario (default ``docs/examples/five_targets.toml``) with
``sequencer.between_targets`` = reacquire, recycle and direct, seed 1, and
prints for each target the time and gas from the end of the target before
(from ejection for the first) to the end of its Mode 6-2, and its true
pointing error there. With ``--seeds N`` it also flies seeds 1..N and prints
each option's worst and mean pointing error per target.
"""

import argparse
from pathlib import Path

import numpy as np

from allsky.config import load_scenario
from allsky.sim.mission import Mission

HOWS = ("reacquire", "recycle", "direct")
DEFAULT = Path(__file__).resolve().parents[1] / "docs" / "examples" / "five_targets.toml"


def per_target(path, how, seed):
    """[(name, time_s, gas_kg, pointing_arcsec)] per target, and the mission's status."""
    cfg = load_scenario(path, overrides=[f"sequencer.between_targets={how}",
                                         f"mission.seed={seed}"])
    m = Mission(cfg, telemetry=False)
    gas, ends = [], []
    while not m.finished:
        rec = m.run_mode()
        if rec.mode == "6-2":
            ends.append(rec.end_s)
            gas.append(cfg.jets.propellant_kg - float(m.state.propellant_kg[0]))
    s = m.summary()
    rows, t0, g0 = [], 0.0, 0.0
    for t, end, used in zip(s["targets"], ends, gas, strict=False):
        rows.append((t["name"], end - t0, used - g0, t["pointing_error_arcsec"]))
        t0, g0 = end, used
    return rows, s["status"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default=str(DEFAULT))
    ap.add_argument("--seeds", type=int, default=0)
    args = ap.parse_args()
    table = {how: per_target(args.scenario, how, 1) for how in HOWS}
    print(f"{'target':<12}" + "".join(f"{how:>28}" for how in HOWS))
    print(f"{'':<12}" + "".join(f"{'time s':>10}{'gas kg':>8}{'err ″':>10}" for _ in HOWS))
    names = [r[0] for r in table["reacquire"][0]]
    for i, name in enumerate(names):
        line = f"{name:<12}"
        for how in HOWS:
            rows = table[how][0]
            if i < len(rows):
                _, t, g, e = rows[i]
                line += f"{t:>10.0f}{g:>8.3f}{e:>10.1f}"
            else:
                line += f"{'-':>28}"
        print(line)
    line = f"{'total':<12}"
    for how in HOWS:
        rows, status = table[how]
        line += (f"{sum(r[1] for r in rows):>10.0f}{sum(r[2] for r in rows):>8.3f}"
                 f"{status:>10}")
    print(line)
    if args.seeds:
        print(f"\npointing over seeds 1..{args.seeds} (mean / worst, arcsec)")
        for how in HOWS:
            errs = np.array([[r[3] for r in per_target(args.scenario, how, seed)[0]]
                             for seed in range(1, args.seeds + 1)])
            print(f"{how:<10}" + "".join(f"{m:>8.1f} /{w:>6.1f}"
                                         for m, w in zip(errs.mean(0), errs.max(0))))


if __name__ == "__main__":
    main()
