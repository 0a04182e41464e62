"""What master sequencer 20 asks of the frame loop, leg by leg, and gets back.

A *leg* is one step of a mode: the program computer 111 runs during it, the
condition the sequencer's watch waits for (settle, hand-over or elapsed
time), the watched signals and the time allowed. The loop returns an exit
code; its progress through the leg is kept in ``State.leg_clock`` so that a
paused leg resumes exactly.
"""

from typing import NamedTuple

import numpy as np

# Computer programs a leg can run.
PROGRAM_NONE = 0
PROGRAM_MODE1 = 1  #: the Mode 1 sun-acquisition controller drives the loops
PROGRAM_TARGET_ROLL = 2  #: Mode 6-1: CPU services the roll axis
PROGRAM_TARGET = 3  #: Mode 6-2: CPU services all three axes
PROGRAM_DITHER = 4  #: comparison mode: dither added to the attitude command of the hold
PROGRAM_TARGET_DITHER = 5  #: dither added while the computer holds the target (Mode 6-2 program)

# What ends a leg.
WATCH_SETTLE = 0  #: all signals of ``settle_mask`` below the threshold for ``hold_s``
WATCH_HANDOVER = 1  #: ``handover_signal`` inside the hand-over threshold after ``blank_s``
WATCH_ELAPSED = 2  #: ``hold_s`` of leg time (the ``settle_mask`` signals timed meanwhile)

# Signals the master sequencer watches (index = bit of settle_mask).
SIG_SUN_PITCH = 0
SIG_SUN_YAW = 1
SIG_TRACKER_YAW = 2
SIG_TRACKER_PITCH = 3
SIG_ERROR_ROLL = 4
SIG_ERROR_PITCH = 5
SIG_ERROR_YAW = 6
N_SIGNALS = 7
#: Sun pitch, Sun yaw and tracker yaw: the optical errors of the hold.
SETTLE_OPTICAL = (1 << SIG_SUN_PITCH) | (1 << SIG_SUN_YAW) | (1 << SIG_TRACKER_YAW)

# Leg exit codes.
EXIT_DONE = 1
EXIT_TIMEOUT = -1
EXIT_PROPELLANT = -2
EXIT_SUN_LOST = -3
EXIT_STAR_LOST = -4
EXIT_PAUSE = 2  #: the leg reached its ``pause_at_s``; run it again with ``resume=1``

# Leg progress kept in State.leg_clock, so that a paused leg resumes exactly.
CLOCK_T_LEG = 0  #: [s] time in the leg
CLOCK_SETTLE = 1  #: [s] time the settle condition has held
CLOCK_SUN_GONE = 2  #: [s] time the Sun has been absent while in use
CLOCK_STAR_GONE = 3  #: [s] time the star has been absent while in use
CLOCK_FRAMES = 4  #: [frames] frames run in the leg
N_CLOCK = 5


class Leg(NamedTuple):
    """One step of a mode: what the computer runs and what ends the step."""

    seed: int  #: seeds the noise of this leg (derived from the mission seed and leg number)
    mode_code: float  #: mode number for telemetry (1..5, 6.1, 6.2)
    program: int  #: PROGRAM_*
    watch: int  #: WATCH_*
    settle_mask: int  #: bits of the SIG_* signals that must settle
    handover_signal: int  #: SIG_* watched for WATCH_HANDOVER
    blank_s: float  #: [s] the watched signal is ignored this long after the leg starts
    hold_s: float  #: [s] settle time (WATCH_SETTLE) or duration (WATCH_ELAPSED)
    timeout_s: float  #: [s] the leg gives up after this long
    pause_at_s: float = np.inf  #: [s] mission time at which to pause (EXIT_PAUSE)
    resume: int = 0  #: 1 = continue a paused leg (clock and noise stream carry on)
    #: 1 = the settle time starts from where the previous leg left it (errors that
    #: have *remained* settled), 0 = from zero
    carry_settle: int = 0
