"""Build step: compile the frame loop into the wheel, so that the first mission starts at once.

Everything else about the package is in pyproject.toml. After the sources are
copied into the build directory, the frame loop's two compiled forms (the
patent's vehicle without faults, and the general one) are compiled there side
by side, one process each, into numba's cache beside the sources; the wheel
carries the cache and the install puts it where the loop looks for it. The
cache is keyed by the sources, numba's and NumPy's versions and this machine's
CPU (``allsky.jit_cache.PackageCacheLocator``): installed anywhere else, or with
other versions, it is ignored and the loop compiles on first use, as it would
without this step.

The first process then builds what a mission calls from Python ahead of time
(``allsky.aot``: an extension module made by numba's ``pycc``), so that a
mission runs without loading numba at all. That needs a C compiler and
Python's headers; without them the build goes on, and missions use numba's
cache.

A build that cannot compile (no numba in the build environment, an editable
install, ``ALLSKY_BUILD_COMPILE=0``) goes on without either. Whatever was not
built, and why, is written beside the package (``allsky/_build_note.json``,
:data:`NOTE`): the first command after the install says it once, where the
user sees it, rather than only in ``pip install -v``.

A wheel that carries the compiled extension and the machine's cache is a
platform wheel (``cp311-cp311-linux_x86_64``), not ``py3-none-any``.
"""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

#: [s] Longest a compile may take before the build goes on without it.
COMPILE_TIMEOUT_S = 900
#: How long the build's compile step and a first use's compile take (allsky.sim.warm_up.
#: COMPILE_S, measured on the project's 2-core machine).
BUILD_TIME, FIRST_COMPILE = "about 20 s", "about 12 s"
#: The file beside the package that says what the build could not compile.
NOTE = "_build_note.json"
#: What to do about it, in the words of the tools that install a compiler.
COMPILER_HINT = ("install a C compiler and Python's headers (Debian/Ubuntu: apt install gcc "
                 "python3-dev; conda: conda install -c conda-forge c-compiler), then "
                 "pip install --force-reinstall --no-deps allsky")


def compiles() -> bool:
    """Whether this build compiles (``ALLSKY_BUILD_COMPILE`` is not ``0``)."""
    return os.environ.get("ALLSKY_BUILD_COMPILE", "1") != "0"


#: What a command pays without the functions built ahead of time (allsky.aot.WITHOUT_AOT).
WITHOUT_AOT = "every command loads numba's compiled loop instead, about 0.6 s more"


def write_note(build_lib: str, what: str, reason: str, hint: str, effect: str) -> None:
    """Record in the package what the build did not compile, and why (:data:`NOTE`)."""
    path = os.path.join(build_lib, "allsky", NOTE)
    try:
        with open(path, "w", encoding="utf-8") as f:
            json.dump({"missing": what, "reason": reason, "hint": hint, "effect": effect}, f)
    except OSError as e:
        print(f"allsky: cannot record the build's note ({e})", file=sys.stderr)


def compiler_missing() -> str:
    """Why this machine cannot build the extension module ("" when it can)."""
    cc = sysconfig.get_config_var("CC") or "cc"
    if not shutil.which(cc.split()[0]) and not shutil.which("cc") and not shutil.which("gcc"):
        return f"no C compiler ({cc.split()[0]} not found)"
    include = sysconfig.get_paths()["include"]
    if not os.path.isfile(os.path.join(include, "Python.h")):
        return f"no Python headers (no Python.h in {include})"
    return ""


def forget_earlier_builds(build_lib: str) -> None:
    """Remove what an earlier build left in ``build_lib`` (its module, manifest, note).

    A build directory can be reused (``pip wheel`` of a source tree); what
    this build does not make must not ship beside its note.
    """
    package = os.path.join(build_lib, "allsky")
    for name in os.listdir(package) if os.path.isdir(package) else ():
        if name.startswith("_aot.") or name.startswith("_build_note."):
            os.remove(os.path.join(package, name))


def compile_frame_loop(build_lib: str) -> None:
    """Compile the frame loop into ``build_lib``'s package; never fails the build."""
    build_lib = os.path.abspath(build_lib)
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    # pip's isolated build environment reaches its packages through PYTHONPATH: keep it.
    env["PYTHONPATH"] = os.pathsep.join(p for p in (build_lib, env.get("PYTHONPATH")) if p)
    check = "import allsky, numba; print(allsky.__file__)"
    try:
        where = subprocess.run([sys.executable, "-c", check], env=env, cwd=build_lib,
                               capture_output=True, text=True, timeout=120, check=False)
    except (OSError, subprocess.SubprocessError) as e:
        print(f"allsky: not compiling the frame loop at build time ({e})", file=sys.stderr)
        return
    if where.returncode != 0 or not where.stdout.strip().startswith(build_lib):
        why = (where.stderr.strip().splitlines() or ["allsky imports from elsewhere"])[-1]
        print(f"allsky: not compiling the frame loop at build time ({why}); it compiles on "
              "first use", file=sys.stderr)
        write_note(build_lib, "the compiled frame loop", why, "run allsky warm-up once "
                   "after the install", f"the first command compiles it ({FIRST_COMPILE})")
        return
    print(f"allsky: compiling the frame loop for this machine, once ({BUILD_TIME})",
          file=sys.stderr, flush=True)
    missing = compiler_missing()
    if missing:
        print(f"allsky: not building the loop ahead of time: {missing}; {COMPILER_HINT}",
              file=sys.stderr)
        write_note(build_lib, "the loop built ahead of time", missing, COMPILER_HINT,
                   WITHOUT_AOT)
    t0 = time.perf_counter()
    plain = ("plain",) if missing else ("plain", "--ahead-of-time")
    procs = [subprocess.Popen([sys.executable, "-m", "allsky.apps.warm", *loop, "--no-lock"],
                              env=env, cwd=build_lib)
             for loop in (plain, ("any",))]
    for proc in procs:
        try:
            proc.wait(timeout=max(1.0, COMPILE_TIMEOUT_S - (time.perf_counter() - t0)))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    failed = [p.args[3] for p in procs if p.returncode != 0]
    if failed:
        print(f"allsky: compiling the {', '.join(failed)} loop failed at build time; it "
              "compiles on first use", file=sys.stderr)
        write_note(build_lib, f"the compiled {' and '.join(failed)} loop",
                   "the compile failed at build time (pip install -v shows why)",
                   "run allsky warm-up once after the install",
                   f"the first command that needs it compiles it ({FIRST_COMPILE})")


class BuildPyCompiled(build_py):
    """``build_py`` that also compiles the frame loop into the build directory."""

    def run(self):
        super().run()
        if self.dry_run or getattr(self, "editable_mode", False):
            return
        forget_earlier_builds(self.build_lib)
        if compiles():
            compile_frame_loop(self.build_lib)


class CompiledDistribution(Distribution):
    """A distribution whose wheel is tagged for this platform when the build compiles.

    The wheel then carries an extension module and numba's cache, both for
    this Python and machine: tagged ``py3-none-any`` it would be installed
    where neither works.
    """

    def has_ext_modules(self):
        return compiles()


setup(cmdclass={"build_py": BuildPyCompiled}, distclass=CompiledDistribution)
