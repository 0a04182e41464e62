"""The switch bank S1-S19 of the patent's block diagram.

The bank is a ``uint8`` array of 20 entries, entry ``k`` for switch Sk (entry
0 unused): 1 = closed, 0 = open. S7 and S8 are single-pole three-position
selectors rather than on/off switches: their entries hold the selected axis
(0 roll contact 121/124, 1 pitch 125/126, 2 yaw 127/128).

Mechanically coupled switches move together and only together: S16 with S18
(roll rate command), S17 with S19 (yaw rate command), S7 with S8 (stepped by
computer sequencer 21). :func:`operate` refuses a request that would move one
member of a pair without the other.

What each switch connects (SPEC section 3):

====  ==========================================================
S1    roll drift DAC 7 -> summing amplifier 4
S2    pitch drift DAC 9 -> summing amplifier 5
S3    yaw drift DAC 11 -> summing amplifier 6
S4    roll VFC 8 -> roll drift counter 13
S5    pitch VFC 10 -> pitch drift counter 15
S6    yaw VFC 12 -> yaw drift counter 17
S7    counters 14/16/18 -> CPU 22 (selector)
S8    CPU 22 -> storage registers 25/26/27 (selector)
S9    roll DAC 28 -> control amplifier 31
S10   pitch DAC 29 -> control amplifier 32
S11   yaw DAC 30 -> control amplifier 33
S12   star tracker yaw output -> control amplifier 31
S13   star tracker pitch output -> control amplifier 32
S14   sun sensor pitch output -> control amplifier 32
S15   sun sensor yaw output -> control amplifier 33
S16   roll rate-command module 120 -> summing amplifier 4
S17   yaw rate-command module 128 -> summing amplifier 6
S18   summing amplifier 4 (line 130) -> control amplifier 31
S19   summing amplifier 6 (line 131) -> control amplifier 33
====  ==========================================================
"""

import numpy as np

N_SWITCHES = 19
COUPLED = {16: 18, 18: 16, 17: 19, 19: 17, 7: 8, 8: 7}
SELECTORS = (7, 8)


class SwitchError(ValueError):
    """A request that would break a mechanical coupling or name no switch."""


def new_bank() -> np.ndarray:
    """All switches open, selectors S7/S8 on the roll contact."""
    return np.zeros(N_SWITCHES + 1, dtype=np.uint8)


def operate(bank: np.ndarray, close=(), open_=()) -> None:
    """Close and open on/off switches by number, respecting the coupled pairs."""
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
    """Step the coupled selectors S7/S8 to ``axis`` (0 roll, 1 pitch, 2 yaw)."""
    if axis not in (0, 1, 2):
        raise SwitchError(f"S7/S8 have contacts for axes 0, 1, 2, not {axis}")
    bank[7] = axis
    bank[8] = axis


def closed(bank: np.ndarray) -> tuple:
    """Numbers of the closed on/off switches."""
    return tuple(k for k in range(1, N_SWITCHES + 1) if k not in SELECTORS and bank[k])


def bitmask(bank) -> int:
    """Bit k-1 set when on/off switch Sk is closed (for telemetry)."""
    m = 0
    for k in range(1, N_SWITCHES + 1):
        if k not in SELECTORS and bank[k]:
            m |= 1 << (k - 1)
    return m
