"""DACs: drift DACs 7, 9, 11 and axis DACs 28, 29, 30, against their transfer function.

Truth: a ``bits``-bit converter with step ``lsb`` outputs ``code * lsb`` for
codes in the two's-complement range [-2**(bits-1), 2**(bits-1) - 1] and the
nearer end of that range beyond it, so its full scale is asymmetric: one
step less on the positive side.
"""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.dac import dac


@settings(deadline=None)
@given(bits=st.integers(2, 32), data=st.data(),
       lsb=st.floats(1.0e-6, 1.0e3, allow_nan=False, allow_infinity=False))
def test_in_range_output_is_code_times_lsb(bits, data, lsb):
    code = data.draw(st.integers(-(1 << (bits - 1)), (1 << (bits - 1)) - 1))
    assert dac(code, bits, lsb) == code * lsb


@pytest.mark.parametrize("bits", [2, 12, 16])
def test_full_scale_is_asymmetric_and_clips(bits):
    lsb = 0.25  # register LSB [arcsec], scenario default
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    assert dac(hi, bits, lsb) == hi * lsb
    assert dac(lo, bits, lsb) == lo * lsb
    assert dac(hi + 1, bits, lsb) == hi * lsb
    assert dac(lo - 1, bits, lsb) == lo * lsb
    assert dac(10**9, bits, lsb) == hi * lsb
    assert dac(-(10**9), bits, lsb) == lo * lsb
    assert -dac(lo, bits, lsb) - dac(hi, bits, lsb) == lsb


@settings(deadline=None)
@given(bits=st.integers(2, 32), data=st.data())
def test_quantisation_step_is_one_lsb(bits, data):
    lsb = 2.0**-4  # dyadic, so the difference is exact
    code = data.draw(st.integers(-(1 << (bits - 1)), (1 << (bits - 1)) - 2))
    assert dac(code + 1, bits, lsb) - dac(code, bits, lsb) == lsb


@settings(deadline=None)
@given(drift_arcsec_s=st.floats(-5.0, 5.0, allow_nan=False))
def test_drift_dac_returns_the_mode3_mean_drift_to_one_lsb(drift_arcsec_s):
    """Drift DAC (SPEC sec. 4, Mode 3): a drift d counted over T at pulse weight w leaves
    trunc(d T / w) pulses in the drift counter; with lsb = w / T the DAC gives d back,
    never more in magnitude and short by less than one lsb. Defaults: w = 0.1",
    T = 40 s, 12 bits (full scale 2047 x 0.0025 = 5.1175 "/s = 5.1 deg/h)."""
    w, t, bits = 0.1, 40.0, 12
    lsb = w / t
    code = math.trunc(drift_arcsec_s * t / w)
    out = dac(code, bits, lsb)
    assert abs(out) <= abs(drift_arcsec_s) + 1e-12
    assert abs(drift_arcsec_s - out) < lsb + 1e-12


def test_drift_beyond_full_scale_saturates():
    """6 deg/h = 6 "/s > 5.1175 "/s full scale of the default 12-bit drift DAC."""
    code = math.trunc(6.0 * 40.0 / 0.1)
    assert dac(code, 12, 0.1 / 40.0) == pytest.approx(2047 * 0.0025)
