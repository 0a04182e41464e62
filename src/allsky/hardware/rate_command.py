"""Rate-command modules 120 (roll, via S16) and 128 (yaw, via S17).

Each puts out a constant commanded rate [arcsec/s] (1.5 deg/s in the patent)
with the sign chosen by the master sequencer for the manoeuvre.
"""

from allsky.jit import njit


@njit
def rate_command(rate_arcsec_s, sign):
    """Commanded rate [arcsec/s] of a module set to turn in direction ``sign`` (+1/-1).

    ``rate_arcsec_s`` is the module's rate magnitude [arcsec/s]
    (``ElectronicsParams.rate_command_arcsec_s``).
    """
    return rate_arcsec_s * sign
