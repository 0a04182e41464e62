"""Calibration sequencer 19 of computer 111: the computations ending Modes 4 and 5.

At the end of the roll (Mode 4) or yaw (Mode 5) calibration turn, master
sequencer 20 starts this sequencer: it steps selector S7 over contacts
121, 125, 127 so that CPU 22 reads up/down counters 14, 16 and 18, and has
the CPU compute the turned axis's scale factor and its two cross-coupling
factors into computed word register 23 (:func:`allsky.computer.cpu.calibrate_roll`,
:func:`allsky.computer.cpu.calibrate_yaw`).

The true angle of the turn is a full turn, 360 deg, in the direction of the
rate command: the optical re-acquisition (star for roll, Sun for yaw)
confirms it. With ``sequencer.recovery`` master sequencer 20 may judge that
more whole turns were flown and pass their number (``turn_sign``).
"""

import numpy as np

from allsky import units
from allsky.computer import cpu
from allsky.hardware import switch_bank
from allsky.vocabulary import SCALE_FACTOR_AXES

FULL_TURN_ARCSEC = 360.0 * units.DEG2ARCSEC
#: The axes a calibration turn can be about.
AXES = SCALE_FACTOR_AXES
#: Register 23's words each calibration turn writes.
WORDS_OF_TURN = {"roll": ("sf_roll", "roll_into_pitch", "roll_into_yaw"),
                 "yaw": ("sf_yaw", "yaw_into_pitch", "yaw_into_roll")}


def calibrate(axis, switches, counters, pulse_weight_arcsec, turn_sign, word23) -> np.ndarray:
    """Read counters 14/16/18 via S7; store ``axis``'s calibration in register 23.

    Parameters
    ----------
    axis : str
        ``"roll"`` (end of Mode 4) or ``"yaw"`` (end of Mode 5).
    switches : numpy.ndarray
        The switch bank; S7/S8 are left on the yaw contact.
    counters : numpy.ndarray
        Up/down counters 14, 16, 18 [pulses].
    pulse_weight_arcsec : float
        [arcsec] per pulse of the converters.
    turn_sign : int
        The turn in signed whole turns: the rate command's sign (+1 or -1)
        times the turns flown (1, or more when ``sequencer.recovery`` counts
        a turn flown on past a missed star or Sun).
    word23 : numpy.ndarray
        Computed word register 23, written in place.

    Returns
    -------
    numpy.ndarray
        The counted angles, roll, pitch, yaw [arcsec].
    """
    if axis not in AXES:
        raise ValueError(f"calibration turn about {axis!r}: only {AXES}")
    counts = np.empty(3)
    for a in range(3):
        switch_bank.select(switches, a)
        counts[a] = counters[a] * pulse_weight_arcsec
    if axis == "roll":
        cpu.calibrate_roll(word23, counts, turn_sign * FULL_TURN_ARCSEC)
    else:
        cpu.calibrate_yaw(word23, counts, turn_sign * FULL_TURN_ARCSEC)
    return counts
