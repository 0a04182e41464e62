"""The noise source: xorshift64 uniforms and ziggurat normal deviates.

Truth: the layer construction of Marsaglia & Tsang (J. Stat. Softw. 5(8),
2000) -- every layer has the same area V, the base layer includes the tail
beyond R -- and the standard normal distribution itself (scipy.stats).
"""

import math

import numba
import numpy as np
import pytest
from scipy import stats

from allsky import gauss


@numba.njit
def draws(rng, n):
    out = np.empty(n)
    for k in range(n):
        out[k] = gauss.standard_normal(rng)
    return out


@numba.njit
def uniforms(rng, n):
    out = np.empty(n)
    for k in range(n):
        out[k] = gauss.uniform(rng)
    return out


def test_every_layer_has_the_common_area():
    x, f = gauss.X, gauss.F
    # R and V are published to 13 digits; the recurrence carries their rounding
    # up to the top layer, whose area is then off by 1.2e-9 of V.
    for i in range(1, gauss.N_LAYERS):
        assert x[i] * (f[i + 1] - f[i]) == pytest.approx(gauss.V, rel=2e-9), i
    # Base layer: rectangle under f(R) out to R, plus the tail integral beyond R.
    tail = math.sqrt(math.pi / 2) * math.erfc(gauss.R / math.sqrt(2))
    assert gauss.R * math.exp(-gauss.R ** 2 / 2) + tail == pytest.approx(gauss.V, rel=1e-9)
    assert x[0] * f[1] == pytest.approx(gauss.V, rel=1e-12)  # its virtual width
    assert np.all(np.diff(x[1:]) < 0) and x[-1] == 0.0


def test_normal_deviates_follow_the_standard_normal():
    z = draws(gauss.new_generator(5), 2_000_000)
    # Sampling errors at n = 2e6: mean 7e-4, std 5e-4 (1 sigma).
    assert abs(z.mean()) < 5 * 7.1e-4
    assert abs(z.std() - 1.0) < 5 * 5e-4
    assert stats.kstest(z, "norm").pvalue > 1e-3
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24 / z.size)


def test_tail_beyond_r_has_the_normal_probability():
    z = draws(gauss.new_generator(6), 4_000_000)
    p = 2 * stats.norm.sf(gauss.R)  # 5.8e-4
    n = np.count_nonzero(np.abs(z) > gauss.R)
    assert n == pytest.approx(p * z.size, abs=5 * math.sqrt(p * z.size))
    assert np.abs(z).max() > gauss.R  # the tail is reached


def test_uniforms_are_uniform_and_the_state_never_sticks_at_zero():
    rng = gauss.new_generator(0)
    u = uniforms(rng, 1_000_000)
    assert u.min() >= 0.0 and u.max() < 1.0
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    assert rng[0] != 0


def test_same_seed_same_stream_and_small_seeds_differ():
    a = draws(gauss.new_generator(3), 100)
    assert np.array_equal(a, draws(gauss.new_generator(3), 100))
    b = draws(gauss.new_generator(4), 100)
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.4


def test_plain_python_gives_the_same_deviates():
    rng_jit, rng_py = gauss.new_generator(9), gauss.new_generator(9)
    z_jit = draws(rng_jit, 1000)
    z_py = [gauss.standard_normal.py_func(rng_py) for _ in range(1000)]
    assert np.array_equal(z_jit, np.array(z_py))
    assert rng_jit[0] == rng_py[0]
