"""What a user waits for: whole ``allsky`` processes, cold and warm, and their memory.

Run: ``python benchmarks/startup_benchmark.py [--src LABEL=SRC_DIR ...] [--repeats N]``,
or ``python benchmarks/startup_benchmark.py --install before=REV --install after=HEAD``.

Every figure is one whole process (``python -m allsky ...`` under
``subprocess``): wall time from ``time.perf_counter`` around it, CPU time
(user + system) and peak resident memory from ``os.wait4`` (the process
and the workers it waited for). Each source tree given with ``--src`` is
put first on ``PYTHONPATH``, so two checkouts (before and after a change)
are measured in turn, item by item, in one sitting; without ``--src`` the
installed ``allsky`` is measured.

* ``--help``, ``config show``, ``config check``: start-up alone.
* Python's bytecode files are written and used (``PYTHONDONTWRITEBYTECODE``
  is cleared), as after ``pip install``.
* ``run --quiet`` warm: numba's cache already written (a private
  ``NUMBA_CACHE_DIR`` per source, filled by one untimed run first).
* ``run --quiet`` cold: a fresh, empty ``NUMBA_CACHE_DIR`` every time, as
  on the first run after ``pip install``.
* the mission itself: one default mission inside a warm process (median of
  7, ``time.perf_counter``), as ``benchmarks/mission_benchmark.py`` times it.
* ``montecarlo --runs N --quiet``: the whole campaign command, warm cache.

With ``--install LABEL=REV`` (a git revision of this repository, repeatable)
each revision is installed as a user installs it instead: ``git archive``
into a temporary directory, a fresh virtual environment, ``pip install
DIR`` (timed: it builds the package, and since the build compiles the frame
loop, the compile is in this figure), then the *first* ``allsky run`` after
the install (once: there is only one first run), and every other item with
that environment's Python, its own cache and no ``NUMBA_CACHE_DIR``.

Medians are printed (min and max beside them); on a shared machine the CPU
time is the steadier figure.
"""

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

MISSION_CODE = """
import statistics, time
from allsky.config import load_scenario
from allsky.sim.mission import Mission
cfg = load_scenario()
Mission(cfg, telemetry=False).run()
ts = []
for _ in range(7):
    t = time.perf_counter(); Mission(cfg, telemetry=False).run(); ts.append(time.perf_counter() - t)
print(statistics.median(ts))
"""


