"""Up/down counters 14, 16, 18 and drift up/down counters 13, 15, 17.

Signed two's-complement integers of ``bits`` bits, range
``[-2**(bits-1), 2**(bits-1) - 1]``. On overflow the counter either wraps
(as a bare binary counter does) or saturates at the end of its range; either
way the event is latched in an overflow flag that telemetry reports.
"""

from allsky.jit import njit

WRAP = 0
SATURATE = 1


@njit
def count(counters, index, pulses, bits, mode, overflow, flag):
    """Add ``pulses`` to ``counters[index]``; latch ``overflow[flag]`` on overflow."""
    hi = (1 << (bits - 1)) - 1
    lo = -(1 << (bits - 1))
    v = counters[index] + pulses
    if v > hi or v < lo:
        overflow[flag] = 1
        if mode == SATURATE:
            v = hi if v > hi else lo
        else:
            span = 1 << bits
            v = (v - lo) % span + lo
    counters[index] = v
