"""Control amplifiers 31 (roll), 32 (pitch), 33 (yaw).

Each sums its switched position inputs [arcsec] (optical errors, or the
storage-register DAC), limits the sum, and subtracts rate feedback::

    V = Kp * clip(sum of positions, +-limit) - Kd * rate,   clipped to +-V_max

``rate`` [arcsec/s] is the summing amplifier's loop output: through
S18/S19 (lines 130/131) it carries the rate command, so with the position
inputs open the axis becomes a rate loop; otherwise the same drift-
compensated gyro rate damps the position loop (the patent draws only the
position paths; a damping path is our addition, see docs/assumptions.md).
The input limiter bounds the slew rate of a position loop to
``Kp * limit / Kd``.
"""

from typing import NamedTuple

import numpy as np

from allsky.jit import njit


class ControlParams(NamedTuple):
    """Gains of the three control amplifiers."""

    position_gain_v_per_arcsec: np.ndarray  #: [V/arcsec] per axis
    rate_gain_v_per_arcsec_s: np.ndarray  #: [V/(arcsec/s)] per axis
    position_limit_arcsec: np.ndarray  #: [arcsec] input limiter per axis
    output_limit_v: float  #: [V] output saturation


@njit
def control_amp(p, axis, position_arcsec, rate_arcsec_s):
    """Output voltage [V] of amplifier ``axis``."""
    lim = p.position_limit_arcsec[axis]
    pos = min(max(position_arcsec, -lim), lim)
    v = p.position_gain_v_per_arcsec[axis] * pos - p.rate_gain_v_per_arcsec_s[axis] * rate_arcsec_s
    return min(max(v, -p.output_limit_v), p.output_limit_v)
