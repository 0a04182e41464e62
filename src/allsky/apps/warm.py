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
    from allsky.sim.warm_up import LOOPS, entry_points, loop_entries, needs_compiling, warm_up

    if needs_compiling(loop_entries() + entry_points()[1:]) and not args.quiet:
        print("allsky: compiling the frame loop for this machine, once (about 30 s)",
              file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    compiled = warm_up(LOOPS)
    what = "compiled and cached" if compiled else "already compiled; loaded from the cache"
    print(f"frame loop {what} ({time.perf_counter() - t0:.1f} s)")
    return 0


def dask_setup(worker=None):
    """Dask preload hook: the worker compiles or loads the loop before it joins."""
    from allsky.sim.warm_up import warm_up

    warm_up()


def main(argv=None) -> int:
    """``python -m allsky.apps.warm [LOOP ...]``: compile loops (the build runs it)."""
    import argparse

    from allsky.sim.warm_up import LOOPS, warm_up

    ap = argparse.ArgumentParser(prog="python -m allsky.apps.warm",
                                 description="compile the frame loop into numba's cache")
    ap.add_argument("loops", nargs="*", choices=LOOPS, default=["plain"], metavar="LOOP",
                    help=f"which loops: {', '.join(LOOPS)} (default: plain)")
    ap.add_argument("--no-lock", action="store_true",
                    help="compile without the machine's compile lock")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    compiled = warm_up(tuple(args.loops), lock=not args.no_lock)
    what = "compiled" if compiled else "already in the cache"
    print(f"allsky: frame loop ({', '.join(args.loops)}) {what} in "
          f"{time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
