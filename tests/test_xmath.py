"""allsky.xmath: accurate to an ulp or two, and the same bits compiled and in Python.

Truth: correctly rounded values from mpmath at 200 bits. Bounds: the ulp
errors measured over the sample below (the module docstring quotes them).
"""

import math
import random
import re
from pathlib import Path

import numpy as np
import pytest

from allsky import xarrays, xmath

mpmath = pytest.importorskip("mpmath")
mpmath.mp.prec = 200
SRC = Path(__file__).resolve().parents[1] / "src" / "allsky"


def ulps(got, exact) -> float:
    """|got - exact| in units of the last place of the double nearest ``exact``."""
    return float(abs(mpmath.mpf(got) - exact) / math.ulp(float(exact)))


def _spread(rnd, scale_lo, scale_hi):
    return rnd.choice((-1.0, 1.0)) * 10.0 ** rnd.uniform(scale_lo, scale_hi)


#: name -> (function, mpmath function, argument generator, ulp bound)
CASES = {
    "sin": (xmath.sin, mpmath.sin, lambda r: _spread(r, -12, 7), 1.0),
    "cos": (xmath.cos, mpmath.cos, lambda r: _spread(r, -12, 7), 1.0),
    "tan": (xmath.tan, mpmath.tan, lambda r: _spread(r, -12, 3), 2.5),
    "exp": (xmath.exp, mpmath.exp, lambda r: r.uniform(-700.0, 700.0), 1.0),
    "log": (xmath.log, mpmath.log, lambda r: 10.0 ** r.uniform(-300, 300), 1.0),
    "atan": (xmath.atan, mpmath.atan, lambda r: _spread(r, -12, 12), 1.5),
    "asin": (xmath.asin, mpmath.asin, lambda r: r.uniform(-1.0, 1.0), 2.0),
    "acos": (xmath.acos, mpmath.acos, lambda r: r.uniform(-1.0, 1.0), 2.0),
    "exp10": (xmath.exp10, lambda x: mpmath.power(10, x), lambda r: r.uniform(-8.0, 8.0), 2.5),
    "log10": (xmath.log10, mpmath.log10, lambda r: 10.0 ** r.uniform(-30, 30), 2.0),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_function_is_within_its_ulp_bound(name):
    f, exact, draw, bound = CASES[name]
    rnd = random.Random(name)
    worst = max(ulps(f(x), exact(mpmath.mpf(x))) for x in (draw(rnd) for _ in range(3000)))
    assert worst <= bound, f"{name}: {worst:.2f} ulp"


def test_atan2_is_within_one_and_a_half_ulp_in_every_quadrant():
    rnd = random.Random(2)
    worst = 0.0
    for _ in range(4000):
        y, x = _spread(rnd, -6, 6), _spread(rnd, -6, 6)
        worst = max(worst, ulps(xmath.atan2(y, x), mpmath.atan2(mpmath.mpf(y), mpmath.mpf(x))))
    assert worst <= 1.5


@pytest.mark.parametrize("y, x, expected", [
    (0.0, 1.0, 0.0), (-0.0, 1.0, -0.0), (0.0, -1.0, math.pi), (-0.0, -1.0, -math.pi),
    (0.0, -0.0, math.pi), (-0.0, -0.0, -math.pi), (0.0, 0.0, 0.0), (1.0, 0.0, math.pi / 2),
    (-1.0, -0.0, -math.pi / 2), (math.inf, math.inf, math.pi / 4),
    (-math.inf, -math.inf, -3 * math.pi / 4), (1.0, math.inf, 0.0), (1.0, -math.inf, math.pi),
    (math.inf, 5.0, math.pi / 2)])
def test_atan2_keeps_c99s_signed_zeros_and_infinities(y, x, expected):
    got = xmath.atan2(y, x)
    assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected)


def test_special_values():
    assert math.isnan(xmath.sin(math.inf)) and math.isnan(xmath.cos(math.nan))
    assert xmath.exp(800.0) == math.inf and xmath.exp(-800.0) == 0.0
    assert xmath.log(0.0) == -math.inf and math.isnan(xmath.log(-1.0))
    assert xmath.exp(0.0) == 1.0 and xmath.log(1.0) == 0.0 and xmath.sin(0.0) == 0.0
    assert math.isnan(xmath.asin(1.5))
    assert xmath.exp(1.0) == math.e and xmath.atan2(1.0, 1.0) == math.pi / 4


def test_the_constants_are_the_decimal_values():
    assert xmath.PI_HI == math.pi and xmath.PIO2_HI == math.pi / 2
    assert xmath.LN2_HI + xmath.LN2_LO == math.log(2.0)
    assert mpmath.mpf(xmath.PIO2_1) + xmath.PIO2_2 + xmath.PIO2_3 + xmath.PIO2_4 \
        + xmath.PIO2_5 - mpmath.pi / 2 < mpmath.mpf(2) ** -150
    for k in range(9):
        assert abs(mpmath.mpf(xmath.ATAN_HI[k]) + xmath.ATAN_LO[k]
                   - mpmath.atan(mpmath.mpf(k) / 8)) < mpmath.mpf(2) ** -105


def _compiled_kernel():
    from allsky.jit import njit

    @njit
    def run(xs, ys, out):
        for i in range(xs.shape[0]):
            x, y = xs[i], ys[i]
            out[i, 0] = xmath.sin(x)
            out[i, 1] = xmath.cos(x)
            out[i, 2] = xmath.tan(x)
            out[i, 3] = xmath.atan2(y, x)
            out[i, 4] = xmath.exp(x * 1e-3)
            out[i, 5] = xmath.log(abs(x))
            out[i, 6] = xmath.asin(y / (1.0 + abs(y)))
            out[i, 7] = xmath.log10(abs(y))

    return run


