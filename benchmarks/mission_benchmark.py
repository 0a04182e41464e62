"""Speed of the emulator: JIT compile time, one mission, and a Monte Carlo campaign.

Run: ``python benchmarks/mission_benchmark.py [--missions N] [--workers W]``.
Prints the compile time of the first mission (numba's cache cleared first
unless --keep-cache), the wall time of the complete default mission after
warm-up (median of repeats), frames per second, the real-time factor, the
peak resident memory, and the throughput of a Monte Carlo campaign over
seeds on ``W`` worker processes, extrapolated to 1000 missions.
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import allsky
from allsky.config.scenario import load_scenario
from allsky.sim.mission import Mission


def one_mission(seed):
    cfg = load_scenario(overrides=[f"mission.seed={seed}"])
    m = Mission(cfg, telemetry=False)
    m.run()
    return m.status, float(m.state.time_s[0]), int(m.state.frame[0])


def clear_numba_cache():
    for d in Path(allsky.__file__).parent.rglob("__pycache__"):
        for f in d.glob("*.nbi"):
            f.unlink()
        for f in d.glob("*.nbc"):
            f.unlink()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--missions", type=int, default=40, help="Monte Carlo missions to time")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--keep-cache", action="store_true")
    a = ap.parse_args()

    if not a.keep_cache:
        clear_numba_cache()
        # Compile in a fresh process so that the figure is a cold start.
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c",
                        "import sys; sys.path[:0] = %r; from mission_benchmark import one_mission;"
                        " one_mission(1)" % [str(Path(__file__).parent)]], check=True)
        print(f"cold start (import + JIT compile + one mission): {time.perf_counter() - t0:.2f} s")
    t0 = time.perf_counter()
    one_mission(1)
    print(f"first mission in this process (cached compile + run): {time.perf_counter() - t0:.2f} s")

    walls = []
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        status, sim_s, frames = one_mission(1)
        walls.append(time.perf_counter() - t0)
    w = statistics.median(walls)
    print(f"default mission: {status}, {sim_s:.1f} s simulated, {frames} frames")
    print(f"  wall time after warm-up: median {w * 1e3:.1f} ms (min {min(walls) * 1e3:.1f},"
          f" max {max(walls) * 1e3:.1f}) over {a.repeats}")
    print(f"  {frames / w / 1e6:.2f} M frames/s, real-time factor {sim_s / w:.0f}x")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  peak resident memory {peak_mb:.0f} MB")

    from concurrent.futures import ProcessPoolExecutor

    seeds = list(range(1000, 1000 + a.missions))
    with ProcessPoolExecutor(a.workers) as ex:
        list(ex.map(one_mission, [1] * a.workers))  # warm the workers
        t0 = time.perf_counter()
        results = list(ex.map(one_mission, seeds))
        dt = time.perf_counter() - t0
    ok = sum(r[0] == "complete" for r in results)
    print(f"Monte Carlo: {a.missions} missions on {a.workers} workers in {dt:.2f} s"
          f" ({ok} complete); 1000 missions -> {dt / a.missions * 1000:.0f} s")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    main()
