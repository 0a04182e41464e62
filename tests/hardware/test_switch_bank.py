"""Switch bank S1-S19 against the patent's mechanical couplings (SPEC sec. 3).

Truth: S16 moves with S18 (roll rate command 120 and line 130), S17 with S19
(yaw rate command 128 and line 131), selector S7 with selector S8 (stepped by
computer sequencer 21); the patent has switches S1 to S19 and no others.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from allsky.hardware.switch_bank import (
    N_SWITCHES,
    SwitchError,
    bitmask,
    closed,
    new_bank,
    operate,
    select,
)

ON_OFF = [k for k in range(1, 20) if k not in (7, 8)]
PAIRS = [(16, 18), (17, 19)]


def test_new_bank_is_all_open_with_selectors_on_roll():
    bank = new_bank()
    assert N_SWITCHES == 19 and bank.shape == (20,) and bank.dtype == np.uint8
    assert closed(bank) == () and bitmask(bank) == 0
    assert bank[7] == bank[8] == 0


@pytest.mark.parametrize("a, b", PAIRS)
def test_coupled_pairs_move_together(a, b):
    bank = new_bank()
    operate(bank, close=(a, b))
    assert bank[a] == bank[b] == 1
    operate(bank, open_=(b, a))
    assert bank[a] == bank[b] == 0


@pytest.mark.parametrize("request_", [{"close": (16,)}, {"close": (18,)}, {"open_": (17,)},
                                      {"open_": (19,)}, {"close": (16, 17, 18)},
                                      {"close": (16,), "open_": (18,)}])
def test_one_member_of_a_pair_alone_is_refused(request_):
    bank = new_bank()
    before = bank.copy()
    with pytest.raises(SwitchError, match="coupled"):
        operate(bank, **request_)
    assert (bank == before).all()


@pytest.mark.parametrize("k", [7, 8])
def test_selectors_are_not_on_off_switches(k):
    with pytest.raises(SwitchError):
        operate(new_bank(), close=(k,))
    with pytest.raises(SwitchError):
        operate(new_bank(), open_=(7, 8))


@pytest.mark.parametrize("k", [0, -1, 20, 21, 100])
def test_unknown_switch_numbers_are_rejected(k):
    with pytest.raises(SwitchError):
        operate(new_bank(), close=(k,))
    with pytest.raises(SwitchError):
        operate(new_bank(), open_=(k,))


def test_close_and_open_at_once_is_refused():
    bank = new_bank()
    with pytest.raises(SwitchError):
        operate(bank, close=(1, 2), open_=(2,))
    assert closed(bank) == ()


def test_refused_request_changes_nothing():
    bank = new_bank()
    operate(bank, close=(14, 15))
    before = bank.copy()
    with pytest.raises(SwitchError):
        operate(bank, close=(1, 2, 16), open_=(14,))
    assert (bank == before).all()


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_select_sets_both_selectors(axis):
    bank = new_bank()
    select(bank, axis)
    assert bank[7] == bank[8] == axis


@pytest.mark.parametrize("axis", [-1, 3, 7])
def test_select_refuses_a_missing_contact(axis):
    bank = new_bank()
    with pytest.raises(SwitchError):
        select(bank, axis)
    assert bank[7] == bank[8] == 0


def test_closed_and_bitmask_ignore_the_selectors():
    bank = new_bank()
    select(bank, 2)
    operate(bank, close=(1, 9, 17, 19))
    assert closed(bank) == (1, 9, 17, 19)
    assert bitmask(bank) == (1 << 0) | (1 << 8) | (1 << 16) | (1 << 18)


@settings(deadline=None)
@given(st.lists(st.tuples(st.lists(st.integers(-1, 21), max_size=5),
                          st.lists(st.integers(-1, 21), max_size=5)), max_size=20))
def test_no_request_sequence_can_uncouple_a_pair(requests):
    bank = new_bank()
    for close, open_ in requests:
        before = bank.copy()
        try:
            operate(bank, close=close, open_=open_)
        except SwitchError:
            assert (bank == before).all()
        else:
            assert all(bank[k] == 1 for k in close) and all(bank[k] == 0 for k in open_)
        for a, b in PAIRS + [(7, 8)]:
            assert bank[a] == bank[b]
        assert bitmask(bank) == sum(1 << (k - 1) for k in closed(bank))
        assert set(closed(bank)) == {k for k in ON_OFF if bank[k]}
