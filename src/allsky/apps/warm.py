"""``allsky warm-up``: compile the frame loop once, before a mission waits for it.

For an install script, a CI image or a cluster machine: afterwards every
command loads the compiled loop from numba's cache. The same module is a
Dask worker preload (``dask worker ADDRESS --preload allsky.apps.warm``):
:func:`dask_setup` compiles or loads the loop before the worker takes runs.
"""

import sys
import time


def run_from_cli(cfg, args) -> int:
    """``allsky warm-up``: compile (or load) the frame loop; one line says which.

    ``cfg`` is None (the command loads no scenario) and ``args`` the parsed
    command line (:mod:`allsky.apps.cli`); returns the exit status.
    """
    from allsky.sim.warm_up import (
        COMPILE_S,
        LOOPS,
        entry_points,
        loop_entries,
        needs_compiling,
        warm_up,
    )

    if getattr(args, "check", False):
        return check()
    if needs_compiling(loop_entries() + entry_points()[1:]) and not args.quiet:
        print(f"allsky: compiling the frame loop for this machine, once (about "
              f"{COMPILE_S['warm-up']} s)",
              file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    compiled = warm_up(LOOPS)
    what = "compiled and cached" if compiled else "already compiled; loaded from the cache"
    print(f"frame loop {what} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _cache_dirs(entries):
    """The cache directories of the compiled entry points (numba's, for this tree)."""
    dirs = []
    for d in entries:
        try:
            path = d._cache._cache_path
        except AttributeError:
            continue
        if path not in dirs:
            dirs.append(path)
    return dirs


def cache_problems(directory) -> tuple:
    """``(files, damaged)`` of numba's cache in ``directory``, changing nothing.

    Each index and data file is checked as a command loads it: it unpickles,
    and a data file matches its recorded size and sha256.
    """
    import os
    import pickle

    from allsky import jit_cache

    files, damaged = 0, []
    try:
        names = sorted(os.listdir(directory))
    except OSError:
        return 0, []
    for name in names:
        path = os.path.join(directory, name)
        if name.endswith(".nbi"):
            files += 1
            try:
                with open(path, "rb") as f:
                    pickle.load(f)
                    pickle.loads(f.read())
            except Exception as e:  # noqa: BLE001 - a damaged pickle fails in many ways
                damaged.append(f"{path} ({type(e).__name__})")
        elif name.endswith(".nbc"):
            files += 1
            try:
                with open(path + jit_cache.DIGEST, encoding="ascii") as f:
                    want = f.read().strip()
            except OSError:
                want = None
            if want is not None and jit_cache.cache_digest(path) != want:
                damaged.append(f"{path} (its size or sha256 is not what was saved)")
                continue
            try:
                with open(path, "rb") as f:
                    pickle.loads(f.read())
            except Exception as e:  # noqa: BLE001
                damaged.append(f"{path} ({type(e).__name__})")
    return files, damaged


def check() -> int:
    """``allsky warm-up --check``: what is installed, compiled, cached; does it load.

    Changes nothing. Exit 0 when nothing is damaged, 1 otherwise.
    """
    import os

    import numba

    import allsky
    from allsky import aot
    from allsky.sim.warm_up import entry_points, loop_entries, needs_compiling

    bad = 0
    print(f"allsky {allsky.__version__} at {os.path.dirname(allsky.__file__)}; python "
          f"{sys.version.split()[0]}; numba {numba.__version__}")
    if not os.path.exists(aot.MANIFEST):
        print("ahead of time: not built (missions use numba's compiled loop)")
    else:
        m = aot.read_manifest()
        if m is None:
            print("ahead of time: the manifest is damaged (bypassed)")
            bad += 1
        elif m.get("stamp") != aot.stamp() or m.get("cpu") != aot.cpu_fingerprint() or (
                m.get("cache_tag") != sys.implementation.cache_tag):
            print("ahead of time: built for other sources, CPU or Python (not used)")
        else:
            why = aot.extension_problem(m)
            print("ahead of time: built, and it loads" if why is None
                  else f"ahead of time: damaged: {why}")
            bad += why is not None
    entries = loop_entries() + entry_points()[1:]
    print("frame loop: " + ("not compiled yet (allsky warm-up compiles it)"
                            if needs_compiling(entries) else "compiled, in numba's cache"))
    for directory in _cache_dirs(entries):
        files, damaged = cache_problems(directory)
        print(f"numba cache {directory}: {files} files, "
              + (f"{len(damaged)} damaged" if damaged else "all load"))
        for what in damaged:
            print(f"  damaged: {what} (allsky warm-up sets it aside and compiles it again)")
        bad += len(damaged)
    return 1 if bad else 0


def dask_setup(worker=None):
    """Dask preload hook: the worker compiles or loads the loop before it joins.

    Dask passes its ``worker``, which is not needed.
    """
    from allsky.sim.warm_up import warm_up

    warm_up()


def main(argv=None) -> int:
    """``python -m allsky.apps.warm [LOOP ...]``: compile loops (the build runs it).

    ``argv`` are the arguments (None: the command line's); returns the exit status.
    """
    import argparse

    from allsky.sim.warm_up import LOOPS, warm_up

    ap = argparse.ArgumentParser(prog="python -m allsky.apps.warm",
                                 description="compile the frame loop into numba's cache")
    ap.add_argument("loops", nargs="*", choices=LOOPS, default=["plain"], metavar="LOOP",
                    help=f"which loops: {', '.join(LOOPS)} (default: plain)")
    ap.add_argument("--no-lock", action="store_true",
                    help="compile without the machine's compile lock")
    ap.add_argument("--ahead-of-time", action="store_true",
                    help="then build what a mission calls from Python ahead of time, into the "
                         "package (allsky.aot; needs a C compiler and Python's headers)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    compiled = warm_up(tuple(args.loops), lock=not args.no_lock)
    what = "compiled" if compiled else "already in the cache"
    print(f"allsky: frame loop ({', '.join(args.loops)}) {what} in "
          f"{time.perf_counter() - t0:.1f} s", file=sys.stderr)
    if args.ahead_of_time:
        from allsky.apps.aot_build import build

        t0 = time.perf_counter()
        try:
            path = build()
        except Exception as e:  # noqa: BLE001 - no compiler, no headers: numba at run time
            why = " ".join(f"{type(e).__name__}: {e}".split())[:300]
            print(f"allsky: not built ahead of time ({why}); missions use numba's compiled "
                  "loop", file=sys.stderr)
            _write_note("the loop built ahead of time", why)
            return 0
        print(f"allsky: built ahead of time in {time.perf_counter() - t0:.1f} s: {path}",
              file=sys.stderr)
    return 0


def _write_note(what, why):
    """Leave the first command after the install a note of what was not built (aot.NOTE)."""
    import json

    from allsky import aot

    try:
        with open(aot.NOTE, "w", encoding="utf-8") as f:
            json.dump({"missing": what, "reason": why, "hint": aot.COMPILER_HINT,
                       "effect": aot.WITHOUT_AOT}, f)
    except OSError:
        pass


if __name__ == "__main__":
    raise SystemExit(main())
