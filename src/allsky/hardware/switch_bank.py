"""The switch bank S1-S19 of the patent's block diagram.

The bank is a ``uint8`` array of 20 entries, entry ``k`` for switch Sk (entry
0 unused): 1 = closed, 0 = open. S7 and S8 are single-pole three-position
selectors rather than on/off switches: their entries hold the selected axis
(0 roll contact 121/124, 1 pitch 125/126, 2 yaw 127/128).

Mechanically coupled switches move together and only together: S16 with S18
(roll rate command), S17 with S19 (yaw rate command), S7 with S8 (stepped by
computer sequencer 21). :func:`operate` refuses a request that would move one
member of a pair without the other.

Switches S1, S2, S3, S4, S5, S6, S7, S8, S9, S10, S11, S12, S13, S14, S15,
S16, S17, S18 and S19 are all here; what each connects is the wiring table,
:mod:`allsky.hardware.wiring`.
"""

import numpy as np

from allsky.hardware.wiring import COUPLED_PAIRS, N_SWITCHES, SELECTORS

#: Switch number -> the switch it is coupled to (both directions).
COUPLED = {**dict(COUPLED_PAIRS), **{b: a for a, b in COUPLED_PAIRS}}


class SwitchError(ValueError):
    """A request that would break a mechanical coupling or name no switch."""


def new_bank() -> np.ndarray:
    """All switches open, selectors S7/S8 on the roll contact."""
    return np.zeros(N_SWITCHES + 1, dtype=np.uint8)


def operate(bank: np.ndarray, close=(), open_=()) -> None:
    """Close and open on/off switches by number, respecting the coupled pairs.

    ``bank`` is the switch bank (:func:`new_bank`), changed in place;
    ``close`` and ``open_`` are iterables of switch numbers (1-19, not the
    selectors S7/S8). A request that moves one member of a coupled pair
    without the other, names no on/off switch, or closes and opens one
    switch at once raises :class:`SwitchError` and changes nothing.
    """
    for group in (close, open_):
        members = set(group)
        for k in members:
            if not 1 <= k <= N_SWITCHES or k in SELECTORS:
                raise SwitchError(f"S{k} is not an on/off switch of the bank")
            mate = COUPLED.get(k)
            if mate is not None and mate not in members:
                raise SwitchError(f"S{k} is coupled to S{mate}: they move together")
    if set(close) & set(open_):
        raise SwitchError("a switch cannot be closed and opened at once")
    for k in close:
        bank[k] = 1
    for k in open_:
        bank[k] = 0


def select(bank: np.ndarray, axis: int) -> None:
    """Step coupled selectors S7/S8 of ``bank`` to ``axis`` (0 roll, 1 pitch, 2 yaw)."""
    if axis not in (0, 1, 2):
        raise SwitchError(f"S7/S8 have contacts for axes 0, 1, 2, not {axis}")
    bank[7] = axis
    bank[8] = axis


def closed(bank: np.ndarray) -> tuple:
    """Numbers of the closed on/off switches of ``bank``, ascending."""
    return tuple(k for k in range(1, N_SWITCHES + 1) if k not in SELECTORS and bank[k])


def bitmask(bank) -> int:
    """Bit k-1 set when on/off switch Sk of ``bank`` is closed (for telemetry)."""
    m = 0
    for k in range(1, N_SWITCHES + 1):
        if k not in SELECTORS and bank[k]:
            m |= 1 << (k - 1)
    return m
