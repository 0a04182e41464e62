"""Control amplifiers 31 (roll), 32 (pitch), 33 (yaw).

Each sums its switched position inputs [arcsec] (optical errors, or the
storage-register DAC), limits the sum, adds a slow clamped integral of it,
and subtracts rate feedback::

    e = clip(sum of positions, +-limit)
    I' = e / T_i   (only while |e| < I_max, I clamped to +-I_max)
    V = Kp * (e + I) - Kd * rate,   clipped to +-V_max

``rate`` [arcsec/s] is the summing amplifier's loop output: through
S18/S19 (lines 130/131) it carries the rate command, so with the position
inputs open the axis becomes a rate loop; otherwise the same drift-
compensated gyro rate damps the position loop (the patent draws only the
position paths; a damping path is our addition, see docs/assumptions.md).
The input limiter bounds the slew rate of a position loop to
``Kp * limit / Kd``. The integral (our addition too) removes the steady
attitude offset that a constant rate signal would leave: during a 1.5 deg/s
turn a misaligned gyro reports a false rate on the held axes, which the
damping path alone would turn into a steady offset (Kd/Kp) x false rate,
i.e. a coning of the turn axis that the calibration would count. The
integral is held at zero while the axis is rate-commanded.
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
    integral_time_s: float  #: [s] T_i of the position integral
    integral_limit_arcsec: float  #: [arcsec] I_max: integral clamp and active window


@njit
def control_amp(p, axis, position_arcsec, rate_arcsec_s, integral_arcsec, integrate, dt_s):
    """Output voltage [V] of amplifier ``axis``; advances its integral state.

    ``integrate`` False holds the integral at zero (rate-commanded axis).

    Parameters
    ----------
    p : ControlParams
        Gains and limits of the three amplifiers.
    axis : int
        0, 1, 2: amplifier 31 (roll), 32 (pitch), 33 (yaw).
    position_arcsec : float
        [arcsec] sum of the switched position inputs (optical errors through
        S12-S15, or the storage-register DAC through S9-S11), before the limiter.
    rate_arcsec_s : float
        [arcsec/s] the summing amplifier's loop rate (line 130/131 on roll
        and yaw).
    integral_arcsec : numpy.ndarray
        [arcsec] the three integral states, advanced.
    dt_s : float
        [s] frame length.
    """
    lim = p.position_limit_arcsec[axis]
    pos = min(max(position_arcsec, -lim), lim)
    imax = p.integral_limit_arcsec
    if not integrate:
        integral_arcsec[axis] = 0.0
    elif abs(pos) < imax:
        i = integral_arcsec[axis] + pos * dt_s / p.integral_time_s
        integral_arcsec[axis] = min(max(i, -imax), imax)
    v = p.position_gain_v_per_arcsec[axis] * (pos + integral_arcsec[axis]) \
        - p.rate_gain_v_per_arcsec_s[axis] * rate_arcsec_s
    return min(max(v, -p.output_limit_v), p.output_limit_v)
