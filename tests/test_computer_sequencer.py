"""Computer sequencer 21 against its stepping rule (SPEC sec. 3).

Truth: every ``step_frames`` frames the coupled selectors S7/S8 move to the
next axis, roll -> pitch -> yaw -> roll, so that frame f (a multiple of
step_frames) selects axis (f / step_frames) mod 3; in between there is no
step (-1) and the selectors stay where they are.
"""

import pytest

from allsky.computer.computer_sequencer import sequencer_step
from allsky.hardware.switch_bank import new_bank


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
