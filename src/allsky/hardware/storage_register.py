"""Storage registers 25 (roll), 26 (pitch), 27 (yaw).

Written by CPU 22 through selector S8 with an angle error [arcsec]; each
holds it as a signed integer of ``bits`` bits in units of ``lsb_arcsec``
(rounded to nearest, saturated at full scale), to be read by DACs 28-30.
"""

from allsky.jit import njit


@njit
def store(registers, axis, value_arcsec, bits, lsb_arcsec):
    """Quantise ``value_arcsec`` into ``registers[axis]``.

    ``registers`` is the (3,) int64 array of registers 25, 26, 27 [LSB]
    (``State.registers``), ``axis`` 0 roll, 1 pitch, 2 yaw; ``value_arcsec``
    is CPU 22's angle error [arcsec], held as a signed word of ``bits`` bits
    whose least significant bit weighs ``lsb_arcsec`` [arcsec].
    """
    hi = (1 << (bits - 1)) - 1
    lo = -(1 << (bits - 1))
    code = round(value_arcsec / lsb_arcsec)
    if code > hi:
        code = hi
    elif code < lo:
        code = lo
    registers[axis] = code
