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
    """Return ``(vfc_input_arcsec_s, line_rate_arcsec_s)`` of one amplifier."""
    compensated = gyro_arcsec_s - drift_arcsec_s * drift_switch
    return compensated, compensated - command_arcsec_s * command_switch
