"""Computer sequencer 21: steps selectors S7/S8 over the three axes.

Every ``step_frames`` frames the coupled selectors move to the next axis
(roll -> pitch -> yaw -> roll ...), so the CPU reads one axis's up/down
counter through S7 and writes that axis's storage register through S8.
"""

from allsky.jit import njit


@njit
def sequencer_step(bank, frame, step_frames):
    """Position S7/S8 for ``frame``; returns the axis selected, or -1 between steps.

    ``bank`` is the switch bank (S7/S8 written in place when they step),
    ``frame`` the mission's frame count and ``step_frames`` the frames per
    step (``ElectronicsParams.computer_step_frames``).
    """
    if frame % step_frames != 0:
        return -1
    axis = (frame // step_frames) % 3
    bank[7] = axis
    bank[8] = axis
    return axis
