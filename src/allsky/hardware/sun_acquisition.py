"""Mode 1 sun-acquisition controller (the conventional part the patent leaves out).

Modelled on a solar-pointing sounding-rocket control: coarse sun eyes give
the Sun's direction over the whole sphere; the controller commands a body
rate about the axis ``x_body x sun`` that turns the roll axis toward the Sun,
proportional to the angle off (``slew_gain_per_s``) and capped at
``slew_rate_max``, while roll rate is nulled. Once the Sun is inside the
fine sensor's linear range on both axes, the fine pitch and yaw errors drive
the ordinary position loops of control amplifiers 32 and 33. Its outputs are
the position input and rate input of each control amplifier.
"""

from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.jit import njit
from allsky.units import RAD2ARCSEC


class SunAcquisitionParams(NamedTuple):
    """Mode 1 controller."""

    slew_gain_per_s: float  #: [1/s] commanded rate per radian off the Sun
    slew_rate_max_arcsec_s: float  #: [arcsec/s] slew-rate cap


@njit
def sun_acquisition(p, linear_range_arcsec, fine, coarse_body, gyro_arcsec_s, pos, rate):
    """Fill control-amplifier inputs ``pos`` [arcsec], ``rate`` [arcsec/s] for Mode 1.

    ``p`` is the :class:`SunAcquisitionParams`; ``linear_range_arcsec`` the
    fine sun sensor's linear half-range [arcsec]; ``fine`` sun sensor 104's
    (3,) output ``[pitch_arcsec, yaw_arcsec, present]``; ``coarse_body`` the
    coarse eyes' (3,) unit Sun vector in body axes; ``gyro_arcsec_s`` the (3,)
    drift-compensated rates of summing amplifiers 4-6 [arcsec/s]. ``pos`` and
    ``rate`` are (3,), roll, pitch, yaw.
    """
    in_range = fine[2] > 0.5 and abs(fine[0]) < linear_range_arcsec \
        and abs(fine[1]) < linear_range_arcsec
    rate[0] = gyro_arcsec_s[0]
    pos[0] = 0.0
    if in_range:
        pos[1] = fine[0]
        pos[2] = fine[1]
        rate[1] = gyro_arcsec_s[1]
        rate[2] = gyro_arcsec_s[2]
        return
    ey = -coarse_body[2]
    ez = coarse_body[1]
    n = np.sqrt(ey * ey + ez * ez)
    angle = xmath.atan2(n, coarse_body[0])
    cmd = min(p.slew_gain_per_s * angle * RAD2ARCSEC, p.slew_rate_max_arcsec_s)
    if n > 1e-12:
        ey /= n
        ez /= n
    else:  # Sun exactly behind: any axis normal to x will do
        ey = 1.0
        ez = 0.0
    pos[1] = 0.0
    pos[2] = 0.0
    rate[1] = gyro_arcsec_s[1] - cmd * ey
    rate[2] = gyro_arcsec_s[2] - cmd * ez
