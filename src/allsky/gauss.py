"""Standard normal deviates for the per-frame noise: the ziggurat method.

Every sensor draws its white noise here. The ziggurat of Marsaglia and Tsang
(J. Stat. Softw. 5(8), 2000), with 128 layers, takes one uniform deviate per
normal deviate in 98.8 % of draws, no logarithm and no square root. The
uniforms come from Marsaglia's xorshift64 generator (J. Stat. Softw. 8(14),
2003; shifts 13, 7, 17, period 2^64 - 1), whose whole state is one uint64
kept in the mission state: the frame loop seeds it at the start of each leg,
a paused leg carries it on, and nothing else draws from it. In the compiled
loop a deviate costs about a fifth of ``np.random.standard_normal``'s.

One 53-bit uniform ``u`` is split: its low 7 bits pick the layer, the next
bit the sign, the upper 45 bits the abscissa inside the layer. Layer ``i``
is the rectangle ``0 <= x < X[i]``, ``f(X[i]) <= y < f(X[i+1])`` under the
density ``f(x) = exp(-x^2/2)``; a point left of ``X[i+1]`` lies under the
curve and is accepted at once. Otherwise the point is tested against the
curve (a second uniform), or, in the base layer, drawn from the tail beyond
``R`` by Marsaglia's exponential method. The result is exactly normal; the
layer edges below follow the paper's recurrence.
"""

import math

import numpy as np

from allsky import xmath
from allsky.jit import njit, njit_stage

N_LAYERS = 128
#: Right edge of the base layer's bounded part, and the common layer area
#: (Marsaglia & Tsang 2000, section 3, for 128 layers).
R = 3.442619855899
V = 9.91256303526217e-3


def _edges():
    """Layer edges ``X[0..128]``: X[0] = V/f(R) (the base layer's virtual width), X[1] = R."""
    x = np.zeros(N_LAYERS + 1)
    x[0] = V / xmath.exp(-0.5 * R * R)
    x[1] = R
    for i in range(2, N_LAYERS):
        prev = float(x[i - 1])
        x[i] = math.sqrt(-2.0 * xmath.log(V / prev + xmath.exp(-0.5 * (prev * prev))))
    x[N_LAYERS] = 0.0
    return x


X = _edges()
#: density at each edge (F[128] = 1)
F = np.array([xmath.exp(-0.5 * (float(x) * float(x))) for x in X])
TWO53 = 9007199254740992.0
TWO_M45 = 2.0 ** -45


@njit
def seed(rng, value):
    """Seed generator ``rng`` ((1,) uint64) from a non-negative integer ``value``."""
    x = np.uint64(value) ^ np.uint64(0x9E3779B97F4A7C15)  # never 0; small seeds spread
    if x == np.uint64(0):
        x = np.uint64(1)
    rng[0] = x
    for _ in range(8):  # let the seed's bits diffuse before the first deviate
        uniform(rng)


@njit
def bits53(rng):
    """Advance generator ``rng`` one step; return its top 53 bits as an integer."""
    x = rng[0]
    x ^= x << np.uint64(13)
    x ^= x >> np.uint64(7)
    x ^= x << np.uint64(17)
    rng[0] = x
    return int(x >> np.uint64(11))


@njit
def uniform(rng):
    """One uniform deviate in [0, 1) from generator ``rng``, which it advances.

    The deviate carries 53 random bits.
    """
    return bits53(rng) * (1.0 / TWO53)


@njit_stage
def standard_normal(rng):
    """One N(0, 1) deviate from generator ``rng`` (ziggurat, 128 layers).

    The first try, accepted in 98.8 % of draws, is inlined where the deviate
    is drawn; the rest of the ziggurat is a call (:func:`_standard_normal_rest`).
    """
    b = bits53(rng)
    i = b & 127
    x = (b >> 8) * TWO_M45 * X[i]
    if x < X[i + 1]:
        return -x if (b >> 7) & 1 else x
    return _standard_normal_rest(rng, b)


@njit
def _standard_normal_rest(rng, b):
    """:func:`standard_normal` from a first try ``b`` (53 bits) that its layer did not accept.

    The ziggurat's tries from there: ``b``'s wedge or tail test, then new
    tries until one is accepted (``b``'s layer test, made again, fails again).
    """
    b = np.int64(b)  # one integer type for the first try and the new ones (53 bits)
    while True:
        i = b & 127
        negative = (b >> 7) & 1
        x = (b >> 8) * TWO_M45 * X[i]
        if x < X[i + 1]:
            return -x if negative else x
        if i == 0:  # the tail beyond R
            while True:
                t = -xmath.log(1.0 - uniform(rng)) / R
                y = -xmath.log(1.0 - uniform(rng))
                if y + y > t * t:
                    x = R + t
                    return -x if negative else x
        elif F[i] + uniform(rng) * (F[i + 1] - F[i]) < xmath.exp(-0.5 * x * x):
            return -x if negative else x
        b = np.int64(bits53(rng))


def new_generator(value=1) -> np.ndarray:
    """A generator state, (1,) uint64, seeded from integer ``value`` (:func:`seed`)."""
    rng = np.zeros(1, dtype=np.uint64)
    seed(rng, value)
    return rng
