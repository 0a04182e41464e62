"""Master sequencer 20: the six modes, their switch actions and exit rules.

Each mode is one function below, written as the patent describes it (SPEC
section 4): switch actions, then the condition the sequencer waits for.
Waiting is done by the compiled frame loop (:func:`allsky.sim.frame_loop.run_leg`);
a step that does not finish within what is left of the mode's timeout ends
the mission as aborted, with the reason.

Calibration sequencer 19 is the part that, at the end of Modes 4 and 5,
has CPU 22 read the counters through S7 and store the results in
register 23 (:func:`calibration_sequencer`).
"""


import numpy as np

from allsky import units
from allsky.computer import cpu
from allsky.computer import word_registers as wr
from allsky.hardware import switch_bank
from allsky.sequencer.legs import (
    PROGRAM_MODE1,
    PROGRAM_NONE,
    PROGRAM_TARGET,
    PROGRAM_TARGET_ROLL,
    SIG_ERROR_PITCH,
    SIG_ERROR_ROLL,
    SIG_ERROR_YAW,
    SIG_SUN_PITCH,
    SIG_SUN_YAW,
    SIG_TRACKER_PITCH,
    SIG_TRACKER_YAW,
    WATCH_ELAPSED,
    WATCH_HANDOVER,
    WATCH_SETTLE,
)

MODES = ("1", "2", "3", "4", "5", "6-1", "6-2")
FULL_TURN_ARCSEC = 360.0 * units.DEG2ARCSEC


def _mask(*signals):
    m = 0
    for k in signals:
        m |= 1 << k
    return m


OPTICAL = _mask(SIG_SUN_PITCH, SIG_SUN_YAW, SIG_TRACKER_YAW)


class ModeAbort(Exception):
    """A mode could not finish; the message is the abort reason."""


def mode_1(m):
    """Sun orientation: the Mode 1 controller nulls rates and puts +x on the Sun."""
    m.leg("sun acquired and settled", PROGRAM_MODE1, WATCH_SETTLE,
          mask=_mask(SIG_SUN_PITCH, SIG_SUN_YAW))
    m.switch(close=(14, 15))
    return "sun pitch and yaw settled; S14, S15 closed"


def mode_2(m):
    """Stellar acquisition: roll about the Sun line until the star is 2 deg off, then lock."""
    m.state.rate_sign[0] = 1
    m.switch(close=(16, 18))
    m.leg("star in the magnitude window", PROGRAM_NONE, WATCH_HANDOVER,
          signal=SIG_TRACKER_YAW,
          on_timeout="no star in the tracker's magnitude window during the acquisition roll")
    m.switch(open_=(16, 18), close=(12,))
    m.leg("locked on Sun and star", PROGRAM_NONE, WATCH_SETTLE, mask=OPTICAL)
    return "tracker yaw and sun pitch/yaw settled"


def mode_3(m):
    """Gyro drift calibration: count each gyro's pulses over the drift interval."""
    m.state.drift_counters[:] = 0
    m.switch(close=(4, 5, 6))
    m.leg("drift count", PROGRAM_NONE, WATCH_ELAPSED, hold_s=m.drift_count_s)
    m.switch(open_=(4, 5, 6), close=(1, 2, 3))
    m.leg("optical errors settled", PROGRAM_NONE, WATCH_SETTLE, mask=OPTICAL)
    return f"drift counted over {m.drift_count_s:g} s; S1-S3 closed"


def mode_4(m):
    """Roll calibration: roll 360 deg about the Sun line and re-acquire the star."""
    m.state.counters[:] = 0
    m.state.rate_sign[0] = 1
    m.switch(open_=(12,), close=(16, 18))
    m.leg("star re-acquired after a full roll", PROGRAM_NONE, WATCH_HANDOVER,
          signal=SIG_TRACKER_YAW, blank_s=m.blanking_s,
          on_timeout="star not re-acquired after the calibration roll")
    m.switch(open_=(16, 18), close=(12,))
    m.leg("settled on Sun and star", PROGRAM_NONE, WATCH_SETTLE, mask=OPTICAL)
    calibration_sequencer(m, "roll")
    return "roll scale factor and roll cross-coupling stored in register 23"


