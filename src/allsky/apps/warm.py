"""``allsky warm-up``: compile the frame loop once, before a mission waits for it.

For an install script, a CI image or a cluster machine: afterwards every
command loads the compiled loop from numba's cache. The same module is a
Dask worker preload (``dask worker ADDRESS --preload allsky.apps.warm``):
:func:`dask_setup` compiles or loads the loop before the worker takes runs.
"""

import sys
import time


def run_from_cli(cfg, args) -> int:
    """``allsky warm-up``: compile (or load) the frame loop; one line says which."""
    from allsky.apps.progress import COMPILE_NOTE
    from allsky.sim.warm_up import needs_compiling, warm_up

    if needs_compiling() and not args.quiet:
        print(f"allsky: {COMPILE_NOTE}", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    compiled = warm_up()
    what = "compiled and cached" if compiled else "already compiled; loaded from the cache"
    print(f"frame loop {what} ({time.perf_counter() - t0:.1f} s)")
    return 0


def dask_setup(worker=None):
    """Dask preload hook: the worker compiles or loads the loop before it joins."""
    from allsky.sim.warm_up import warm_up

    warm_up()
