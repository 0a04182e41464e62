"""The one place that decides how blocks are compiled.

Every per-frame block is a small function decorated with :func:`njit`.
``NUMBA_DISABLE_JIT=1`` turns them back into plain Python with identical
results, for stepping through with a debugger.
"""

import numba

# cache=True keeps compiled code between processes (Monte Carlo workers,
# repeated CLI runs); fastmath stays off so that the plain-Python path gives
# the same bits.
njit = numba.njit(cache=True, nogil=True)
