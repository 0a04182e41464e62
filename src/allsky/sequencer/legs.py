"""What master sequencer 20 asks of the frame loop, leg by leg, and gets back.

A *leg* is one step of a mode: the program computer 111 runs during it, the
condition the sequencer's watch waits for (settle, hand-over or elapsed
time), the watched signals and the time allowed. The loop returns an exit
code; its progress through the leg is kept in ``State.leg_clock`` so that a
paused leg resumes exactly. Every time of a leg is a whole number of frames
(:mod:`allsky.clock`): the mission driver converts the sequencer's seconds
by the clock's rule, and the loop counts frames.
"""

from typing import NamedTuple

from allsky.clock import NEVER

# Computer programs a leg can run.
PROGRAM_NONE = 0
PROGRAM_MODE1 = 1  #: the Mode 1 sun-acquisition controller drives the loops
PROGRAM_TARGET_ROLL = 2  #: Mode 6-1: CPU services the roll axis
PROGRAM_TARGET = 3  #: Mode 6-2: CPU services all three axes
PROGRAM_DITHER = 4  #: comparison mode: dither added to the attitude command of the hold
PROGRAM_TARGET_DITHER = 5  #: dither added while the computer holds the target (Mode 6-2 program)

# What ends a leg.
WATCH_SETTLE = 0  #: all signals of ``settle_mask`` below the threshold for ``hold_frames``
#: ``handover_signal`` inside the hand-over threshold once ``blank_frames`` have passed
WATCH_HANDOVER = 1
WATCH_ELAPSED = 2  #: ``hold_frames`` of the leg (the ``settle_mask`` signals timed meanwhile)

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
EXIT_PAUSE = 2  #: the leg reached its ``pause_at_frame``; run it again with ``resume=1``

# Leg progress kept in State.leg_clock [frames], so that a paused leg resumes exactly.
CLOCK_FRAMES = 0  #: frames run in the leg
CLOCK_SETTLE = 1  #: frames the settle condition has held
CLOCK_SUN_GONE = 2  #: frames the Sun has been absent while in use
CLOCK_STAR_GONE = 3  #: frames the star has been absent while in use
N_CLOCK = 4


class Leg(NamedTuple):
    """One step of a mode: what the computer runs and what ends the step."""

    seed: int  #: seeds the noise of this leg (derived from the mission seed and leg number)
    mode_code: float  #: mode number for telemetry (1..5, 6.1, 6.2)
    program: int  #: PROGRAM_*
    watch: int  #: WATCH_*
    settle_mask: int  #: bits of the SIG_* signals that must settle
    handover_signal: int  #: SIG_* watched for WATCH_HANDOVER
    #: [frames] the watched signal is ignored for this many frames of the leg; a hand-over
    #: counts from the next
    blank_frames: int
    hold_frames: int  #: [frames] settle time (WATCH_SETTLE) or length (WATCH_ELAPSED)
    timeout_frames: int  #: [frames] the leg gives up after this many
    #: the mission's frame at which to pause (EXIT_PAUSE); NEVER: none
    pause_at_frame: int = NEVER
    resume: int = 0  #: 1 = continue a paused leg (clock and noise stream carry on)
    #: 1 = the settle time starts from where the previous leg left it (errors that
    #: have *remained* settled), 0 = from zero
    carry_settle: int = 0
