"""Sun sensor 104 on the +x (roll) axis, and the coarse sun eyes used in Mode 1.

Fine outputs, in arcsec, are the rotations about body +y (pitch) and +z (yaw)
that would bring +x onto the Sun, each measured in its own plane::

    pitch = atan2(-s_z, s_x)     yaw = atan2(s_y, s_x)

(``s`` the Sun's unit vector in body axes). Each output is linear within
``linear_range_arcsec`` and saturated beyond; "sun present" is true when the
Sun is within ``presence_half_angle_rad`` of +x. Outputs read zero when the
Sun is absent. Noise is white, per frame.
"""

from typing import NamedTuple

import numpy as np

from allsky import xmath
from allsky.gauss import standard_normal
from allsky.jit import njit_stage
from allsky.units import RAD2ARCSEC


class SunSensorParams(NamedTuple):
    """Fine sun sensor and coarse sun eyes."""

    linear_range_arcsec: float  #: [arcsec] linear half-range of each output
    presence_cos: float  #: [-] cosine of the "sun present" half-angle
    noise_arcsec: float  #: [arcsec] 1-sigma white noise per output per frame
    coarse_noise_rad: float  #: [rad] 1-sigma noise per axis of the coarse sun vector


@njit_stage
def sun_sensor(p, sun_body, out, rng):
    """Fine sun sensor. ``out`` receives ``[pitch_arcsec, yaw_arcsec, present]``.

    Parameters
    ----------
    p : SunSensorParams
        Range, presence cone and noise of sun sensor 104.
    sun_body : array of 3 float
        [-] unit vector to the Sun, body axes.
    rng : numpy.ndarray
        (1,) uint64 noise generator state (``allsky.gauss``), advanced.
    """
    sx, sy, sz = sun_body[0], sun_body[1], sun_body[2]
    present = sx >= p.presence_cos
    if not present:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        return
    lim = p.linear_range_arcsec
    pitch = xmath.atan2(-sz, sx) * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    yaw = xmath.atan2(sy, sx) * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    out[0] = min(max(pitch, -lim), lim)
    out[1] = min(max(yaw, -lim), lim)
    out[2] = 1.0


@njit_stage
def coarse_sun(p, sun_body, out, rng):
    """Coarse sun eyes: a noisy unit Sun vector in body axes over the whole sphere.

    Parameters
    ----------
    p : SunSensorParams
        Its ``coarse_noise_rad`` [rad] is the noise per axis.
    sun_body : array of 3 float
        [-] true unit vector to the Sun, body axes.
    out : array of 3 float
        [-] written: the noisy Sun direction, normalised.
    rng : numpy.ndarray
        (1,) uint64 noise generator state (``allsky.gauss``), advanced.
    """
    n = 0.0
    for i in range(3):
        out[i] = sun_body[i] + p.coarse_noise_rad * standard_normal(rng)
        n += out[i] * out[i]
    n = np.sqrt(n)
    for i in range(3):
        out[i] /= n
