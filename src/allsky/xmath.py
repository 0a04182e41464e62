"""Exact arithmetic for the flight: the same bits on every machine.

The C library's ``sin``, ``cos``, ``atan2``, ``exp`` and ``log`` are not
the same function on every computer: glibc picks an FMA or an AVX2 variant
for the CPU it runs on, and NumPy's array loops (and its BLAS, for ``@``)
pick SIMD kernels the same way. Their results differ in the last bit, one
bit can tip a modulator's threshold, and the flight then diverges. Every
transcendental function the flight evaluates comes from here instead, in the
compiled loop and in the Python that feeds it (the Sun, the stars, the
programmed angles, the ejection attitude, the noise generator's tables).

Each function is a fixed sequence of IEEE-754 double operations (``+ - * /``
and ``sqrt``, all correctly rounded; ``floor``, ``frexp`` and ``ldexp``,
which are exact), evaluated in a fixed order: a short argument reduction,
then a polynomial. Python evaluates it as Python, and the compiled code
(:func:`allsky.jit.jitable`) compiles the same operations without fusing a
multiply and an add into one FMA (numba leaves fast-math off), so both give
the same bits on any x86-64 or ARM CPU. The polynomials are the Taylor
series, truncated where the next term falls below 2^-56 of the result on
the reduced interval; their coefficients and the tables of exact constants
are computed when the module loads, with Python's ``decimal`` arithmetic
(60 digits), not copied from anywhere. ``tests/test_xmath.py`` measures the
error against correctly rounded values: at most 1 ulp for every function.

Arguments of ``sin``, ``cos`` and ``tan`` are reduced by multiples of pi/2
held in four pieces of 27 bits and a fifth of 53 (Cody and Waite's method),
exact for ``|x|`` below ``2^26 pi/2`` (about 1.05e8 rad); beyond it the
reduction still gives the same bits everywhere, with an absolute error
growing as ``|x| 2^-110``.
"""

import math
from decimal import Decimal, localcontext
from fractions import Fraction

from allsky.jit import jitable

INF = math.inf
NAN = math.nan


# -- constants, computed once with 60-digit decimal arithmetic -------------------------
def _decimal_atan(x: Decimal) -> Decimal:
    """atan(x) to the context's precision: halve the angle three times, then the series."""
    for _ in range(3):
        x = x / (1 + (1 + x * x).sqrt())
    term, total, k, x2 = x, x, 1, x * x
    while True:
        term = -term * x2
        add = term / (2 * k + 1)
        if add == 0 or abs(add) < Decimal(10) ** -70:
            break
        total += add
        k += 1
    return 8 * total


def _split(d: Decimal, bits: int, pieces: int) -> tuple:
    """``d`` as ``pieces`` doubles summing to it: all but the last with ``bits`` significant bits."""
    out = []
    for _ in range(pieces - 1):
        m, e = math.frexp(float(d))
        piece = math.ldexp(math.floor(m * 2.0 ** bits), e - bits)
        out.append(piece)
        d -= Decimal(piece)
    out.append(float(d))
    return tuple(out)


with localcontext() as _ctx:
    _ctx.prec = 60
    _PI = 4 * _decimal_atan(Decimal(1))
    _LN2 = Decimal(2).ln()
    #: pi and pi/2 as a double and the double nearest to the rest
    PI_HI, PI_LO = _split(_PI, 53, 2)
    PIO2_HI, PIO2_LO = _split(_PI / 2, 53, 2)
    PIO4 = float(_PI / 4)
    TWO_OVER_PI = float(2 / _PI)
    #: pi/2 in pieces for the argument reduction: ``n * piece`` is exact for ``abs(n) < 2**26``
    PIO2_1, PIO2_2, PIO2_3, PIO2_4, PIO2_5 = _split(_PI / 2, 27, 5)
    #: ln 2 in two pieces: ``n * LN2_HI`` is exact for ``abs(n) < 2**13``
    LN2_HI, LN2_LO = _split(_LN2, 40, 2)
    INV_LN2 = float(1 / _LN2)
    #: ln 10 and 1/ln 10, for the powers and logarithms of ten
    LN10, LN10_LO = _split(Decimal(10).ln(), 53, 2)
    INV_LN10 = float(1 / Decimal(10).ln())
    SQRT_HALF = float(Decimal("0.5").sqrt())
    #: atan(k/8), k = 0..8, as a double and the rest
    _ATAN = [_split(_decimal_atan(Decimal(k) / 8), 53, 2) for k in range(9)]