def mode_5(m):
    """Yaw calibration: pitch to the star, yaw 360 deg about it, re-acquire the Sun, pitch back."""
    m.state.counters[:] = 0
    m.state.rate_sign[1] = 1
    m.switch(close=(13,), open_=(14,))
    m.leg("tracker pitch nulled", PROGRAM_NONE, WATCH_SETTLE, mask=_mask(SIG_TRACKER_PITCH))
    m.switch(open_=(15,), close=(17, 19))
    m.leg("Sun re-acquired in yaw after a full yaw", PROGRAM_NONE, WATCH_HANDOVER,
          signal=SIG_SUN_YAW, blank_s=m.blanking_s,
          on_timeout="Sun not re-acquired after the calibration yaw")
    m.switch(open_=(17, 19), close=(15,))
    m.leg("settled on star (yaw, pitch) and Sun yaw", PROGRAM_NONE, WATCH_SETTLE,
          mask=_mask(SIG_TRACKER_YAW, SIG_TRACKER_PITCH, SIG_SUN_YAW))
    m.switch(close=(14,), open_=(13,))
    m.leg("pitched back, settled on Sun and star", PROGRAM_NONE, WATCH_SETTLE, mask=OPTICAL)
    calibration_sequencer(m, "yaw")
    return "yaw scale factor and yaw cross-coupling stored in register 23"


def calibration_sequencer(m, axis):
    """Calibration sequencer 19: CPU 22 reads counters 14/16/18 via S7 and fills register 23."""
    counts = np.empty(3)
    for a in range(3):
        switch_bank.select(m.state.switches, a)
        counts[a] = m.state.counters[a] * m.pulse_weight_arcsec
    if axis == "roll":
        cpu.calibrate_roll(m.state.word23, counts, m.state.rate_sign[0] * FULL_TURN_ARCSEC)
    else:
        cpu.calibrate_yaw(m.state.word23, counts, m.state.rate_sign[1] * FULL_TURN_ARCSEC)
    m.counted_arcsec[axis] = counts.tolist()


def mode_6_1(m):
    """Target roll: roll through the programmed roll angle on the roll gyro, Sun holding pitch/yaw."""
    s = m.state
    if not m.apply_calibration:
        s.word23[:] = wr.neutral_computed()
        m.switch(open_=(1, 2, 3))
    s.word24[wr.PROGRAMMED_ROLL] = m.programmed_roll_deg * units.DEG2ARCSEC
    s.word24[wr.PROGRAMMED_YAW] = m.programmed_yaw_deg * units.DEG2ARCSEC
    s.counters[:] = 0
    s.cpu[:] = 0.0
    cpu.target_step(0, 0.0, s.word23, s.word24, s.cpu)
    s.rate_sign[0] = 1 if s.word24[wr.PROGRAMMED_ROLL] >= 0 else -1
    m.switch(open_=(12,), close=(16, 18))
    m.leg("roll error inside the hand-over threshold", PROGRAM_TARGET_ROLL, WATCH_HANDOVER,
          signal=SIG_ERROR_ROLL)
    m.switch(open_=(16, 18), close=(9,))
    m.leg("roll error and Sun errors settled", PROGRAM_TARGET_ROLL, WATCH_SETTLE,
          mask=_mask(SIG_ERROR_ROLL, SIG_SUN_PITCH, SIG_SUN_YAW))
    pitch_arcsec, yaw_arcsec = cpu.mode6_preset_arcsec(s.word23, s.cpu)
    s.counters[1] = round(pitch_arcsec / m.pulse_weight_arcsec)
    s.counters[2] = round(yaw_arcsec / m.pulse_weight_arcsec)
    return "roll settled; pitch and yaw counters preset"


def mode_6_2(m):
    """Target yaw: yaw through the programmed yaw angle on the gyros alone."""
    s = m.state
    cpu.target_step(2, s.counters[2] * m.pulse_weight_arcsec, s.word23, s.word24, s.cpu)
    cpu.target_step(1, s.counters[1] * m.pulse_weight_arcsec, s.word23, s.word24, s.cpu)
    s.rate_sign[1] = 1 if s.cpu[cpu.ERROR_YAW] >= 0 else -1
    m.switch(open_=(14, 15), close=(17, 19, 10))
    m.leg("yaw error inside the hand-over threshold", PROGRAM_TARGET, WATCH_HANDOVER,
          signal=SIG_ERROR_YAW)
    m.switch(open_=(17, 19), close=(11,))
    m.leg("roll, pitch and yaw errors settled", PROGRAM_TARGET, WATCH_SETTLE,
          mask=_mask(SIG_ERROR_ROLL, SIG_ERROR_PITCH, SIG_ERROR_YAW))
    return "on target: computed errors settled"


RULES = {"1": mode_1, "2": mode_2, "3": mode_3, "4": mode_4, "5": mode_5,
         "6-1": mode_6_1, "6-2": mode_6_2}
MODE_CODE = {"1": 1.0, "2": 2.0, "3": 3.0, "4": 4.0, "5": 5.0, "6-1": 6.1, "6-2": 6.2}
#: What each mode does, for displays.
MODE_TITLE = {"1": "Sun orientation", "2": "Canopus acquisition", "3": "drift calibration",
              "4": "roll calibration, 360 deg roll", "5": "yaw calibration, 360 deg yaw",
              "6-1": "target acquisition, roll", "6-2": "target acquisition, yaw"}
assert set(RULES) == set(MODES) == set(MODE_TITLE)
