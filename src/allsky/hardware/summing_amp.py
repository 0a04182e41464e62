"""Summing amplifiers 4 (roll), 5 (pitch), 6 (yaw).

Inputs: the gyro rate [arcsec/s]; the drift DAC output through S1/S2/S3
(subtracted); for roll and yaw, the rate-command module through S16/S17.

Two output nodes (a choice documented in docs/assumptions.md): the
*drift-compensated rate* feeds the voltage-to-frequency converter, so the
up/down counter integrates the vehicle's rotation; the *loop rate* (that
rate minus the commanded rate) goes out on line 130/131 to the control
amplifier. Were the rate command summed ahead of the converter, counter 14
would count the rate error and Mode 4 could not measure the 360 deg turn.
"""

from allsky.jit import njit


@njit
def summing_amp(gyro_arcsec_s, drift_arcsec_s, drift_switch, command_arcsec_s, command_switch):
    """Return ``(vfc_input_arcsec_s, line_rate_arcsec_s)`` of one amplifier.

    Parameters
    ----------
    gyro_arcsec_s : float
        [arcsec/s] the gyro's rate (gyro 1, 2 or 3).
    drift_arcsec_s : float
        [arcsec/s] output of drift DAC 7, 9 or 11.
    drift_switch : float
        1.0 when S1/S2/S3 is closed (the drift subtracted), 0.0 when open.
    command_arcsec_s : float
        [arcsec/s] rate-command module 120 (roll) or 128 (yaw); 0 for pitch.
    command_switch : float
        1.0 when S16/S17 is closed (the rate command followed), 0.0 when open.
    """
    compensated = gyro_arcsec_s - drift_arcsec_s * drift_switch
    return compensated, compensated - command_arcsec_s * command_switch
