"""Speed of the exact arithmetic's atan2, sin and cos against the C library's [ns per call].

Run: ``python benchmarks/xmath_speed.py [N]``. Each function is timed in a
compiled loop over ``N`` arguments (default 2**20) two ways: *throughput*,
the calls independent (as the sensors' outputs in one frame), and *latency*,
each call's argument depending on the last result (a chain). Arguments are
of the frame loop's kinds: small angles (a sensor near null, the common
case: the star near the boresight, the Sun near +x) and angles anywhere.
The best of 7 repetitions is printed, with the C library's figure beside.
"""

import math
import os
import sys
import tempfile
import time

# Compiled afresh in each process: numba's cache of this file's loops would keep the code
# of whichever checkout's xmath compiled them first (it checks only this file's own stamp).
os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="xmath-speed-")

import numpy as np

from allsky import xmath
from allsky.jit import njit


@njit
def _through_atan2_x(y, x, out):
    for i in range(y.shape[0]):
        out[i] = xmath.atan2(y[i], x[i])


@njit
def _through_atan2_m(y, x, out):
    for i in range(y.shape[0]):
        out[i] = math.atan2(y[i], x[i])


@njit
def _chain_atan2_x(y, x):
    a = 0.0
    for i in range(y.shape[0]):
        a = xmath.atan2(y[i] + a * 1e-300, x[i])
    return a


@njit
def _chain_atan2_m(y, x):
    a = 0.0
    for i in range(y.shape[0]):
        a = math.atan2(y[i] + a * 1e-300, x[i])
    return a


@njit
def _through_sin_x(x, out):
    for i in range(x.shape[0]):
        out[i] = xmath.sin(x[i])


@njit
def _through_sin_m(x, out):
    for i in range(x.shape[0]):
        out[i] = math.sin(x[i])


@njit
def _through_cos_x(x, out):
    for i in range(x.shape[0]):
        out[i] = xmath.cos(x[i])


@njit
def _through_cos_m(x, out):
    for i in range(x.shape[0]):
        out[i] = math.cos(x[i])


def _best_ns(f, n, *args):
    f(*args)  # compiled before timing
    best = math.inf
    for _ in range(7):
        t0 = time.perf_counter()
        f(*args)
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e9


def main(n=2**20):
    rng = np.random.default_rng(1)
    out = np.empty(n)
    cases = {"small angles (|y/x| < 0.06)": (rng.uniform(-0.06, 0.06, n), np.ones(n)),
             "any angle": (rng.standard_normal(n), rng.standard_normal(n))}
    print(f"{'[ns per call]':<32}{'allsky.xmath':>13}{'C library':>11}")
    for name, (y, x) in cases.items():
        print(f"atan2, {name}")
        print(f"  {'throughput':<30}{_best_ns(_through_atan2_x, n, y, x, out):>13.1f}"
              f"{_best_ns(_through_atan2_m, n, y, x, out):>11.1f}")
        print(f"  {'latency (a chain)':<30}{_best_ns(_chain_atan2_x, n, y, x):>13.1f}"
              f"{_best_ns(_chain_atan2_m, n, y, x):>11.1f}")
    angles = rng.uniform(-math.pi, math.pi, n)
    print(f"{'sin, throughput':<32}{_best_ns(_through_sin_x, n, angles, out):>13.1f}"
          f"{_best_ns(_through_sin_m, n, angles, out):>11.1f}")
    print(f"{'cos, throughput':<32}{_best_ns(_through_cos_x, n, angles, out):>13.1f}"
          f"{_best_ns(_through_cos_m, n, angles, out):>11.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2**20)
