"""CPU time of the default mission in this process: minimum and median [ms].

Run: ``python benchmarks/mission_cpu.py [RUNS]``. Two warm-up missions first
(compiling or loading the loop), then ``RUNS`` (default 15) timed with
``time.process_time``, without telemetry. To compare two checkouts side by
side, run it alternately with ``PYTHONPATH=<checkout>/src``: the minimum is
the figure least disturbed by other work on the machine.
"""

import sys
import time

from allsky.config.scenario import load_scenario
from allsky.sim.mission import Mission


def mission_cpu_s(cfg) -> float:
    """CPU seconds of one mission of ``cfg``."""
    m = Mission(cfg, telemetry=False)
    t0 = time.process_time()
    m.run()
    return time.process_time() - t0


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    cfg = load_scenario()
    for _ in range(2):
        mission_cpu_s(cfg)
    ts = sorted(mission_cpu_s(cfg) for _ in range(runs))
    print(f"default mission CPU: min {ts[0] * 1e3:.1f} ms, median {ts[len(ts) // 2] * 1e3:.1f} ms "
          f"over {runs} runs")


if __name__ == "__main__":
    main()