ATAN_HI = tuple(a for a, _ in _ATAN)
ATAN_LO = tuple(b for _, b in _ATAN)


def _coefficient(numerator: int, denominator: int) -> float:
    return float(Fraction(numerator, denominator))  # correctly rounded


# sin r = r + r z (S1 + z (S2 + ... + z S8)), z = r^2, |r| <= pi/4: through r^17/17!
S1, S2, S3, S4, S5, S6, S7, S8 = (_coefficient((-1) ** k, math.factorial(2 * k + 1))
                                  for k in range(1, 9))
# cos r = 1 - z/2 + z^2 (C2 + z (C3 + ... + z C9)): through r^18/18!
C2, C3, C4, C5, C6, C7, C8, C9 = (_coefficient((-1) ** k, math.factorial(2 * k))
                                  for k in range(2, 10))
# atan u = u + u z (A1 + ... + z A7), |u| <= 1/16: through u^15/15
A1, A2, A3, A4, A5, A6, A7 = (_coefficient((-1) ** k, 2 * k + 1) for k in range(1, 8))
# exp r = 1 + r + r^2 (E2 + r (E3 + ... + r E13)), |r| <= ln2/2: through r^13/13!
E2, E3, E4, E5, E6, E7, E8, E9, E10, E11, E12, E13 = (
    _coefficient(1, math.factorial(k)) for k in range(2, 14))
# log(1+f) = f - s (f - R), s = f/(2+f), R = z (L1 + z (L2 + ... + z L10)), z = s^2
L1, L2, L3, L4, L5, L6, L7, L8, L9, L10 = (_coefficient(2, 2 * k + 1) for k in range(1, 11))
#: [-] exp overflows above this argument and is zero below the second
EXP_OVERFLOW = 709.782712893384
EXP_UNDERFLOW = -745.1332191019412


# -- sine, cosine, tangent --------------------------------------------------------------
@jitable
def _reduce(x):
    """``x`` as ``n pi/2 + (hi + lo)``, ``|hi + lo| <= pi/4`` (about); returns (n mod 4, hi, lo)."""
    if abs(x) <= PIO4:
        return 0, x, 0.0
    n = math.floor(x * TWO_OVER_PI + 0.5)
    hi = x - n * PIO2_1  # exact: n * PIO2_1 is exact and close to x
    lo = 0.0
    for piece in (PIO2_2, PIO2_3, PIO2_4):
        b = -(n * piece)  # exact for |n| < 2^26
        s = hi + b  # two-sum: s + e == hi + b exactly
        bb = s - hi
        e = (hi - (s - bb)) + (b - bb)
        hi = s
        lo += e
    lo -= n * PIO2_5
    s = hi + lo  # renormalise: |lo| well below ulp(hi) again
    lo = lo - (s - hi)
    q = n - 4.0 * math.floor(n * 0.25)
    return int(q), s, lo


@jitable
def _sin_kernel(hi, lo):
    """sin(hi + lo) for ``|hi| <= pi/4`` (``lo`` a small tail)."""
    z = hi * hi
    p = S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * (S6 + z * (S7 + z * S8))))))
    return hi + ((hi * z) * p + lo * (1.0 - 0.5 * z))


@jitable
def _cos_kernel(hi, lo):
    """cos(hi + lo) for ``|hi| <= pi/4`` (``lo`` a small tail)."""
    z = hi * hi
    q = C2 + z * (C3 + z * (C4 + z * (C5 + z * (C6 + z * (C7 + z * (C8 + z * C9))))))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + (z * z * q - hi * lo))


