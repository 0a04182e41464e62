"""The mission clock: the frame index, and the one rule that puts times on frames.

The mission's time is its frame index ``n``. Every time the program reports
is computed from it, never summed frame by frame: ``t = n * frame_s``, with
the frame length taken as the decimal the scenario gives
(``mission.frame_s = 0.01`` is exactly 1/100 s), so ``t = (n * num) / den``
in one correctly rounded division of integers. A time on the frame grid is
then the double nearest its decimal: frame 131307 is 1313.07 s, printed as
``1313.07`` in JSON, CSV and Parquet (a sum of 0.01 s steps gave
1313.0699999989508).

**The rule.** Anything scheduled at a mission time ``t`` -- a fault's start,
a ground command, a pause, a telemetry row, the end of a session -- acts at
the start of the first frame that starts at or after ``t``:
``frame_at(t) = ceil(t / frame_s)``, computed exactly on the decimals the
scenario or the command log gives (``t`` as its shortest decimal, ``repr``).
A time on the grid lands on its own frame; a time between two frames on the
next one. A duration ``d`` from a frame covers ``frames_for(d) = ceil(d /
frame_s)`` frames; "longer than ``d``" is more than ``frames_within(d) =
floor(d / frame_s)`` frames. The frame loop, the ground commands, the
``[[faults]]`` table, the replay and the live server all use these
functions, so a commanded fault at 812.5 s and its ``[[faults]]`` twin with
``start_s = 812.5`` begin in the same frame.

Compiled code has the clock as :class:`ClockParams` (``Params.clock``) and
:func:`frame_time`, the same division.
"""

import functools
import math
from fractions import Fraction
from typing import NamedTuple

from allsky.jit import jitable

#: A frame index no flight reaches: "never" (a pause not asked for, a permanent fault).
NEVER = 2 ** 62


class ClockParams(NamedTuple):
    """The frame length as the fraction ``num / den`` of a second the scenario wrote.

    ``num / den`` rounded is the frame step the physics integrates over
    (``Params.frame_s``).
    """

    num: int  #: numerator of the frame length [s]
    den: int  #: its denominator


def decimal(value) -> Fraction:
    """A number as the decimal written for it: a float by its shortest ``repr``.

    ``value`` is an int, a float or a Fraction. ``0.1`` is 1/10, not the
    binary double just above it.
    """
    if isinstance(value, Fraction):
        return value
    if isinstance(value, int):
        return Fraction(value)
    return _float_decimal(float(value))


@functools.lru_cache(maxsize=4096)
def _float_decimal(value: float) -> Fraction:
    """:func:`decimal` of a float, kept: a mission asks for the same few durations at every
    leg, and parsing a repr into a Fraction takes some 5 us."""
    return Fraction(repr(value))


def clock(frame_s) -> ClockParams:
    """The clock of a frame length ``frame_s`` [s] (a positive decimal)."""
    f = decimal(frame_s)
    if f <= 0:
        raise ValueError(f"frame length {frame_s!r} s must be positive")
    return ClockParams(f.numerator, f.denominator)


@functools.lru_cache(maxsize=64)
def _frame_length(c: ClockParams) -> Fraction:
    """[s] the frame length of clock ``c`` as a Fraction."""
    return Fraction(c.num, c.den)


def time_s(c: ClockParams, frame) -> float:
    """[s] the mission time at the start of frame ``frame`` (an integer), rounded once.

    Also the length of a span of ``frame`` frames. ``c`` is the clock.
    """
    return (int(frame) * c.num) / c.den


@jitable
def frame_time(c, frame):
    """[s] :func:`time_s` in compiled code: ``frame * num / den``, one rounding.

    ``c`` is the :class:`ClockParams`; ``frame`` below 2^53 / ``num``, so
    that the product is exact.
    """
    return float(frame * c.num) / float(c.den)


def frame_at(c: ClockParams, t_s) -> int:
    """The first frame that starts at or after mission time ``t_s`` [s] (the rule).

    ``t_s`` is taken as its decimal (:func:`decimal`); an infinite time is
    :data:`NEVER`, a negative one frame 0. ``c`` is the clock.
    """
    if isinstance(t_s, float) and math.isinf(t_s):
        return NEVER if t_s > 0 else 0
    return max(0, math.ceil(decimal(t_s) / _frame_length(c)))


def frames_for(c: ClockParams, d_s) -> int:
    """Frames a duration ``d_s`` [s] covers from a frame: ``ceil(d / frame_s)``.

    An infinite duration is :data:`NEVER`. ``c`` is the clock.
    """
    if isinstance(d_s, float) and math.isinf(d_s):
        return NEVER
    return max(0, math.ceil(decimal(d_s) / _frame_length(c)))


def frames_within(c: ClockParams, d_s) -> int:
    """The most frames that last no longer than ``d_s`` [s]: ``floor(d / frame_s)``.

    Something that must last *longer* than ``d_s`` lasts more than this many
    frames. An infinite duration is :data:`NEVER`. ``c`` is the clock.
    """
    if isinstance(d_s, float) and math.isinf(d_s):
        return NEVER
    return max(0, math.floor(decimal(d_s) / _frame_length(c)))
