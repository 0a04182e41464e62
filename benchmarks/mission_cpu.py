"""CPU time of the default mission in this process: minimum and median [ms].

Run: ``python benchmarks/mission_cpu.py [RUNS] [--scenario NAME] [--set KEY=VALUE]...
[--general] [--compare]``. Two warm-up missions first (compiling or loading the loop),
then ``RUNS`` (default 15) timed with ``time.process_time``, without telemetry. To
compare two checkouts side by side, run it alternately with ``PYTHONPATH=<checkout>/src``:
the minimum is the figure least disturbed by other work on the machine.

``--scenario`` flies a packaged scenario (or a file), ``--set`` overrides a key
(``--set actuators.kind='"wheels"'``: the reaction-wheel vehicle), ``--general``
flies the general loop (the one of the wheels and the faults) even where the
patent's vehicle without faults has its own. ``--compare`` measures, in turns in
this process, the default mission, the wheel vehicle, the default mission through
the general loop, a fault scenario and the mission in orbit, and prints each one's time per frame over
the default mission's.
"""

import argparse
import time

from allsky.config.scenario import load_scenario
from allsky.sim import frame_loop
from allsky.sim.mission import Mission

#: The fault scenario of ``--compare``.
FAULT_SCENARIO = "stuck-jet-roll-calibration"
#: The mission in orbit of ``--compare`` (the orbit's loop, docs/orbit.md).
ORBIT_SCENARIO = "shuttle-free-flyer"


def mission_cpu_s(cfg, general=False) -> tuple:
    """CPU seconds of one mission of ``cfg``, and the frames it flew."""
    entry = frame_loop.leg_entry
    if general:
        frame_loop.leg_entry = lambda p: frame_loop._run_leg_any
    try:
        m = Mission(cfg, telemetry=False)
        t0 = time.process_time()
        m.run()
        return time.process_time() - t0, int(m.state.frame[0])
    finally:
        frame_loop.leg_entry = entry


def compare(runs):
    """Per-frame CPU of the wheel vehicle, the general loop, a fault and an orbit, over the default."""
    cases = {"default (plain loop)": (load_scenario(), False),
             "wheel vehicle": (load_scenario(overrides=['actuators.kind="wheels"']), False),
             "default, general loop": (load_scenario(), True),
             f"fault: {FAULT_SCENARIO}": (load_scenario(FAULT_SCENARIO), False),
             f"in orbit: {ORBIT_SCENARIO}": (load_scenario(ORBIT_SCENARIO), False)}
    for cfg, general in cases.values():
        for _ in range(2):
            mission_cpu_s(cfg, general)
    best = {k: (float("inf"), 0) for k in cases}
    for _ in range(runs):
        for k, (cfg, general) in cases.items():
            best[k] = min(best[k], mission_cpu_s(cfg, general))
    plain = best["default (plain loop)"]
    for k, (t, n) in best.items():
        print(f"{k:45s} {t * 1e3:7.2f} ms {n:7d} frames {t / n * 1e9:6.1f} ns/frame "
              f"{t / n / (plain[0] / plain[1]):5.2f}x")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="?", type=int, default=15)
    ap.add_argument("--scenario", default=None)
    ap.add_argument("--set", action="append", default=[], dest="overrides")
    ap.add_argument("--general", action="store_true")
    ap.add_argument("--compare", action="store_true")
    a = ap.parse_args()
    if a.compare:
        compare(a.runs)
        return
    cfg = load_scenario(a.scenario, overrides=a.overrides)
    for _ in range(2):
        mission_cpu_s(cfg, a.general)
    ts = sorted(mission_cpu_s(cfg, a.general) for _ in range(a.runs))
    t, n = ts[0]
    print(f"mission CPU: min {t * 1e3:.1f} ms ({t / n * 1e9:.1f} ns/frame, {n} frames), "
          f"median {ts[len(ts) // 2][0] * 1e3:.1f} ms over {a.runs} runs")


if __name__ == "__main__":
    main()
