"""Storage registers 25, 26, 27 against rounding and two's-complement range.

Truth: a register of ``bits`` bits with step ``lsb`` holds the integer
nearest value/lsb (error at most half a step), clamped to
[-2**(bits-1), 2**(bits-1) - 1].
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.storage_register import store

LSB_ARCSEC = 0.25  # scenario default
BITS = 16  # scenario default: full scale 32767 x 0.25" = 8191.75" (just above 7200")


def stored(value_arcsec, axis=1, bits=BITS, lsb=LSB_ARCSEC):
    """Tiny harness: write one register of three and return all three."""
    regs = np.array([11, 22, 33], dtype=np.int64)
    store(regs, axis, float(value_arcsec), bits, lsb)
    return regs


@pytest.mark.parametrize("value, code", [(0.0, 0), (0.1, 0), (0.2, 1), (-0.2, -1),
                                         (7200.0, 28800), (-7200.1, -28800),
                                         (1.0, 4), (1.13, 5), (-1.13, -5)])
def test_rounds_to_nearest_lsb(value, code):
    assert stored(value)[1] == code


@settings(deadline=None)
@given(bits=st.integers(2, 32), data=st.data(),
       lsb=st.floats(1.0e-3, 10.0, allow_nan=False))
def test_in_range_error_is_at_most_half_an_lsb(bits, data, lsb):
    hi = (1 << (bits - 1)) - 1
    value = data.draw(st.floats(-(hi + 0.49) * lsb, (hi + 0.49) * lsb, allow_nan=False))
    code = int(stored(value, bits=bits, lsb=lsb)[1])
    assert abs(code - value / lsb) <= 0.5 + 1e-9


@pytest.mark.parametrize("bits", [2, 8, 16])
def test_saturates_at_full_scale(bits):
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    assert stored((hi + 1) * LSB_ARCSEC, bits=bits)[1] == hi
    assert stored(1e12, bits=bits)[1] == hi
    assert stored((lo - 1) * LSB_ARCSEC, bits=bits)[1] == lo
    assert stored(-1e12, bits=bits)[1] == lo


@settings(deadline=None)
@given(bits=st.integers(2, 32),
       value=st.floats(-1e12, 1e12, allow_nan=False))
def test_word_length_bounds_every_code_and_only_the_axis_moves(bits, value):
    regs = stored(value, axis=2, bits=bits)
    assert -(1 << (bits - 1)) <= regs[2] <= (1 << (bits - 1)) - 1
    assert regs[:2].tolist() == [11, 22]