@jitable
def sin(x):
    """Sine of ``x`` [rad], within 1 ulp, the same bits everywhere."""
    if x - x != 0.0:  # inf or NaN
        return x - x
    q, hi, lo = _reduce(x)
    if q == 0:
        return _sin_kernel(hi, lo)
    if q == 1:
        return _cos_kernel(hi, lo)
    if q == 2:
        return -_sin_kernel(hi, lo)
    return -_cos_kernel(hi, lo)


@jitable
def cos(x):
    """Cosine of ``x`` [rad], within 1 ulp, the same bits everywhere."""
    if x - x != 0.0:
        return x - x
    q, hi, lo = _reduce(x)
    if q == 0:
        return _cos_kernel(hi, lo)
    if q == 1:
        return -_sin_kernel(hi, lo)
    if q == 2:
        return -_cos_kernel(hi, lo)
    return _sin_kernel(hi, lo)


@jitable
def tan(x):
    """Tangent of ``x`` [rad], within 2 ulp, the same bits everywhere."""
    if x - x != 0.0:
        return x - x
    q, hi, lo = _reduce(x)
    s = _sin_kernel(hi, lo)
    c = _cos_kernel(hi, lo)
    if q == 0 or q == 2:
        return s / c
    return -c / s


# -- inverse tangent, sine, cosine ------------------------------------------------------
@jitable(inline=True)
def _atan01(t):
    """atan(t) for ``0 <= t <= 1`` as (big, small): a table value and the rest.

    ``t`` is referred to the nearest k/8: atan t = atan(k/8) + atan u with
    ``u = (t - k/8) / (1 + t k/8)``, ``|u| <= 1/16``; for k = 0 that is
    ``t / 1``, so ``u = t`` is taken as it is (the same bits, one division
    fewer). Compiled into :func:`atan2`'s body: called, it returned its pair
    through memory on the frame's critical path (the four atan2 of a frame),
    about 1 ms of a 23 ms mission.
    """
    k = int(t * 8.0 + 0.5)
    if k == 0:  # t < 1/16, the sensors' common case: u = t exactly, without a division
        return _atan_near(t, 0)
    c = k * 0.125
    return _atan_near((t - c) / (1.0 + t * c), k)


@jitable(inline=True)
def _atan_near(u, k):
    """atan(k/8) + atan(u) as (big, small), ``|u| <= 1/16``, for :func:`_atan01`.

    Its own function so that no variable of ``_atan01`` is assigned on two
    paths: numba's inliner warns of such a variable (``NumbaIRAssumptionWarning``).
    """
    z = u * u
    p = A1 + z * (A2 + z * (A3 + z * (A4 + z * (A5 + z * (A6 + z * A7)))))
    return ATAN_HI[k], u + (ATAN_LO[k] + (u * z) * p)


@jitable
def atan2(y, x):
    """The angle [rad] of the point (``x``, ``y``), in [-pi, pi].

    C99's conventions for signed zeros, infinities and NaN; within 1.5 ulp,
    the same bits everywhere.
    """
    if math.isnan(x) or math.isnan(y):
        return x + y
    ax = abs(x)
    ay = abs(y)
    if ay == 0.0:  # +-0: +-0 toward +x, +-pi toward -x (and -0)
        if x > 0.0 or (x == 0.0 and math.copysign(1.0, x) > 0.0):
            return y
        return math.copysign(PI_HI, y)
    if ax == 0.0:
        return math.copysign(PIO2_HI, y)
    if ax == INF or ay == INF:
        if ax == INF and ay == INF:
            return math.copysign(PIO2_HI * 0.5 if x > 0.0 else PIO2_HI * 1.5, y)
        if ay == INF:
            return math.copysign(PIO2_HI, y)
        return math.copysign(0.0 if x > 0.0 else PI_HI, y)
    if ay <= ax:
        big, small = _atan01(ay / ax)
        if x > 0.0:
            r = big + small
        else:
            r = (PI_HI - big) + (PI_LO - small)
    else:
        big, small = _atan01(ax / ay)
        if x > 0.0:
            r = (PIO2_HI - big) + (PIO2_LO - small)
        else:
            r = (PIO2_HI + big) + (PIO2_LO + small)
    return math.copysign(r, y)


