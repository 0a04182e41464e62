"""CPU 22 of computer 111: the calibration and target-acquisition arithmetic.

Calibration (end of Modes 4 and 5, SPEC section 4)::

    scale factor   = true angle / counted angle
    cross-coupling = counts accumulated on the other axis / true angle

Target acquisition, each time computer sequencer 21 selects an axis
(Mode 6-1 services roll only; Mode 6-2 all three axes)::

    1. corrections   = latest corrected roll / yaw x stored cross-coupling factors
    2. intermediate  = counter angle - corrections into that axis
    3. corrected     = intermediate x that axis's scale factor   (roll, yaw)
    4. errors        = programmed - corrected (roll, yaw);  pitch error = 0 - intermediate

All angles in arcsec; errors are the rotation still to be made (positive =
rotate about the positive axis), the sign convention of every position input
of the control amplifiers.
"""

from allsky.computer import word_registers as wr
from allsky.jit import njit

# CPU working-store layout (float64 array of N_WORK).
CORRECTED_ROLL = 0  #: [arcsec]
CORRECTED_YAW = 1  #: [arcsec]
INTERMEDIATE_PITCH = 2  #: [arcsec]
ERROR_ROLL = 3  #: [arcsec]
ERROR_PITCH = 4  #: [arcsec]
ERROR_YAW = 5  #: [arcsec]
N_WORK = 6


def scale_factor(true_angle_arcsec: float, counted_arcsec: float) -> float:
    """Scale factor = true angle / counted angle, both [arcsec].

    ``true_angle_arcsec`` is the turn as the optics confirm it and
    ``counted_arcsec`` what the turned axis's counter holds; ZeroDivisionError
    when it holds nothing.
    """
    if counted_arcsec == 0.0:
        raise ZeroDivisionError("no counts accumulated: the turn was not measured")
    return true_angle_arcsec / counted_arcsec


def cross_coupling(other_axis_arcsec: float, true_angle_arcsec: float) -> float:
    """Cross-coupling factor = counts on the other axis / true angle [-].

    ``other_axis_arcsec`` is what another axis's counter holds after the turn
    and ``true_angle_arcsec`` the turn, both [arcsec].
    """
    return other_axis_arcsec / true_angle_arcsec


def calibrate_roll(word23, counts_arcsec, true_angle_arcsec):
    """Mode 4: roll scale factor, roll-into-pitch and roll-into-yaw into register 23.

    ``word23`` is computed word register 23, written in place;
    ``counts_arcsec`` the counted angles, roll, pitch, yaw [arcsec]; and
    ``true_angle_arcsec`` the signed angle of the roll turn [arcsec].
    """
    word23[wr.SF_ROLL] = scale_factor(true_angle_arcsec, counts_arcsec[0])
    word23[wr.ROLL_INTO_PITCH] = cross_coupling(counts_arcsec[1], true_angle_arcsec)
    word23[wr.ROLL_INTO_YAW] = cross_coupling(counts_arcsec[2], true_angle_arcsec)


def calibrate_yaw(word23, counts_arcsec, true_angle_arcsec):
    """Mode 5: yaw scale factor, yaw-into-pitch and yaw-into-roll into register 23.

    ``word23`` is computed word register 23, written in place;
    ``counts_arcsec`` the counted angles, roll, pitch, yaw [arcsec]; and
    ``true_angle_arcsec`` the signed angle of the yaw turn [arcsec].
    """
    word23[wr.SF_YAW] = scale_factor(true_angle_arcsec, counts_arcsec[2])
    word23[wr.YAW_INTO_PITCH] = cross_coupling(counts_arcsec[1], true_angle_arcsec)
    word23[wr.YAW_INTO_ROLL] = cross_coupling(counts_arcsec[0], true_angle_arcsec)


@njit
def target_step(axis, counter_arcsec, word23, word24, work):
    """One computer cycle on ``axis``: update that axis's corrected angle and error.

    ``axis`` is 0 roll, 1 pitch, 2 yaw; ``counter_arcsec`` the selected
    counter's content times the pulse weight [arcsec]; ``word23`` and
    ``word24`` registers 23 (calibration) and 24 (programmed roll and yaw
    [arcsec]); ``work`` CPU 22's (N_WORK,) working store, updated in place.
    Returns the error [arcsec] to write into that axis's storage register.
    """
    phi = work[CORRECTED_ROLL]
    psi = work[CORRECTED_YAW]
    if axis == 0:
        inter = counter_arcsec - word23[wr.YAW_INTO_ROLL] * psi
        phi = inter * word23[wr.SF_ROLL]
        work[CORRECTED_ROLL] = phi
        work[ERROR_ROLL] = word24[wr.PROGRAMMED_ROLL] - phi
        return work[ERROR_ROLL]
    if axis == 1:
        inter = counter_arcsec - word23[wr.YAW_INTO_PITCH] * psi \
            - word23[wr.ROLL_INTO_PITCH] * phi
        work[INTERMEDIATE_PITCH] = inter
        work[ERROR_PITCH] = -inter
        return work[ERROR_PITCH]
    inter = counter_arcsec - word23[wr.ROLL_INTO_YAW] * phi
    psi = inter * word23[wr.SF_YAW]
    work[CORRECTED_YAW] = psi
    work[ERROR_YAW] = word24[wr.PROGRAMMED_YAW] - psi
    return work[ERROR_YAW]


def mode6_preset_arcsec(word23, work):
    """Counter contents [arcsec] for pitch and yaw at the end of Mode 6-1.

    The pitch and yaw counters are loaded with the latest roll-into-pitch and
    roll-into-yaw corrections, so that the intermediate (hence corrected)
    pitch and yaw angles start Mode 6-2 at exactly zero: the Sun-held pitch
    and yaw of the end of 6-1 become the zero of 6-2. The patent words this
    as loading the negative of the correction; with corrections subtracted
    in step 2 above, as here, it is the correction itself.

    ``word23`` is register 23 (its roll cross-couplings are read) and
    ``work`` CPU 22's working store (its corrected roll is read).
    """
    phi = work[CORRECTED_ROLL]
    return (word23[wr.ROLL_INTO_PITCH] * phi, word23[wr.ROLL_INTO_YAW] * phi)
