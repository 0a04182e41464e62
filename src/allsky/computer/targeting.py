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

from allsky import units, xmath


def reference_frame(sun_inertial, star_inertial) -> np.ndarray:
    """Rows: reference x, y, z axes in inertial components (a body-from-inertial DCM).

    ``sun_inertial`` and ``star_inertial`` are the directions of the Sun and
    the reference star, (3,) in inertial axes, any length: +x goes to the Sun,
    +z toward the star. ValueError when the star is on the Sun line.
    """
    x = np.asarray(sun_inertial, dtype=float)
    x = x / xmath.norm3(x)
    c = np.asarray(star_inertial, dtype=float)
    z = c - xmath.dot3(c, x) * x
    nz = xmath.norm3(z)
    if nz < 1e-6:
        raise ValueError("the reference star is on the Sun line: no roll reference")
    z = z / nz
    y = np.cross(z, x)
    return np.vstack([x, y, z])


def programmed_angles_deg(sun_inertial, star_inertial, target_inertial) -> tuple:
    """Programmed (roll, yaw) [deg] that point +x at the target.

    The turns start from the reference attitude that ``sun_inertial`` and
    ``star_inertial`` define (:func:`reference_frame`); ``target_inertial`` is
    the target's direction. All three are (3,) in inertial axes, any length.
    """
    t = xmath.matmul(reference_frame(sun_inertial, star_inertial),
                     np.asarray(target_inertial, dtype=float))
    return angles_to_deg(t)


def angles_to_deg(direction) -> tuple:
    """(roll, yaw) [deg] carrying +x onto ``direction`` (in the start frame).

    A roll about +x, then a yaw about the rolled +z; of the two solutions the
    one with ``|roll| <= 90 deg``.
    """
    t = np.asarray(direction, dtype=float)
    t = t / xmath.norm3(t)
    # A target a rounding error from the roll = +-90 deg boundary (in the y-z plane's
    # z axis) rolls by sign(z) 90 deg, whatever the sign of the rounding error in y.
    phi = xmath.atan2(t[2], abs(t[1]) if abs(t[1]) <= 1e-15 else t[1])
    psi = xmath.atan2(xmath.hypot(t[1], t[2]), t[0])
    if phi > math.pi / 2:
        phi -= math.pi
        psi = -psi
    elif phi < -math.pi / 2:
        phi += math.pi
        psi = -psi
    return phi * units.RAD2DEG, psi * units.RAD2DEG


def pointing_direction(roll_deg, yaw_deg) -> np.ndarray:
    """Reference-frame direction of +x after the roll-then-yaw manoeuvre.

    ``roll_deg`` and ``yaw_deg`` are the turns [deg], as programmed in
    register 24 (:func:`programmed_angles_deg`).
    """
    phi, psi = roll_deg * units.DEG2RAD, yaw_deg * units.DEG2RAD
    return np.array([xmath.cos(psi), xmath.sin(psi) * xmath.cos(phi),
                     xmath.sin(psi) * xmath.sin(phi)])


def attitude_after(roll_deg, yaw_deg) -> np.ndarray:
    """The body axes after the roll-then-yaw manoeuvre, as columns, in the start frame.

    ``roll_deg`` and ``yaw_deg`` are the turns [deg]. The roll turns the frame
    about +x, the yaw about the rolled +z: ``Rx(roll) Rz(yaw)``; its first
    column is :func:`pointing_direction`.
    """
    phi, psi = roll_deg * units.DEG2RAD, yaw_deg * units.DEG2RAD
    cf, sf, cp, sp = xmath.cos(phi), xmath.sin(phi), xmath.cos(psi), xmath.sin(psi)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cf, -sf], [0.0, sf, cf]])
    rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    return xmath.matmul(rx, rz)


def turn_to_deg(body_axes, to_roll_deg, to_yaw_deg) -> tuple:
    """The turn from the attitude held to a target given by its programmed angles.

    ``body_axes`` are the body axes held, as columns in the reference frame
    the programmed angles are measured from (:func:`attitude_after` of the
    first target's angles, then of each turn flown). The target,
    :func:`pointing_direction` of ``to_roll_deg`` and ``to_yaw_deg``, is
    reached by a roll about the current +x and a yaw about the rolled +z
    (:func:`angles_to_deg` in the current body frame). This is the
    arithmetic CPU 22 would do (products and sums of sines and cosines) to
    go from target to target without the Sun and the star.

    Returns ``(roll_deg, yaw_deg, body_axes_after)``: the turn, and the body
    axes it leaves the vehicle in (``body_axes @ attitude_after(roll, yaw)``).
    A target reached this way has its +x where its programmed angles say,
    but not in general their roll about it.
    """
    body = np.asarray(body_axes, dtype=float)
    roll, yaw = angles_to_deg(xmath.matmul(body.T, pointing_direction(to_roll_deg, to_yaw_deg)))
    return roll, yaw, xmath.matmul(body, attitude_after(roll, yaw))


def turn_between_deg(from_roll_deg, from_yaw_deg, to_roll_deg, to_yaw_deg) -> tuple:
    """(roll, yaw) [deg] from a target reached by its programmed angles to the next.

    ``from_roll_deg``, ``from_yaw_deg`` are the programmed angles [deg] of the
    target held and ``to_roll_deg``, ``to_yaw_deg`` those of the next. Both
    pairs are measured from the same reference attitude; the vehicle on the
    first target has the body axes :func:`attitude_after` of its angles
    (:func:`turn_to_deg`).
    """
    return turn_to_deg(attitude_after(from_roll_deg, from_yaw_deg), to_roll_deg,
                       to_yaw_deg)[:2]
