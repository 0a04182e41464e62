"""Ground computation of the programmed target angles (register 24).

Modes 1-5 leave the vehicle in the *reference attitude*: roll axis +x on the
Sun, the reference star (Canopus) on the tracker's null plane, i.e. in the
body x-z plane on the +z side. Pointing +x at a target ``t`` then takes a
roll ``phi`` about +x followed by a yaw ``psi`` about the rolled +z::

    x_final = cos(psi) x + sin(psi) (cos(phi) y + sin(phi) z)

so ``cos psi = t_x``, ``sin psi cos phi = t_y``, ``sin psi sin phi = t_z``
(components in the reference frame). Of the two solutions we program the one
with the smaller roll, ``|phi| <= 90 deg`` (the yaw then takes either sign).
"""

import math

import numpy as np

from allsky import units


def reference_frame(sun_inertial, star_inertial) -> np.ndarray:
    """Rows: reference x, y, z axes in inertial components (a body-from-inertial DCM)."""
    x = np.asarray(sun_inertial, dtype=float)
    x = x / np.linalg.norm(x)
    c = np.asarray(star_inertial, dtype=float)
    z = c - (c @ x) * x
    nz = np.linalg.norm(z)
    if nz < 1e-6:
        raise ValueError("the reference star is on the Sun line: no roll reference")
    z = z / nz
    y = np.cross(z, x)
    return np.vstack([x, y, z])


def programmed_angles_deg(sun_inertial, star_inertial, target_inertial) -> tuple:
    """Programmed (roll, yaw) [deg] that point +x at the target.

    The turns start from the reference attitude.
    """
    t = reference_frame(sun_inertial, star_inertial) @ np.asarray(target_inertial, dtype=float)
    t = t / np.linalg.norm(t)
    phi = math.atan2(t[2], t[1])
    psi = math.atan2(math.hypot(t[1], t[2]), t[0])
    if phi > math.pi / 2:
        phi -= math.pi
        psi = -psi
    elif phi < -math.pi / 2:
        phi += math.pi
        psi = -psi
    return phi * units.RAD2DEG, psi * units.RAD2DEG


def pointing_direction(roll_deg, yaw_deg) -> np.ndarray:
    """Reference-frame direction of +x after the roll-then-yaw manoeuvre."""
    phi, psi = roll_deg * units.DEG2RAD, yaw_deg * units.DEG2RAD
    return np.array([math.cos(psi), math.sin(psi) * math.cos(phi),
                     math.sin(psi) * math.sin(phi)])
