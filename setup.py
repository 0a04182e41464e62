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
install, ``ALLSKY_BUILD_COMPILE=0``) goes on without either.
"""

import os
import subprocess
import sys
import time

from setuptools import setup
from setuptools.command.build_py import build_py

#: [s] Longest a compile may take before the build goes on without it.
COMPILE_TIMEOUT_S = 900


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
        return
    print("allsky: compiling the frame loop for this machine, once (about 20 s)",
          file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-m", "allsky.apps.warm", *loop, "--no-lock"],
                              env=env, cwd=build_lib)
             for loop in (("plain", "--ahead-of-time"), ("any",))]
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


class BuildPyCompiled(build_py):
    """``build_py`` that also compiles the frame loop into the build directory."""

    def run(self):
        super().run()
        if (self.dry_run or getattr(self, "editable_mode", False)
                or os.environ.get("ALLSKY_BUILD_COMPILE", "1") == "0"):
            return
        compile_frame_loop(self.build_lib)


setup(cmdclass={"build_py": BuildPyCompiled})