@jitable
def atan(x):
    """Inverse tangent of ``x`` [rad], in [-pi/2, pi/2], within 1 ulp."""
    return atan2(x, 1.0)


@jitable
def asin(x):
    """Inverse sine [rad] of ``x`` in [-1, 1] (NaN outside), within 1 ulp."""
    if not abs(x) <= 1.0:
        return NAN
    return atan2(x, math.sqrt((1.0 - x) * (1.0 + x)))


@jitable
def acos(x):
    """Inverse cosine [rad] of ``x`` in [-1, 1] (NaN outside), within 1 ulp."""
    if not abs(x) <= 1.0:
        return NAN
    return atan2(math.sqrt((1.0 - x) * (1.0 + x)), x)


# -- exponential and logarithm ----------------------------------------------------------
@jitable
def _exp_tail(x, tail):
    """exp(x + tail) for a small ``tail`` (below ulp(x))."""
    if math.isnan(x):
        return x
    if x > EXP_OVERFLOW:
        return INF
    if x < EXP_UNDERFLOW:
        return 0.0
    n = math.floor(x * INV_LN2 + 0.5)
    hi = x - n * LN2_HI  # exact
    b = n * LN2_LO
    r = hi - b
    rlo = ((hi - r) - b) + tail  # r + rlo = hi - b + tail to far below ulp(r)
    p = E2 + r * (E3 + r * (E4 + r * (E5 + r * (E6 + r * (E7 + r * (
        E8 + r * (E9 + r * (E10 + r * (E11 + r * (E12 + r * E13))))))))))
    e = 1.0 + (r + ((r * r) * p + rlo * (1.0 + r)))
    return math.ldexp(e, int(n))


@jitable
def exp(x):
    """e to the power ``x``, within 1 ulp, the same bits everywhere."""
    return _exp_tail(x, 0.0)


@jitable
def _product_error(a, b, p):
    """The rounding error ``a b - p`` of ``p = fl(a b)``, exactly (Dekker's split, no FMA)."""
    ca = a * 134217729.0  # 2^27 + 1
    ah = ca - (ca - a)
    al = a - ah
    cb = b * 134217729.0
    bh = cb - (cb - b)
    bl = b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


@jitable
def log(x):
    """Natural logarithm of ``x`` (NaN below 0, -inf at 0), within 1 ulp."""
    if math.isnan(x) or x < 0.0:
        return NAN
    if x == 0.0:
        return -INF
    if x == INF:
        return x
    m, e = math.frexp(x)  # x = m 2^e, 0.5 <= m < 1 (subnormals too)
    if m < SQRT_HALF:
        m = m + m
        e -= 1
    f = m - 1.0  # exact
    s = f / (2.0 + f)
    z = s * s
    r = z * (L1 + z * (L2 + z * (L3 + z * (L4 + z * (L5 + z * (L6 + z * (L7 + z * (
        L8 + z * (L9 + z * L10)))))))))
    return e * LN2_HI + (f - (s * (f - r) - e * LN2_LO))


@jitable
def exp10(x):
    """10 to the power ``x`` (magnitudes to fluxes), within 1 ulp for ``|x| < 300``.

    ``x ln 10`` is carried with its rounding error, which ``exp`` takes as a tail.
    """
    if math.isnan(x) or abs(x) > 400.0:
        return _exp_tail(x * LN10, 0.0)
    p = x * LN10
    return _exp_tail(p, _product_error(x, LN10, p) + x * LN10_LO)


@jitable
def log10(x):
    """Decimal logarithm of ``x``, within 2 ulp."""
    return log(x) * INV_LN10


# -- small vectors and matrices ----------------------------------------------------------
@jitable
def hypot(x, y):
    """``sqrt(x*x + y*y)`` of ``x`` and ``y``, the same bits everywhere (unscaled)."""
    return math.sqrt(x * x + y * y)