def run_process(argv, env) -> dict:
    """Run one process to its end; its wall, CPU [s] and peak RSS [MB]."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stdout.close()
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "rss": usage.ru_maxrss / 1024.0, "code": proc.returncode, "out": out}


def environment(src, cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    env.pop("NUMBA_DISABLE_JIT", None)
    # Bytecode files as on a user's machine (pip writes them at install; the untimed
    # first run writes them for a source tree): without them every import compiles
    # allsky's sources again, about 0.1 s of each figure.
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if src:
        env["PYTHONPATH"] = os.pathsep.join([src] + [p for p in [os.environ.get(
            "PYTHONPATH")] if p])
    return env


def install(label, rev, root) -> tuple:
    """``rev`` installed in a fresh virtual environment under ``root``: (python, pip's figures)."""
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    tree = os.path.join(root, f"tree-{label}")
    os.makedirs(tree)
    archive = subprocess.run(["git", "-C", repo, "archive", rev], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", tree], input=archive, check=True)
    venv = os.path.join(root, f"venv-{label}")
    subprocess.run([sys.executable, "-m", "venv", venv], check=True)
    py = os.path.join(venv, "bin", "python")
    env = installed_environment()
    r = run_process([py, "-m", "pip", "install", "--quiet", tree], env)
    if r["code"] != 0:
        raise SystemExit(f"pip install of {rev} failed")
    return py, r


def installed_environment():
    """The environment of a process of an installed allsky: its own cache, its own paths."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT", "PYTHONPATH",
                        "PYTHONDONTWRITEBYTECODE")}
    return env


def install_main(a):
    """``--install``: each revision as a user installs and first runs it, then warm."""
    root = tempfile.mkdtemp(prefix="allsky-install-")
    try:
        revs = [tuple(s.split("=", 1)) for s in a.install]
        results, pythons = {}, {}
        for label, rev in revs:
            py, r = install(label, rev, root)
            pythons[label] = py
            results[("pip install .", label)] = [r]
            env = installed_environment()
            results[("first allsky run after install", label)] = [
                run_process([py, "-m", "allsky", "run", "--quiet"], env)]
            for key, rs in list(results.items()):
                if key[1] == label:
                    _report(key[0], label, rs[-1])
        warm_items = [row for row in items(a) if row[2] == "warm"]
        for name, tail, _, repeats in warm_items:
            for _ in range(repeats):
                for label, _ in revs:
                    r = _one(pythons[label], tail, installed_environment())
                    results.setdefault((name, label), []).append(r)
                    _report(name, label, r)
        names = ["pip install .", "first allsky run after install"] + [
            row[0] for row in warm_items]
        _table(names, [label for label, _ in revs], results)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _one(py, tail, env) -> dict:
    if tail is None:
        r = run_process([py, "-c", MISSION_CODE], env)
        return {"wall": float(r["out"].split()[-1]), "cpu": float("nan"),
                "rss": float("nan"), "code": r["code"]}
    return run_process([py, "-m", "allsky", *tail], env)


def _report(name, label, r):
    print(f"  {name} [{label}]: {r['wall']:.3f} s wall, {r['cpu']:.2f} s cpu, "
          f"{r['rss']:.0f} MB, exit {r['code']}", file=sys.stderr, flush=True)


def _table(names, labels, results):
    print("| what | " + " | ".join(f"{label}: wall (cpu) median [min-max] s, peak MB"
                                     for label in labels) + " |")
    print("|---|" + "---|" * len(labels))
    for name in names:
        cells = []
        for label in labels:
            rs = results[(name, label)]
            walls = [r["wall"] for r in rs]
            cpu = statistics.median(r["cpu"] for r in rs)
            rss = max(r["rss"] for r in rs)
            scale, unit = (1e3, "ms") if name.startswith("mission") else (1.0, "s")
            cell = f"{statistics.median(walls) * scale:.3g} {unit}"
            if len(rs) > 1:
                cell += f" [{min(walls) * scale:.3g}-{max(walls) * scale:.3g}]"
            if not math.isnan(cpu):
                cell += f" ({cpu:.2f} s cpu), {rss:.0f} MB"
            cells.append(cell)
        print(f"| {name} | " + " | ".join(cells) + " |")


def items(args):
    """(name, argv tail, cache kind, repeats) of every measured item."""
    r = args.repeats
    rows = [("allsky --help", ["--help"], "warm", r),
            ("allsky config show", ["config", "show"], "warm", r),
            ("allsky config check", ["config", "check", "--set", "mission.seed=2"], "warm", r),
            ("allsky run --quiet, warm", ["run", "--quiet"], "warm", r),
            ("mission itself (in a warm process)", None, "warm", 1)]
    if not args.skip_cold:
        rows.append(("first allsky run (empty cache)", ["run", "--quiet"], "cold",
                     args.cold_repeats))
    if args.runs:
        rows.append((f"allsky montecarlo --runs {args.runs}",
                     ["montecarlo", "--runs", str(args.runs), "--quiet"], "warm", 1))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", action="append", default=[], metavar="LABEL=DIR",
                    help="a source tree (its src/ directory) to measure; repeatable")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cold-repeats", type=int, default=2)
    ap.add_argument("--runs", type=int, default=1000,
                    help="montecarlo runs (0: leave the campaign out)")
    ap.add_argument("--skip-cold", action="store_true")
    ap.add_argument("--install", action="append", default=[], metavar="LABEL=REV",
                    help="a git revision to install in a fresh environment and measure as "
                         "installed (first run after pip install); repeatable")
    a = ap.parse_args()
    if a.install:
        install_main(a)
        return
    sources = [tuple(s.split("=", 1)) for s in a.src] or [("installed", "")]
    py = sys.executable
    root = tempfile.mkdtemp(prefix="allsky-startup-")
    try:
        warm = {}
        for label, src in sources:  # fill each source's warm cache, untimed
            warm[label] = os.path.join(root, f"warm-{label}")
            run_process([py, "-m", "allsky", "run", "--quiet"], environment(src, warm[label]))
        results = {}
        for name, tail, kind, repeats in items(a):
            for _ in range(repeats):
                for label, src in sources:
                    if kind == "cold":
                        cache = tempfile.mkdtemp(dir=root, prefix="cold-")
                    else:
                        cache = warm[label]
                    r = _one(py, tail, environment(src, cache))
                    if kind == "cold":
                        shutil.rmtree(cache, ignore_errors=True)
                    results.setdefault((name, label), []).append(r)
                    _report(name, label, r)
        _table([row[0] for row in items(a)], [label for label, _ in sources], results)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
