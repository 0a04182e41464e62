"""The exact functions of :mod:`allsky.xmath` over arrays, for the studies.

NumPy's ``sin``, ``cos`` and ``arctan2`` of an array run SIMD kernels chosen
for the CPU, and ``@`` and ``einsum`` BLAS or SIMD kernels whose order of
summation does too; the studies whose numbers are results (the information
bound, the pointing decomposition) use these instead. Each element gets the
same bits as :mod:`allsky.xmath` gives it alone (the functions are compiled
loops over the scalar ones), and sums run in a fixed order.
"""

import numpy as np

from allsky.jit import njit_alloc
from allsky.xmath import atan2, cos, sin


@njit_alloc
def _sin_flat(x):
    out = np.empty(x.size)
    for i in range(x.size):
        out[i] = sin(x[i])
    return out


@njit_alloc
def _cos_flat(x):
    out = np.empty(x.size)
    for i in range(x.size):
        out[i] = cos(x[i])
    return out


@njit_alloc
def _atan2_flat(y, x):
    out = np.empty(x.size)
    for i in range(x.size):
        out[i] = atan2(y[i], x[i])
    return out


def _flat(*arrays):
    """The arrays broadcast together, as contiguous 1-D float arrays, and their shape."""
    b = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in arrays))
    return [np.ascontiguousarray(a).ravel() for a in b], b[0].shape


def sin_many(x):
    """:func:`sin` of every element of ``x`` (the same bits as element by element)."""
    (f,), shape = _flat(x)
    return _sin_flat(f).reshape(shape)


def cos_many(x):
    """:func:`cos` of every element of ``x``."""
    (f,), shape = _flat(x)
    return _cos_flat(f).reshape(shape)


def atan2_many(y, x):
    """:func:`atan2` of every pair of elements of ``y`` and ``x`` (broadcast together)."""
    (fy, fx), shape = _flat(y, x)
    return _atan2_flat(fy, fx).reshape(shape)


def norm_rows(v):
    """The length of each row of ``v`` (n, k): the squares summed in column order."""
    v = np.asarray(v, dtype=float)
    s = v[..., 0] * v[..., 0]
    for k in range(1, v.shape[-1]):
        s = s + v[..., k] * v[..., k]
    return np.sqrt(s)


def matvec_rows(a, v):
    """``a[n] v[n]`` for stacks of matrices ``a`` (n, i, j) and vectors ``v`` (n, j).

    Summed in j order.
    Either may be a single matrix or vector, broadcast over the other's stack.
    """
    a = np.asarray(a, dtype=float)
    v = np.asarray(v, dtype=float)
    out = a[..., :, 0] * v[..., None, 0]
    for j in range(1, a.shape[-1]):
        out = out + a[..., :, j] * v[..., None, j]
    return out
