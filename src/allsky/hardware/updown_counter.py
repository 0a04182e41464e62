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
    """Add ``pulses`` to ``counters[index]``; latch ``overflow[flag]`` on overflow.

    Parameters
    ----------
    counters : numpy.ndarray
        [pulses] int64 contents of a bank of counters (14/16/18, or the
        drift counters 13/15/17), updated.
    index : int
        The counter of the bank: 0, 1, 2 for roll, pitch, yaw.
    pulses : int
        Signed pulses of the frame from the converter.
    bits : int
        The counter's length in bits (two's complement).
    mode : int
        :data:`WRAP` or :data:`SATURATE`, what an overflow does.
    overflow : numpy.ndarray
        int64 overflow flags, latched to 1 (never cleared here).
    flag : int
        Which of ``overflow`` is this counter's.
    """
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
