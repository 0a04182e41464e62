"""The sequencers of computer 111: computer sequencer 21 and calibration sequencer 19.

Truth for 21 (SPEC sec. 3): every ``step_frames`` frames the coupled
selectors S7/S8 move to the next axis, roll -> pitch -> yaw -> roll, so that
frame f (a multiple of step_frames) selects axis (f / step_frames) mod 3; in
between there is no step (-1) and the selectors stay where they are.

Truth for 19 (SPEC sec. 4, calibration arithmetic): after a turn of 360 deg
in the direction ``sign``, scale factor = sign * 360 deg / counted angle of
the turned axis; cross-coupling = counted angle of the other axis / (sign *
360 deg); counted angle = counter [pulses] x pulse weight [arcsec].
"""

import numpy as np
import pytest

from allsky.computer import word_registers as wr
from allsky.computer.calibration_sequencer import FULL_TURN_ARCSEC, calibrate
from allsky.computer.computer_sequencer import sequencer_step
from allsky.hardware.switch_bank import new_bank

PULSE_WEIGHT_ARCSEC = 0.1  # scenarios/default.toml, electronics.vfc_pulse_weight_arcsec


@pytest.mark.parametrize("step_frames", [1, 2, 5, 7])
def test_steps_roll_pitch_yaw_every_step_frames(step_frames):
    bank = new_bank()
    selected = []
    for frame in range(12 * step_frames):
        before = (int(bank[7]), int(bank[8]))
        axis = sequencer_step(bank, frame, step_frames)
        if frame % step_frames:
            assert axis == -1
            assert (bank[7], bank[8]) == before
        else:
            assert bank[7] == bank[8] == axis
            selected.append(axis)
    assert selected == [0, 1, 2] * 4


def test_sequence_follows_the_frame_number_not_a_call_count():
    """A leg resumed at frame 3001 picks up the cycle where the frame number puts it."""
    bank = new_bank()
    assert sequencer_step(bank, 3001, 1) == 3001 % 3 == 1
    assert sequencer_step(bank, 3002, 2) == 1501 % 3 == 1
    assert sequencer_step(bank, 3003, 2) == -1
    assert bank[7] == bank[8] == 1


def test_other_switches_are_untouched():
    bank = new_bank()
    bank[1:7] = 1
    bank[9:] = 1
    for frame in range(10):
        sequencer_step(bank, frame, 1)
    assert bank[1:7].tolist() == [1] * 6 and bank[9:].tolist() == [1] * 11


@pytest.mark.parametrize("sign", [1, -1])
def test_calibration_sequencer_roll_turn(sign):
    counters = np.array([sign * 12_963_000, 6_480, -1_296], dtype=np.int64)  # [pulses]
    w = wr.neutral_computed()
    bank = new_bank()
    counts = calibrate("roll", bank, counters, PULSE_WEIGHT_ARCSEC, sign, w)
    np.testing.assert_array_equal(counts, counters * PULSE_WEIGHT_ARCSEC)
    turn = sign * FULL_TURN_ARCSEC
    assert FULL_TURN_ARCSEC == 1_296_000.0
    assert w[wr.SF_ROLL] == pytest.approx(turn / (sign * 1_296_300.0), rel=1e-15)
    assert w[wr.ROLL_INTO_PITCH] == pytest.approx(648.0 / turn, rel=1e-15)
    assert w[wr.ROLL_INTO_YAW] == pytest.approx(-129.6 / turn, rel=1e-15)
    # The yaw results are untouched; the selectors end on the last contact read (yaw).
    neutral = wr.neutral_computed()
    assert w[wr.SF_YAW] == neutral[wr.SF_YAW] and w[wr.YAW_INTO_ROLL] == neutral[wr.YAW_INTO_ROLL]
    assert bank[7] == bank[8] == 2


def test_calibration_sequencer_yaw_turn():
    counters = np.array([2_592, -3_888, 12_958_704], dtype=np.int64)
    w = wr.neutral_computed()
    calibrate("yaw", new_bank(), counters, PULSE_WEIGHT_ARCSEC, 1, w)
    assert w[wr.SF_YAW] == pytest.approx(1_296_000.0 / 1_295_870.4, rel=1e-15)
    assert w[wr.YAW_INTO_ROLL] == pytest.approx(259.2 / 1_296_000.0, rel=1e-15)
    assert w[wr.YAW_INTO_PITCH] == pytest.approx(-388.8 / 1_296_000.0, rel=1e-15)


def test_calibration_sequencer_turns_only_about_roll_or_yaw():
    with pytest.raises(ValueError, match="pitch"):
        calibrate("pitch", new_bank(), np.ones(3, dtype=np.int64), PULSE_WEIGHT_ARCSEC, 1,
                  wr.neutral_computed())
