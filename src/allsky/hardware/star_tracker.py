"""Star tracker 105 on the +z (yaw) axis.

The tracker reports, in arcsec, the rotations that would bring its boresight
(+z) onto the tracked star ``s`` (unit vector, body axes)::

    yaw output   = atan2(-s_y, s_z)   (rotation about +x: what a roll moves)
    pitch output = atan2( s_x, s_z)   (rotation about +y)

Its field of view is a slit: long (``fov_long_half``) in the pitch direction,
since the Sun-Canopus angle varies by about +-14 deg over a year, narrow
(``fov_narrow_half``) across. Only stars inside the magnitude window reach
the kernel (the window is applied once, before flight, by
:func:`allsky.sim.mission` from the catalog); of those in the field, the one
nearest the boresight is tracked. "Star present" flags a lock, and the
tracker tells which star it holds (its index in ``stars_inertial``): the
programmed angles assume a planned star, and a window that passes two stars
can lock the other one.
"""

from typing import NamedTuple

import numpy as np

from allsky.gauss import standard_normal
from allsky.jit import njit
from allsky.units import RAD2ARCSEC

#: What the tracker holds when it holds no star of the catalog but a false target (a glint
#: of stray light): its index is neither a star's nor -1 (nothing in the slit).
FALSE_TARGET = -2


class StarTrackerParams(NamedTuple):
    """Canopus tracker."""

    fov_long_half_rad: float  #: [rad] half field along the tracker pitch direction
    fov_narrow_half_rad: float  #: [rad] half field across (tracker yaw direction)
    noise_arcsec: float  #: [arcsec] 1-sigma white noise per output per frame
    stars_inertial: np.ndarray  #: [-] (n, 3) unit vectors of the stars inside the magnitude window


@njit
def star_tracker(p, q, out, rng):
    """Outputs of star tracker 105 for attitude ``q``, written into ``out``.

    ``out = [yaw_arcsec, pitch_arcsec, present]``. Returns the index of the
    tracked star in ``p.stars_inertial``, -1 when none is in the field.
    """
    best = 1e9
    k_best = -1
    yaw_best = 0.0
    pitch_best = 0.0
    w, x, y, z = q[0], q[1], q[2], q[3]
    # Rows of the body-from-inertial matrix (see quaternion.dcm_body_from_inertial).
    r0 = (w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
    r1 = (2.0 * (x * y - w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z + w * x))
    r2 = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)
    for k in range(p.stars_inertial.shape[0]):
        a, b, c = p.stars_inertial[k, 0], p.stars_inertial[k, 1], p.stars_inertial[k, 2]
        sz = r2[0] * a + r2[1] * b + r2[2] * c
        if sz <= 0.0:
            continue
        sx = r0[0] * a + r0[1] * b + r0[2] * c
        sy = r1[0] * a + r1[1] * b + r1[2] * c
        yaw = np.arctan2(-sy, sz)
        pitch = np.arctan2(sx, sz)
        if abs(yaw) > p.fov_narrow_half_rad or abs(pitch) > p.fov_long_half_rad:
            continue
        d = yaw * yaw + pitch * pitch
        if d < best:
            best = d
            yaw_best = yaw
            pitch_best = pitch
            k_best = k
    if k_best < 0:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        return -1
    out[0] = yaw_best * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    out[1] = pitch_best * RAD2ARCSEC + p.noise_arcsec * standard_normal(rng)
    out[2] = 1.0
    return k_best