def test_compiled_code_gives_the_bits_python_gives():
    rnd = np.random.default_rng(5)
    xs = rnd.standard_normal(3000) * 10.0 ** rnd.uniform(-8, 6, 3000)
    ys = rnd.standard_normal(3000) * 10.0 ** rnd.uniform(-8, 6, 3000)
    out = np.zeros((3000, 8))
    _compiled_kernel()(xs, ys, out)
    for i in range(xs.size):
        x, y = float(xs[i]), float(ys[i])
        row = (xmath.sin(x), xmath.cos(x), xmath.tan(x), xmath.atan2(y, x),
               xmath.exp(x * 1e-3), xmath.log(abs(x)), xmath.asin(y / (1.0 + abs(y))),
               xmath.log10(abs(y)))
        assert np.array_equal(np.array(row).view(np.int64), out[i].view(np.int64)), i


def test_the_arrays_give_the_bits_of_the_scalars():
    rnd = np.random.default_rng(6)
    x = rnd.standard_normal((50, 7)) * 100.0
    y = rnd.standard_normal(7)
    assert np.array_equal(xarrays.sin_many(x), np.vectorize(xmath.sin)(x))
    assert np.array_equal(xarrays.cos_many(x), np.vectorize(xmath.cos)(x))
    assert np.array_equal(xarrays.atan2_many(y, x), np.vectorize(xmath.atan2)(y, x))
    v = rnd.standard_normal((40, 3))
    assert np.array_equal(xarrays.norm_rows(v), [xmath.norm3(r) for r in v])


def test_the_frame_loop_has_no_fused_multiply_add_and_calls_no_math_library():
    """No FMA instruction and no call into the C library's maths in the compiled loop."""
    from allsky.jit import load_numba
    from allsky.sim import frame_loop

    load_numba()
    entry = frame_loop._run_frames  # compiled by the missions of the test session
    if not entry.signatures:
        from allsky.config.scenario import load_scenario
        from allsky.sim.mission import Mission

        Mission(load_scenario(overrides=["mission.seed=1"]), telemetry=False).run_mode()
    asm = "\n".join(entry.inspect_asm().values())
    assert not re.findall(r"\bv?f(n)?m(add|sub)(sub|add)?\d{3}[ps][sd]\b", asm)
    called = set(re.findall(r"call\w*\s+\*?_*([A-Za-z_][A-Za-z0-9_]*)", asm))
    libm = {"sin", "cos", "tan", "atan", "atan2", "exp", "log", "log10", "pow", "asin",
            "acos", "hypot", "sincos"}
    assert not called & libm


def test_linear_algebra_agrees_with_lapack():
    rnd = np.random.default_rng(7)
    a = rnd.standard_normal((6, 6)) + 6 * np.eye(6)
    b = rnd.standard_normal(6)
    assert np.allclose(xmath.solve(a, b), np.linalg.solve(a, b), rtol=1e-13, atol=1e-15)
    assert np.allclose(xmath.inv(a), np.linalg.inv(a), rtol=1e-12, atol=1e-15)
    assert np.allclose(xmath.matmul(a, a.T), a @ a.T, rtol=1e-14, atol=1e-13)
    tall = rnd.standard_normal((300, 5))
    y = rnd.standard_normal(300)
    assert np.allclose(xmath.lstsq(tall, y), np.linalg.lstsq(tall, y, rcond=None)[0],
                       rtol=1e-12, atol=1e-14)


#: Modules that feed the flight, its summary and the comparison's results: no libm or BLAS.
FLIGHT = ("hardware", "computer", "sequencer", "sim", "vehicle/sky.py", "vehicle/ephemeris.py",
          "vehicle/orbit.py", "vehicle/environment.py",
          "vehicle/plant.py", "vehicle/quaternion.py", "gauss.py", "config/dispersions.py",
          "config/checkers.py", "config/schema.py", "studies/crlb.py", "studies/pointing.py",
          "studies/compare.py")
#: What the C library (math, NumPy's element-wise loops) or BLAS (NumPy) would compute.
LIBM = {"sin", "cos", "tan", "arctan", "arctan2", "arcsin", "arccos", "atan", "atan2", "asin",
        "acos", "exp", "expm1", "log", "log10", "log1p", "log2", "power", "pow", "hypot",
        "erf", "dot", "matmul", "einsum", "inner", "linalg", "sinh", "cosh", "tanh"}


def _integer_constant(node) -> bool:
    """An integer literal: an exponent (a product, or a power of two) or a base (int power)."""
    import ast

    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        node = node.operand
    return isinstance(node, ast.Constant) and isinstance(node.value, int)


def _calls_outside_xmath(tree):
    """(line, what) of each libm or BLAS use in a module's code (docstrings aside)."""
    import ast

    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id in ("np", "numpy", "math") and node.attr in LIBM:
            yield node.lineno, f"{node.value.id}.{node.attr}"
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            yield node.lineno, "@"
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow) \
                and not _integer_constant(node.right) and not _integer_constant(node.left):
            yield node.lineno, "** (a power the C library computes)"


def test_no_module_that_feeds_the_flight_calls_the_c_library_or_blas():
    import ast

    offenders = []
    for part in FLIGHT:
        path = SRC / part
        for f in ([path] if path.suffix == ".py" else sorted(path.rglob("*.py"))):
            for line, what in _calls_outside_xmath(ast.parse(f.read_text())):
                offenders.append(f"{f.relative_to(SRC)}:{line}: {what}")
    assert not offenders, "\n".join(offenders)