@jitable
def dot3(u, v):
    """``u`` . ``v`` of two 3-vectors, summed in index order (no BLAS)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@jitable
def norm3(u):
    """The length of the 3-vector ``u``."""
    return math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])


def dot(u, v) -> float:
    """``u`` . ``v`` of two vectors of any length, summed in index order (no BLAS)."""
    s = 0.0
    for a, b in zip(u, v, strict=True):
        s += float(a) * float(b)
    return s


def matmul(a, b):
    """The product of two small matrices ``a`` ``b`` (or a matrix and a vector).

    NumPy's ``@`` goes to BLAS, whose kernels (and their use of FMA) depend
    on the CPU; this is the same product with the same bits everywhere.
    """
    import numpy as np

    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    vector = b.ndim == 1
    bm = b.reshape(-1, 1) if vector else b
    out = np.empty((a.shape[0], bm.shape[1]))
    for i in range(a.shape[0]):
        for j in range(bm.shape[1]):
            s = 0.0
            for k in range(a.shape[1]):
                s += float(a[i, k]) * float(bm[k, j])
            out[i, j] = s
    return out[:, 0] if vector else out


def solve(a, b):
    """x with a x = b for a small square ``a`` (Gauss elimination, partial pivoting).

    ``b`` a vector or a matrix of columns; the operations in a fixed order
    (``numpy.linalg`` calls LAPACK, whose kernels depend on the CPU).

    Raises
    ------
    ValueError
        ``a`` is singular.
    """
    import numpy as np

    m = np.array(a, dtype=float)
    r = np.array(b, dtype=float)
    vector = r.ndim == 1
    if vector:
        r = r.reshape(-1, 1)
    n = m.shape[0]
    for c in range(n):
        p = c + int(np.argmax(np.abs(m[c:, c])))
        if m[p, c] == 0.0:
            raise ValueError("singular matrix")
        if p != c:
            m[[c, p]] = m[[p, c]]
            r[[c, p]] = r[[p, c]]
        for i in range(c + 1, n):
            f = m[i, c] / m[c, c]
            for j in range(c, n):
                m[i, j] = m[i, j] - f * m[c, j]
            for j in range(r.shape[1]):
                r[i, j] = r[i, j] - f * r[c, j]
    x = np.zeros_like(r)
    for i in range(n - 1, -1, -1):
        for j in range(r.shape[1]):
            s = r[i, j]
            for k in range(i + 1, n):
                s = s - m[i, k] * x[k, j]
            x[i, j] = s / m[i, i]
    return x[:, 0] if vector else x


def inv(a):
    """The inverse of a small square matrix ``a`` (:func:`solve` against the identity)."""
    import numpy as np

    return solve(a, np.eye(np.asarray(a).shape[0]))


def fsum_dot(u, v) -> float:
    """``u`` . ``v`` of two long vectors, correctly rounded (``math.fsum``)."""
    import numpy as np

    return math.fsum(np.asarray(u, dtype=float) * np.asarray(v, dtype=float))


def lstsq(a, b):
    """Least-squares x of ``a`` x ~ ``b`` (tall, full column rank), by Householder QR.

    The reflections are formed with NumPy's element-wise operations, which
    are exact per element, and correctly rounded sums (:func:`fsum_dot`):
    the same bits everywhere, where ``numpy.linalg.lstsq`` calls LAPACK.

    Raises
    ------
    ValueError
        ``a`` has a column that is zero after the reflections before it
        (rank deficient).
    """
    import numpy as np

    r = np.array(a, dtype=float)
    y = np.array(b, dtype=float)
    cols = r.shape[1]
    for j in range(cols):
        col = r[j:, j]
        size = math.sqrt(fsum_dot(col, col))
        if size == 0.0:
            raise ValueError("rank-deficient least-squares problem")
        alpha = -size if col[0] >= 0.0 else size
        v = col.copy()
        v[0] = v[0] - alpha
        vv = fsum_dot(v, v)
        for k in range(j, cols):
            r[j:, k] = r[j:, k] - v * (2.0 * fsum_dot(v, r[j:, k]) / vv)
        y[j:] = y[j:] - v * (2.0 * fsum_dot(v, y[j:]) / vv)
    x = np.zeros(cols)
    for i in range(cols - 1, -1, -1):
        s = float(y[i])
        for k in range(i + 1, cols):
            s = s - float(r[i, k]) * x[k]
        x[i] = s / float(r[i, i])
    return x
