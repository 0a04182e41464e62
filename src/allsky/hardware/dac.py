"""Digital-to-analogue converters: drift DACs 7, 9, 11 and axis DACs 28, 29, 30.

A DAC of ``bits`` bits turns a signed integer code into ``code * lsb``, the
code clipped to ``[-2**(bits-1), 2**(bits-1) - 1]``: the quantisation step and
the full scale are real.

* Drift DAC: code = drift counter content [pulses counted over the drift
  interval]; lsb = pulse weight / interval [arcsec/s per count], so the
  output is the mean drift rate measured in Mode 3.
* Axis DAC: code = storage register content; lsb = register LSB [arcsec].
"""

from allsky.jit import njit


@njit
def dac(code, bits, lsb):
    """Analogue value of signed ``code`` through a ``bits``-bit DAC with step ``lsb``."""
    hi = (1 << (bits - 1)) - 1
    lo = -(1 << (bits - 1))
    if code > hi:
        code = hi
    elif code < lo:
        code = lo
    return code * lsb
