"""Up/down counters 14, 16, 18 and drift counters 13, 15, 17 against integer arithmetic.

Truth: a ``bits``-bit two's-complement counter spans
[-2**(bits-1), 2**(bits-1) - 1]. Wrapping it is Python's integer sum taken
modulo 2**bits and mapped back to that signed range; saturating it is the sum
clamped step by step to the range. Either way an excursion beyond the range
latches the overflow flag, which never clears by itself.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.updown_counter import SATURATE, WRAP, count


def signed_wrap(v: int, bits: int) -> int:
    """v modulo 2**bits, as a two's-complement signed value."""
    v &= (1 << bits) - 1
    return v - (1 << bits) if v >> (bits - 1) else v


class Harness:
    """Three counters and six flags, laid out as in the kernel's State."""

    def __init__(self, bits, mode, start=0):
        self.bits, self.mode = bits, mode
        self.counters = np.array([start, 0, 0], dtype=np.int64)
        self.overflow = np.zeros(6, dtype=np.int64)

    def add(self, pulses, index=0, flag=0):
        count(self.counters, index, pulses, self.bits, self.mode, self.overflow, flag)
        return int(self.counters[index])


@pytest.mark.parametrize("bits", [4, 16, 28])
@pytest.mark.parametrize("mode", [WRAP, SATURATE])
def test_full_range_holds_without_overflow(bits, mode):
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    h = Harness(bits, mode)
    assert h.add(hi) == hi
    assert h.add(lo - hi) == lo
    assert not h.overflow.any()


@pytest.mark.parametrize("bits", [4, 16, 28])
def test_wrap_and_saturate_one_past_each_end(bits):
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    assert Harness(bits, WRAP, hi).add(1) == lo
    assert Harness(bits, WRAP, lo).add(-1) == hi
    assert Harness(bits, SATURATE, hi).add(1) == hi
    assert Harness(bits, SATURATE, lo).add(-1) == lo


@pytest.mark.parametrize("mode", [WRAP, SATURATE])
@pytest.mark.parametrize("flag", [0, 2, 3, 5])
def test_overflow_latches_at_its_own_flag_and_stays_set(mode, flag):
    h = Harness(8, mode, start=120)
    h.add(10, flag=flag)  # 130 > 127
    expected = np.zeros(6, dtype=np.int64)
    expected[flag] = 1
    assert h.overflow.tolist() == expected.tolist()
    h.add(-50, flag=flag)  # back well inside the range
    h.counters[0] = 0  # even a reset of the content leaves the flag
    h.add(1, flag=flag)
    assert h.overflow.tolist() == expected.tolist()


def test_only_the_indexed_counter_moves():
    h = Harness(16, WRAP)
    h.counters[:] = [5, 6, 7]
    h.add(100, index=1, flag=4)
    assert h.counters.tolist() == [5, 106, 7]


def test_full_roll_fits_the_default_28_bit_counter():
    """A 360 deg turn at 0.1 "/pulse is 12 960 000 pulses: fits 28 bits (2**27 - 1 =
    134 217 727), would overflow 24 bits (2**23 - 1 = 8 388 607). Scenario defaults."""
    assert Harness(28, WRAP).add(12_960_000) == 12_960_000
    h = Harness(24, WRAP)
    assert h.add(12_960_000) == 12_960_000 - (1 << 24)
    assert h.overflow[0] == 1


# Word lengths up to 62 bits, the scenario limit (allsky.config.scenario): sums stay in int64.
pulse_lists = st.lists(st.integers(-(1 << 44), 1 << 44), min_size=1, max_size=30)


@settings(deadline=None)
@given(bits=st.integers(2, 62), start=st.integers(-(1 << 61), (1 << 61) - 1),
       pulses=pulse_lists)
def test_wrap_is_python_arithmetic_modulo_2_to_the_bits(bits, start, pulses):
    start = signed_wrap(start, bits)
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    h = Harness(bits, WRAP, start)
    v, overflowed, total = start, False, start
    for n in pulses:
        overflowed |= not lo <= v + n <= hi
        v = signed_wrap(v + n, bits)
        total += n
        assert h.add(n) == v == signed_wrap(total, bits)
        assert h.overflow[0] == overflowed


@settings(deadline=None)
@given(bits=st.integers(2, 62), start=st.integers(-(1 << 61), (1 << 61) - 1),
       pulses=pulse_lists)
def test_saturate_is_the_clamped_running_sum(bits, start, pulses):
    start = signed_wrap(start, bits)
    hi, lo = (1 << (bits - 1)) - 1, -(1 << (bits - 1))
    h = Harness(bits, SATURATE, start)
    v, overflowed = start, False
    for n in pulses:
        overflowed |= not lo <= v + n <= hi
        v = min(max(v + n, lo), hi)
        assert h.add(n) == v
        assert h.overflow[0] == overflowed
